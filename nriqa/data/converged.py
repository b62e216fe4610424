"""Converged patches: a share of training patches whose input is the reference itself, at its target (1 everywhere).

A scorer that has only seen renders up to the dataset's top rung has never been shown what converged looks like in
each scene, and reads dense converged detail (leaves, fibres, sparkle) as noise: the reference of a scene it learnt
can read 0.6. A converged draw shows the network the reference as the noisy image; everything after the cut (pixel
filter, albedo texture, display, jitter) acts on both alike, so the SSIM map target is exactly 1.
"""

from __future__ import annotations

import torch
from torch import Tensor

from nriqa.data.options import check_share


def check_converged_p(p: float, twins: bool = False) -> float:
    """``p`` as a float in [0, 1], or a one-line ``ValueError`` naming ``data.converged_p`` (also where ``p`` > 0 for
    a two-buffer model: a reference is no independent twin of itself)."""
    p = check_share(p, "data.converged_p", "it")
    if p and twins:
        raise ValueError("data.converged_p needs a single-image model: a reference is no independent twin of itself")
    return p


def sample_converged(generator: torch.Generator, p: float) -> bool:
    """True with probability ``p``. Nothing is drawn from ``generator`` when ``p`` is 0, so switching it off leaves
    every other draw of a training item as it was."""
    if p <= 0.0:
        return False
    return bool(torch.rand(1, generator=generator, dtype=torch.float64) < p)


def converged_batch(rows: list[int], members: list[Tensor]) -> list[Tensor]:
    """The ``(B, C, P, P)`` member stacks ``[noisy, reference, ...]`` with the noisy image of items ``rows`` replaced
    by their reference."""
    if not rows:
        return members
    noisy = members[0].clone()
    noisy[rows] = members[1][rows]
    return [noisy, *members[1:]]
