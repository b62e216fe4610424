r"""The two-buffer scorer: the bias-corrected dual-buffer SSIM map plus a learned correction.

A render loop holds two independent estimates of every pixel for free (the image and its half
buffer, or two renders with different seeds). Their SSIM map, bias-corrected pixel by pixel,

    D = 2 S_ab / (1 + S_ab),   S_ab = SSIM(tonemap(a), tonemap(b))

already estimates SSIM(a, reference) well where its assumptions hold (zero-mean noise of equal
variance in both buffers, a tone map that is locally linear; :mod:`nriqa.eval.baselines.dual_buffer`
derives it). It fails where they break: dark renders whose samples are mostly zero (the tone map
and the clip at 0 are far from linear there), clipped highlights, and a luminance term that is not 1.

This model starts from ``D`` and learns only the correction: an ``fcnn_fast``-style trunk on 2x2
pixel blocks sees the image ``a``, the buffers' difference ``a - b`` and ``D`` itself, and adds its
output to ``D``. The last convolution starts at zero, so an untrained model *is* the corrected dual
buffer, and training can only move it where the data say it is wrong. Output ``ReLU(D + delta)``.

* in: ``(B, 6, H, W)``: the displayed image and its twin stacked on channels (the Scorer does this);
* ``S_ab`` is :func:`nriqa.core.ssim.ssim_map`'s, in [0, 1], and ``D`` is
  :func:`nriqa.core.ssim.correct_dual_buffer` of it, the ``dual_buffer_corrected`` baseline's map;
* receptive field: the 11x11 SSIM window (radius 5) under a trunk of ``n3x3`` 3x3 convolutions on
  2x2 blocks (``2 * (2 n3x3 + 1)`` px): ``2 * (2 n3x3 + 1) + 10`` px, 24 for the default 3.

``context=k`` (odd, off by default) adds two features for the lowest sample counts, where both
buffers are black on most pixels and agree there, so ``D`` reads them as converged: over a k x k
box, the fraction of pixels black in both buffers and the fraction black in exactly one. A render
whose paths mostly miss the light has many of the second; a truly black region has none, and
neither has a converged dim one. The window grows to ``max(11, k)``.

The name follows Whittle's "dual buffer" and the model it extends (:mod:`nriqa.models.fcnn_fast`).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from nriqa.core.ssim import WINDOW, correct_dual_buffer, ssim_map
from nriqa.models import init_keras_, register_model
from nriqa.models.fcnn import block_trunk

__all__ = ["DualFast", "dual_fast"]

# Image, image - twin, corrected dual-buffer map; with context, two sparse-sample fractions.
_FEATURES = 3 + 3 + 1
_CONTEXT_FEATURES = 2
# A displayed pixel counts as black at or below this (every channel): under half an 8-bit step.
BLACK = 1.0 / 512


class DualFast(nn.Module):
    """Two-buffer SSIM-map model: ``(B,6,H,W)`` (image, twin) -> ``(B,1,H,W)`` >= 0, any H, W >= 6."""

    output = "map"
    align = 2
    in_channels = 6

    def __init__(self, width: int = 32, n3x3: int = 3, n1x1: int = 1, context: int = 0):
        super().__init__()
        if n3x3 < 1:
            raise ValueError(f"DualFast needs at least one 3x3 block, got n3x3={n3x3}")
        if context and (context < 3 or context % 2 == 0):
            raise ValueError(f"DualFast context must be 0 (off) or an odd window >= 3, got {context}")
        s = self.align
        self.context = int(context)
        cin = _FEATURES + (_CONTEXT_FEATURES if context else 0)
        self.trunk = nn.Sequential(*block_trunk(cin * s * s, width, n3x3, n1x1))
        self.head = nn.Conv2d(width, s * s, 1)
        window = max(WINDOW, self.context)
        self.receptive_field = s * (2 * n3x3 + 1) + 2 * (window // 2)
        # The SSIM window (and the context box) need window // 2 + 1 pixels a side (reflect padding).
        self.min_size = window // 2 + 1 + (window // 2 + 1) % s
        init_keras_(self)
        nn.init.zeros_(self.head.weight)  # untrained == the corrected dual buffer
        self.memory_format = torch.channels_last
        self.to(memory_format=self.memory_format)

    def forward(self, x: Tensor) -> Tensor:
        """``x``: ``(B, 6, H, W)``, the image then its twin; returns ``(B,1,H,W)``."""
        if x.ndim != 4 or x.shape[1] != self.in_channels:
            raise ValueError(f"dual_fast expects (B,6,H,W): the image and its twin, got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        a, b = x[:, :3], x[:, 3:]
        d = correct_dual_buffer(ssim_map(a, b))
        feats = [a, a - b, d]
        if self.context:
            feats += self._sparse_fractions(a, b)
        feats = torch.cat(feats, dim=1)
        s = self.align
        ph, pw = -h % s, -w % s
        if ph or pw:
            feats = F.pad(feats, (0, pw, 0, ph))
        y = self.trunk(F.pixel_unshuffle(feats, s).contiguous(memory_format=self.memory_format))
        delta = F.pixel_shuffle(self.head(y), s)[..., :h, :w]
        return F.relu(d + delta).contiguous()

    def _sparse_fractions(self, a: Tensor, b: Tensor) -> list[Tensor]:
        """Over a ``context`` box: the fraction of pixels black in both buffers, and in exactly one."""
        za = (a.amax(1, keepdim=True) <= BLACK).to(a.dtype)
        zb = (b.amax(1, keepdim=True) <= BLACK).to(a.dtype)
        both, one = za * zb, (za - zb).abs()
        r = self.context // 2
        box = F.avg_pool2d(F.pad(torch.cat([both, one], 1), (r, r, r, r), mode="reflect"), self.context, stride=1)
        return [box[:, :1], box[:, 1:]]


@register_model
def dual_fast(**kwargs) -> DualFast:
    """Corrected dual-buffer map + a learned correction (:class:`DualFast`); image and twin in."""
    return DualFast(**kwargs)
