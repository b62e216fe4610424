"""Batch-norm statistics when fine-tuning: estimate them over many batches, then hold them fixed.

A network trained with batch norm normalises by each batch's own statistics, and keeps exponential
running averages (momentum 0.1: about the last ten batches) that inference uses instead (the Scorer
folds them into the convolutions). Two things follow for a fine-tune of a few thousand small batches
drawn from many scene families and display transforms:

* the running averages at the last step are those of the last few batches, so the level of the
  predicted map moves from run to run with whichever batches came last;
* the function trained (batch statistics) is not the one run (running statistics).

:func:`estimate_batchnorm` replaces the running statistics by their average over ``n`` training
batches (train-mode forward passes, no gradient: "precise BN", Wu & Johnson 2021, *Rethinking "Batch"
in BatchNorm*); :func:`freeze_batchnorm` then keeps every batch-norm layer in eval mode, so the
optimiser fits the network exactly as the Scorer will run it (the affine weights still learn).
``nriqa-train ... bn_estimate=N freeze_bn=true`` does both (:func:`nriqa.training.fit.train`).

    >>> from nriqa.models import create_model
    >>> net = create_model("unet_fast")
    >>> estimate_batchnorm(net, [torch.rand(2, 3, 32, 32)] * 3, 3)
    3
    >>> freeze_batchnorm(net.train()) is net and not batchnorms(net)[0].training
    True
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import torch
from torch import Tensor, nn
from torch.nn.modules.batchnorm import _BatchNorm

__all__ = ["batchnorms", "estimate_batchnorm", "freeze_batchnorm", "repeated"]


def batchnorms(net: nn.Module) -> list[_BatchNorm]:
    """The batch-norm layers of ``net`` that keep running statistics, in module order."""
    return [m for m in net.modules() if isinstance(m, _BatchNorm) and m.track_running_stats]


def _inputs(batch) -> Tensor:
    # A training batch is (input, target); a bare tensor is taken as the input.
    return batch[0] if isinstance(batch, (tuple, list)) else batch


@torch.no_grad()
def estimate_batchnorm(net: nn.Module, batches: Iterable, n: int) -> int:
    """Set every batch-norm layer's running statistics to their mean over the first ``n`` ``batches``.

    Each batch is run forward in train mode (so each layer sees the statistics it trains with), its input
    moved to the network's device (a network on a GPU, batches from a CPU loader); the running mean and
    variance become the plain average over those batches (momentum ``None``). The weights, the layers'
    momentum and the network's train/eval mode are as they were.

    Returns:
        the number of batches used (fewer than ``n`` when ``batches`` runs out first).

    Raises:
        ValueError: ``n < 1``, or ``batches`` yields nothing.
    """
    if n < 1:
        raise ValueError(f"estimate_batchnorm needs n >= 1 batches, got {n}")
    layers = batchnorms(net)
    if not layers:
        return 0
    device = layers[0].running_mean.device  # where the network runs: its statistics live there
    modes = {m: m.training for m in net.modules()}
    momenta = [m.momentum for m in layers]
    for m in layers:
        m.reset_running_stats()
        m.momentum = None
    net.train()
    used = 0
    try:
        for batch in batches:
            net(_inputs(batch).to(device))
            used += 1
            if used >= n:
                break
    finally:
        for m, momentum in zip(layers, momenta):
            m.momentum = momentum
        for m, mode in modes.items():
            m.training = mode
    if used == 0:
        raise ValueError("estimate_batchnorm: no batches to estimate the batch-norm statistics from")
    return used


def repeated(loader: Iterable) -> Iterator:
    """The batches of ``loader``, pass after pass (a training loader draws new patches each pass).

    Stops when a pass yields nothing, so an empty loader ends at once.
    """
    while True:
        empty = True
        for batch in loader:
            empty = False
            yield batch
        if empty:
            return


def freeze_batchnorm(net: nn.Module) -> nn.Module:
    """Put every batch-norm layer of ``net`` in eval mode (running statistics used and left as they are)."""
    for m in batchnorms(net):
        m.eval()
    return net
