"""Charbonnier loss, a smooth L1 (thesis ch. 5)."""

from __future__ import annotations

import torch
from torch import Tensor, nn

from nriqa.losses._checks import check_pair

EPS = 1e-3


def charbonnier(pred: Tensor, target: Tensor, eps: float = EPS) -> Tensor:
    """Mean Charbonnier penalty ``mean sqrt((y - y_hat)^2 + eps^2)``, eps = 1e-3 (thesis ch. 5).

    Computed as ``hypot(y - y_hat, eps)``, which neither overflows for huge errors nor has a
    singular gradient at zero error. ``charbonnier(y, y) == eps``.

    Args:
        pred: predictions, any shape.
        target: targets, same shape as ``pred``.
        eps: smoothing constant, > 0.

    Returns:
        Scalar tensor.

    Examples:
        >>> charbonnier(torch.zeros(3), torch.zeros(3))
        tensor(0.0010)
    """
    check_pair(pred, target, "charbonnier")
    return torch.hypot(pred - target, torch.tensor(eps, dtype=pred.dtype, device=pred.device)).mean()


class CharbonnierLoss(nn.Module):
    """Module form of :func:`charbonnier`."""

    def __init__(self, eps: float = EPS) -> None:
        super().__init__()
        if not eps > 0:
            raise ValueError(f"charbonnier: eps must be > 0, got {eps}")
        self.eps = float(eps)

    def forward(self, pred: Tensor, target: Tensor) -> Tensor:
        return charbonnier(pred, target, self.eps)

    def extra_repr(self) -> str:
        return f"eps={self.eps}"
