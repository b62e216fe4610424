"""L2 loss (thesis ch. 5)."""

from __future__ import annotations

from torch import Tensor, nn

from nriqa.losses._checks import check_pair


class L2Loss(nn.Module):
    """Mean squared error ``mean (y - y_hat)^2`` over all elements; returns a scalar.

    Examples:
        >>> import torch
        >>> L2Loss()(torch.zeros(4), torch.full((4,), 2.0))
        tensor(4.)
    """

    def forward(self, pred: Tensor, target: Tensor) -> Tensor:
        check_pair(pred, target, "l2")
        return (pred - target).square().mean()
