"""Batch norm folded into the convolution before it: the same network, one pass over memory less per layer.

In eval mode a ``BatchNorm2d`` is a fixed per-channel affine map, ``y = g (x - m) / s + b``, so a
convolution followed by it is one convolution with scaled weights and a shifted bias (Ioffe & Szegedy
2015, sec. 3.2; ``torch.nn.utils.fusion.fuse_conv_bn_eval``). Every model here builds its blocks as
``Conv -> BN -> ReLU`` in ``nn.Sequential`` containers (:func:`nriqa.models.fcnn.conv_bn_relu`), so
folding each adjacent pair saves the batch-norm pass -- a fifth of ``fcnn_fast``'s time per image on a CPU,
a twentieth of ``unet_fast``'s (docs/results/scorer_frontier.md) -- and changes the map by float rounding only
(~1e-6).

    >>> fast = fold_batchnorm(net)  # doctest: +SKIP  a folded copy; ``net`` is left as it was
"""

from __future__ import annotations

import copy

from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval

__all__ = ["fold_batchnorm"]


def fold_batchnorm(net: nn.Module) -> nn.Module:
    """A copy of ``net`` in eval mode with every ``Conv2d`` directly followed by a ``BatchNorm2d``
    (within one ``nn.Sequential``) folded into one ``Conv2d``; the batch norm becomes ``nn.Identity``.

    Only the copy changes; its attributes (``output``, ``receptive_field``, ``window``, ...) are the
    original's. Batch norms that follow anything else, or that keep no running statistics, are left as
    they are.
    """
    folded = copy.deepcopy(net).eval()
    for module in folded.modules():
        if not isinstance(module, nn.Sequential):
            continue
        names = list(module._modules)
        for first, second in zip(names, names[1:]):
            conv, norm = module._modules[first], module._modules[second]
            if (
                type(conv) is nn.Conv2d
                and type(norm) is nn.BatchNorm2d
                and norm.track_running_stats
                and norm.num_features == conv.out_channels
            ):
                module._modules[first] = fuse_conv_bn_eval(conv, norm)
                module._modules[second] = nn.Identity()
    return folded
