"""Experiment I of thesis ch. 5: the patch CNN that predicts one quality score per 32x32 patch.

Reading of the thesis architecture that gives exactly its 8,553,889 trainable parameters::

    layer (input 3x32x32)               conv/dense    BN   PReLU (one slope per C*H*W)
    Conv3x3(3->32)   BN  PReLU                 896    64   32,768
    Conv3x3(32->32)  BN  PReLU               9,248    64   32,768
    MaxPool2 -> 32x16x16                         0
    Conv3x3(32->64)  BN  PReLU              18,496   128   16,384
    Conv3x3(64->64)  BN  PReLU              36,928   128   16,384
    Flatten, Dense(16384->512)           8,389,120
    Dropout(0.7), Dense(512->1), ReLU          513

That is: convolutions and dense layers with biases, batch norm counting its trainable gamma and
beta (its running mean and variance are buffers, not trainable), and the Keras-default PReLU with
one learnable slope per element. Total 65,568 (conv) + 384 (BN) + 98,304 (PReLU) +
8,389,633 (dense) = 8,553,889.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from nriqa.models import BN_EPS, BN_MOMENTUM, init_keras_, register_model

__all__ = ["ElementwisePReLU", "PatchCNN", "patch_cnn"]


class ElementwisePReLU(nn.Module):
    """PReLU with one learnable slope per element, as Keras ``PReLU()`` with no shared axes.

    ``y = max(x, 0) + alpha * min(x, 0)`` with ``alpha`` of shape ``(C, H, W)``, initialised to
    zero (the Keras default, so it starts as a ReLU). Input ``(B, C, H, W)``; because the slope is
    tied to positions, the spatial size is fixed at construction. Thesis ch. 5, experiment I.
    """

    def __init__(self, shape: tuple[int, int, int]):
        super().__init__()
        self.alpha = nn.Parameter(torch.zeros(shape))

    def forward(self, x: Tensor) -> Tensor:
        return torch.relu(x) - self.alpha * torch.relu(-x)


def _block(cin: int, cout: int, size: int) -> list[nn.Module]:
    return [
        nn.Conv2d(cin, cout, 3, padding=1),
        nn.BatchNorm2d(cout, momentum=BN_MOMENTUM, eps=BN_EPS),
        ElementwisePReLU((cout, size, size)),
    ]


class PatchCNN(nn.Module):
    """Thesis ch. 5, experiment I patch CNN: ``(B,3,32,32)`` LDR in [0,1] -> ``(B,1)`` >= 0.

    Trained to predict the MAE of the patch against its converged reference. 'same' padding,
    batch norm with Keras momentum 0.9, per-element PReLU, Dropout(0.7) before the last dense
    layer, final ReLU so scores are non-negative. 8,553,889 trainable parameters.

    The last dense layer starts at the target's scale (weights x ``output_init_scale``, bias
    ``output_init_bias`` ~ a typical patch MAE): with plain Glorot init its outputs start at about
    +-2, Adam's first steps throw every one below zero and the ReLU output dies for good (the
    thesis's NaN with L1/L2/Charbonnier; here a constant 0). Parameters are unchanged.

    The flatten is channels-first (PyTorch order); porting Keras (channels-last) dense weights
    would need a permutation of the first dense layer's inputs.
    """

    output = "patch"
    patch_size = 32
    receptive_field = 32

    def __init__(self, dropout: float = 0.7, output_init_scale: float = 0.01, output_init_bias: float = 0.05):
        super().__init__()
        s = self.patch_size
        self.features = nn.Sequential(
            *_block(3, 32, s),
            *_block(32, 32, s),
            nn.MaxPool2d(2),
            *_block(32, 64, s // 2),
            *_block(64, 64, s // 2),
        )
        self.head = nn.Sequential(
            nn.Flatten(),
            nn.Linear(64 * (s // 2) ** 2, 512),
            nn.Dropout(dropout),
            nn.Linear(512, 1),
            nn.ReLU(),
        )
        init_keras_(self)
        last = self.head[-2]
        with torch.no_grad():
            last.weight.mul_(output_init_scale)
            last.bias.fill_(output_init_bias)

    def forward(self, x: Tensor) -> Tensor:
        """``x``: ``(B,3,32,32)``; returns ``(B,1)``."""
        s = self.patch_size
        if x.ndim != 4 or x.shape[1] != 3 or x.shape[-2:] != (s, s):
            raise ValueError(
                f"patch_cnn takes (B,3,{s},{s}) patches (its PReLU has one slope per position), "
                f"got {tuple(x.shape)}; cut the image into {s}x{s} patches or use a map model (fcnn)"
            )
        return self.head(self.features(x))


@register_model
def patch_cnn(**kwargs) -> PatchCNN:
    """Thesis ch. 5, experiment I patch CNN: ``(B,3,32,32) -> (B,1)``; see :class:`PatchCNN`."""
    return PatchCNN(**kwargs)
