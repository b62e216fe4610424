"""The ladder-pair term: the error of the score's difference between two rungs of one view (:mod:`nriqa.data.ladders`).

Added to the training loss by :class:`nriqa.training.module.NRIQAModule` with ``ladder_weight`` > 0.
"""

from __future__ import annotations

from torch import Tensor

from nriqa.losses.charbonnier import EPS, charbonnier

__all__ = ["check_ladder_weight", "ladder_term"]


def check_ladder_weight(weight: float) -> float:
    """``weight`` as a float; not >= 0 a one-line ``ValueError``."""
    if not float(weight) >= 0.0:
        raise ValueError(f"ladder_weight must be >= 0, got {float(weight)}")
    return float(weight)


def ladder_term(pred: Tensor, target: Tensor) -> Tensor:
    """Mean Charbonnier of ``(p[2i+1] - p[2i]) - (t[2i+1] - t[2i])`` over a batch's pairs, ``p``/``t`` each item's
    mean predicted / target map.

        >>> import torch
        >>> t = torch.tensor([0.2, 0.5, 0.9, 0.8]).view(4, 1, 1, 1)
        >>> round(ladder_term(t + 0.1, t).item(), 4)  # a shared bias is no error of order
        0.001
    """
    if pred.shape[0] % 2:
        raise ValueError(f"ladder pairs need an even batch, got {pred.shape[0]} items")
    p = pred.reshape(pred.shape[0], -1).mean(dim=1)
    t = target.reshape(target.shape[0], -1).mean(dim=1).to(p.dtype)
    return charbonnier(p[1::2] - p[0::2], t[1::2] - t[0::2], EPS)
