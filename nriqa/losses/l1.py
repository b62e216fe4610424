"""L1 loss (thesis ch. 5)."""

from __future__ import annotations

from torch import Tensor, nn

from nriqa.losses._checks import check_pair


class L1Loss(nn.Module):
    """Mean absolute error ``mean |y - y_hat|`` over all elements; returns a scalar.

    Examples:
        >>> import torch
        >>> L1Loss()(torch.zeros(4), torch.ones(4))
        tensor(1.)
    """

    def forward(self, pred: Tensor, target: Tensor) -> Tensor:
        check_pair(pred, target, "l1")
        return (pred - target).abs().mean()
