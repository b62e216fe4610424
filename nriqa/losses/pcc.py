"""Pearson correlation over a batch, and the PCC loss term 1 - |PCC| (thesis ch. 5)."""

from __future__ import annotations

import torch
from torch import Tensor, nn

from nriqa.losses._checks import check_pair

# Added to var(y_hat) * var(y) under the square root so that nearly constant inputs fade smoothly
# to PCC 0 with bounded gradients. For standard deviations whose product is above ~1e-5 the
# relative change of the PCC is below 1e-6.
EPS = 1e-16


def pearson(pred: Tensor, target: Tensor, eps: float = EPS) -> Tensor:
    r"""Differentiable Pearson correlation of all elements of ``pred`` and ``target``, flattened.

    .. math::
        \mathrm{PCC} = \frac{\operatorname{mean}(a b)}{\sqrt{\operatorname{mean}(a^2)\,
                       \operatorname{mean}(b^2) + \varepsilon}},
        \quad a = \hat y - \bar{\hat y},\ b = y - \bar y

    The thesis computes it over the whole batch with no guard, so a constant prediction (a dead
    final ReLU) or a constant target gives 0/0. Here ``eps`` keeps the denominator positive:
    when either input is constant the PCC is **0** (the loss term ``1 - |PCC|`` is 1) with finite
    gradients (exact constancy is tested, so float rounding in the mean cannot fake a spread);
    nearly constant inputs fade smoothly towards 0, and for ordinary inputs the value equals the textbook PCC to ~1e-6.

    Args:
        pred: predictions, any shape.
        target: targets, same shape as ``pred``.
        eps: guard added to the product of the variances, > 0.

    Returns:
        Scalar tensor in [-1, 1].

    Examples:
        >>> x = torch.arange(5.0)
        >>> pearson(x, 2 * x + 1)
        tensor(1.)
        >>> pearson(torch.zeros(5), x)
        tensor(0.)
    """
    check_pair(pred, target, "pcc")
    a = pred.flatten() - pred.mean()
    b = target.flatten() - target.mean()
    cov = (a * b).mean()
    den = torch.sqrt(a.square().mean() * b.square().mean() + eps)
    # The mean of a constant vector is not always that constant in floating point, which would
    # leave a tiny spurious spread; test constancy exactly instead.
    constant = (pred.amax() == pred.amin()) | (target.amax() == target.amin())
    return torch.where(constant, torch.zeros_like(cov), cov / den).clamp(-1.0, 1.0)


class PCCLoss(nn.Module):
    """The PCC loss term ``1 - |PCC(y, y_hat)|`` over the whole batch (thesis ch. 5); see :func:`pearson`."""

    def __init__(self, eps: float = EPS) -> None:
        super().__init__()
        if not eps > 0:
            raise ValueError(f"pcc: eps must be > 0, got {eps}")
        self.eps = float(eps)

    def forward(self, pred: Tensor, target: Tensor) -> Tensor:
        return 1.0 - pearson(pred, target, self.eps).abs()

    def extra_repr(self) -> str:
        return f"eps={self.eps}"
