"""Pasted patches ("CutMix", Yun et al. 2019): a share of training patches carry a rectangle of another patch.

A network whose receptive field spans the whole training image can read a level off the whole image's kind of
scene, and then reads a kind it never learnt at a level of its own. A pasted patch holds two images, often of two
families, each with its own display and jitter, so the level of each part must come from that part. The rectangle
replaces the same pixels of every member (noisy image, reference, twin, albedo pass) with the partner's, after
everything else of both items (cut, texture, filter, display, jitter), and the target is computed from the pasted
pair: it is the exact SSIM map of what the network sees, seams included.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch
from torch import Tensor

from nriqa.data.options import check_share


@dataclasses.dataclass(frozen=True)
class Box:
    """The rectangle ``[y, y + h) x [x, x + w)`` of a patch that the partner fills."""

    y: int
    x: int
    h: int
    w: int


def check_cutmix_p(p: float, ladder_pairs: bool = False) -> float:
    """``p`` as a float in [0, 1], or a one-line ``ValueError`` naming ``data.cutmix_p`` (also where ``p`` > 0 with
    ladder pairs: an odd item is its even item's cut on another rung, which a partner's rectangle would not follow)."""
    p = check_share(p, "data.cutmix_p", "pasting")
    if p and ladder_pairs:
        raise ValueError("data.cutmix_p and ladder pairs (ladder_weight > 0) do not go together; set one of them to 0")
    return p


def sample_box(generator: torch.Generator, p: float, size: int) -> Box | None:
    """With probability ``p``, a rectangle of a ``size``-side patch, each side uniform in ``[size/4, 3 size/4]``.

    Nothing is drawn from ``generator`` when ``p`` is 0, so switching pasting off leaves every other draw of a
    training item as it was.
    """
    if p <= 0.0:
        return None
    u = float(torch.rand(1, generator=generator, dtype=torch.float64))
    lo, hi = max(1, size // 4), max(1, (3 * size) // 4)
    h, w = (int(v) for v in torch.randint(lo, hi + 1, (2,), generator=generator))
    y = int(torch.randint(0, size - h + 1, (1,), generator=generator))
    x = int(torch.randint(0, size - w + 1, (1,), generator=generator))
    return Box(y, x, h, w) if u < p else None


def partner_generator(seed: int, index: int) -> torch.Generator:
    """The generator of item ``index``'s partner: a stream of its own, unrelated to every item's own."""
    state = np.random.SeedSequence([int(seed), int(index), 1]).generate_state(1, dtype=np.uint64)[0]
    return torch.Generator().manual_seed(int(state))


def paste_batch(boxes: dict[int, tuple[Box, int]], members: list[Tensor]) -> list[Tensor]:
    """The ``(B, C, P, P)`` member stacks with item ``i``'s box filled from item ``j`` for each ``i: (box, j)``."""
    if not boxes:
        return members
    out = [m.clone() for m in members]
    for i, (b, j) in boxes.items():
        for m, o in zip(members, out):
            o[i, :, b.y : b.y + b.h, b.x : b.x + b.w] = m[j, :, b.y : b.y + b.h, b.x : b.x + b.w]
    return out
