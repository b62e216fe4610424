"""Models of thesis chapter 5 and a small timm-style registry.

Every model is built by a plain constructor function decorated with :func:`register_model`;
:func:`create_model` builds one by name and :func:`list_models` lists the names.

Each model class exposes two class attributes that callers (the Scorer, tiling, evaluation) rely on:

* ``output`` -- ``"patch"``: ``(B,3,h,w) -> (B,1)`` one score per patch, or
  ``"map"``: ``(B,3,H,W) -> (B,1,H,W)`` a quality map the size of the input.
* ``receptive_field`` -- side in pixels of the input window one output value depends on
  (for a patch model, the patch side).

Map models also expose ``align``: tiles must start at multiples of it for tiled == untiled
(1 for plain convolutional models, 2 for ``fcnn_fast``, which works on 2x2 pixel blocks).

The fast map models (``fcnn_fast``, ``unet_fast``, ``dual_fast``) lay their activations out
channels-last (oneDNN's CPU convolutions run faster so) and read that layout from their
``memory_format`` attribute; the outputs do not depend on it. :mod:`nriqa.training.stacked` sets it to
``torch.contiguous_format``: ``torch.func.vmap`` cannot lay out a batched tensor channels-last.

Examples:
    >>> from nriqa.models import create_model, list_models
    >>> list_models("fcnn*")
    ['fcnn', 'fcnn11', 'fcnn_fast']
    >>> model = create_model("fcnn").eval()
"""

from __future__ import annotations

from collections.abc import Callable

from torch import nn

from nriqa.registry import Registry

__all__ = ["register_model", "create_model", "list_models", "init_keras_", "BN_MOMENTUM", "BN_EPS"]

# Keras BatchNormalization(momentum=0.9) keeps running = 0.9 * running + 0.1 * batch; PyTorch's
# momentum is the weight of the batch statistic, so the same update is momentum=0.1. Keras's
# default epsilon is 1e-3 (PyTorch's is 1e-5).
BN_MOMENTUM = 0.1
BN_EPS = 1e-3

MODELS: Registry[Callable[..., nn.Module]] = Registry("model")


def register_model(fn: Callable[..., nn.Module]) -> Callable[..., nn.Module]:
    """Register a constructor function under its ``__name__``; returns it unchanged.

    Raises:
        nriqa.errors.NriqaError: a model of that name is already registered.
    """
    return MODELS.register(fn)


def list_models(pattern: str = "*") -> list[str]:
    """Sorted names of the registered models matching the shell-style ``pattern``."""
    return MODELS.names(pattern)


def create_model(name: str, **kwargs) -> nn.Module:
    """Build the registered model ``name``; ``kwargs`` go to its constructor function.

    Raises:
        nriqa.errors.NriqaError: ``name`` is not registered (the message lists the valid names).
    """
    return MODELS.create(name, **kwargs)


def init_keras_(module: nn.Module) -> nn.Module:
    """Initialise in place as Keras 2 does by default, the framework the thesis used.

    Conv and dense weights: Glorot (Xavier) uniform; their biases: zeros. Batch norm keeps
    gamma = 1, beta = 0. Returns ``module``.
    """
    for m in module.modules():
        if isinstance(m, (nn.Conv2d, nn.Linear)):
            nn.init.xavier_uniform_(m.weight)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
    return module


# Imported last: the model modules register themselves with the functions above.
from nriqa.models import dual_fast, fcnn, fcnn_fast, map_mean, patch_cnn, unet_fast, unet_ssim  # noqa: E402,F401
