"""Coarse pixels: a share of training patches carry a half-size copy of themselves, each pixel four of theirs averaged.

Averaging a render's 2 x 2 pixel blocks gives the same view at half the resolution with four times the samples a
pixel (each sample still counts for the one pixel it fell in): an honest render of its own, whose edges, textures
and shadows are twice as fine against the pixel grid and whose noise is half as strong. Every learnt family then
also shows detail finer than its pixels at the noise that goes with it, as rods a pixel wide, foliage and fibres
do, and the network can learn that sharp sub-pixel structure is not noise wherever it meets it. The copy of the
whole patch fills a random half-size square of it in every member alike (noisy image, reference, twin, albedo
pass), on the linear radiance right after the cut, before everything else (texture, filter, display, jitter,
pasting), and the target is computed from the result: it is the exact SSIM map of what the network sees, seams
included.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor

from nriqa.data.options import check_share
from nriqa.data.cutmix import Box


def check_coarse_p(p: float, patch_size: int) -> float:
    """``p`` as a float in [0, 1], or a one-line ``ValueError`` naming ``data.coarse_p`` (also where ``p`` > 0 and the
    patch side is odd or under 4: its 2 x 2 blocks would not tile it)."""
    p = check_share(p, "data.coarse_p", "coarse pixels")
    if p and (patch_size % 2 or patch_size < 4):
        raise ValueError(f"data.coarse_p needs an even data.patch_size of at least 4, got {patch_size}")
    return p


def sample_coarse(generator: torch.Generator, p: float, size: int) -> Box | None:
    """With probability ``p``, the ``size/2``-side square of a ``size``-side patch that its coarse copy fills.

    Nothing is drawn from ``generator`` when ``p`` is 0, so switching coarse pixels off leaves every other draw of a
    training item as it was.
    """
    if p <= 0.0:
        return None
    u = float(torch.rand(1, generator=generator, dtype=torch.float64))
    half = size // 2
    y, x = (int(v) for v in torch.randint(0, size - half + 1, (2,), generator=generator))
    return Box(y, x, half, half) if u < p else None


def coarsen(x: Tensor) -> Tensor:
    """``(B, C, H, W)`` images at half the resolution: each pixel the mean of a 2 x 2 block (``H``, ``W`` even)."""
    return F.avg_pool2d(x, 2)


def coarse_batch(boxes: dict[int, Box], members: list[Tensor]) -> list[Tensor]:
    """The ``(B, C, P, P)`` member stacks with item ``i``'s square filled by its own coarse copy, for each ``i: box``."""
    if not boxes:
        return members
    rows = sorted(boxes)
    out = [m.clone() for m in members]
    for m, o in zip(members, out):
        small = coarsen(m[rows])
        for k, i in enumerate(rows):
            b = boxes[i]
            o[i, :, b.y : b.y + b.h, b.x : b.x + b.w] = small[k]
    return out
