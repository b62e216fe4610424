"""Correlation between predicted and true quality scores: PCC, SROCC, Kendall tau (thesis ch. 5).

These are the evaluation numbers of tables 5.3-5.8, returned as python floats. They never return
NaN: when either input is constant the correlation is undefined, and it is reported as **0.0**
(no evidence of association) rather than poisoning a per-fold mean with NaN.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor
from torchmetrics.functional import kendall_rank_corrcoef, pearson_corrcoef, spearman_corrcoef


def _prepare(a, b, fn: str) -> tuple[Tensor, Tensor] | None:
    """Validate and convert to float64; ``None`` means "a side is constant: report 0.0"."""
    try:
        a = torch.as_tensor(a).detach().to("cpu", torch.float64)
        b = torch.as_tensor(b).detach().to("cpu", torch.float64)
    except (TypeError, ValueError, RuntimeError) as exc:
        raise TypeError(f"{fn}: inputs must be 1-D tensors or arrays of numbers ({exc})") from None
    if a.ndim != 1 or b.ndim != 1:
        raise ValueError(
            f"{fn}: inputs must be 1-D, got shapes {tuple(a.shape)} and {tuple(b.shape)}; flatten them first"
        )
    if a.numel() != b.numel():
        raise ValueError(f"{fn}: inputs must have the same length, got {a.numel()} and {b.numel()}")
    if a.numel() < 2:
        raise ValueError(f"{fn}: need at least 2 pairs, got {a.numel()}")
    if not (torch.isfinite(a).all() and torch.isfinite(b).all()):
        raise ValueError(f"{fn}: inputs contain NaN or Inf; drop or fix those entries first")
    if a.min() == a.max() or b.min() == b.max():
        return None
    return a, b


def _finish(value: Tensor) -> float:
    r = float(value)
    return min(1.0, max(-1.0, r)) if math.isfinite(r) else 0.0


def pcc(a, b) -> float:
    """Pearson linear correlation coefficient of two 1-D sequences of scores.

    Args:
        a: ``(N,)`` predicted scores (tensor or array-like), N >= 2, finite.
        b: ``(N,)`` true scores.

    Returns:
        PCC in [-1, 1]; 0.0 when either input is constant.

    Examples:
        >>> pcc(torch.tensor([1.0, 2.0, 3.0]), torch.tensor([2.0, 4.0, 7.0])) > 0.99
        True
    """
    pair = _prepare(a, b, "pcc")
    return 0.0 if pair is None else _finish(pearson_corrcoef(*pair))


def srocc(a, b) -> float:
    """Spearman rank-order correlation coefficient (ties get their mean rank).

    Computed by :func:`torchmetrics.functional.spearman_corrcoef`, which adds 1e-6 to the
    denominator: the value is biased towards 0 by about ``1e-6 / var(ranks)`` (1e-9 at N = 100).

    Args:
        a: ``(N,)`` predicted scores, N >= 2, finite.
        b: ``(N,)`` true scores.

    Returns:
        SROCC in [-1, 1]; 0.0 when either input is constant.

    Examples:
        >>> round(srocc(torch.tensor([1.0, 2.0, 3.0]), torch.tensor([1.0, 10.0, 100.0])), 4)
        1.0
    """
    pair = _prepare(a, b, "srocc")
    return 0.0 if pair is None else _finish(spearman_corrcoef(*pair))


def kendall_tau(a, b) -> float:
    """Kendall rank correlation coefficient, tau-b (adjusted for ties, as ``scipy.stats.kendalltau``).

    Args:
        a: ``(N,)`` predicted scores, N >= 2, finite.
        b: ``(N,)`` true scores.

    Returns:
        Kendall tau in [-1, 1]; 0.0 when either input is constant.

    Examples:
        >>> kendall_tau(torch.tensor([1.0, 2.0, 3.0]), torch.tensor([3.0, 2.0, 1.0]))
        -1.0
    """
    pair = _prepare(a, b, "kendall_tau")
    return 0.0 if pair is None else _finish(kendall_rank_corrcoef(*pair, variant="b"))


def bootstrap_interval(
    fn, a, b, *, other=None, resamples: int = 2000, level: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """A correlation and its percentile bootstrap interval, resampling the pairs with replacement.

    With ``other`` (a second predictor's ``(N,)`` scores of the same items) the statistic is the
    paired difference ``fn(a, b) - fn(other, b)``, each resample taking the same items for both:
    whether two predictors differ on these items, which two separate intervals cannot tell.
    Deterministic for a ``seed``. On few items (the 48 test images of one held-out scene) an
    SROCC of 0.97 carries an interval of several hundredths: differences below that are not
    measured.

    Args:
        fn: :func:`pcc`, :func:`srocc` or :func:`kendall_tau`.
        a: ``(N,)`` predicted scores, N >= 2, finite.
        b: ``(N,)`` true scores.
        other: ``(N,)`` scores of a second predictor, or ``None``.
        resamples: number of bootstrap resamples (>= 100).
        level: coverage of the interval, in (0, 1).
        seed: seed of the resampling.

    Returns:
        ``(estimate, low, high)``: the statistic on all items and the interval's bounds.

    Examples:
        >>> est, low, high = bootstrap_interval(srocc, torch.arange(20.0), torch.arange(20.0) ** 2)
        >>> (est, low, high)
        (1.0, 1.0, 1.0)
    """
    check_bootstrap(resamples, level, "bootstrap_interval")
    a = torch.as_tensor(a, dtype=torch.float64)
    b = torch.as_tensor(b, dtype=torch.float64)
    if other is not None:
        other = torch.as_tensor(other, dtype=torch.float64)
        if other.shape != a.shape:
            raise ValueError(
                f"bootstrap_interval: other must have the shape of a, {tuple(a.shape)}, got {tuple(other.shape)}"
            )

    def statistic(index: Tensor) -> float:
        value = fn(a[index], b[index])
        return value if other is None else value - fn(other[index], b[index])

    estimate = statistic(torch.arange(a.numel()))  # also validates the inputs, with fn's own message
    generator = torch.Generator().manual_seed(seed)
    draws = torch.randint(0, a.numel(), (resamples, a.numel()), generator=generator)
    values = [statistic(index) for index in draws]
    return (estimate, *percentile_bounds(values, level))


def check_bootstrap(resamples: int, level: float, who: str) -> None:
    """Refuse a bootstrap with fewer than 100 resamples or a level outside (0, 1) (``ValueError`` naming ``who``)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"{who}: level must be in (0, 1), got {level}")
    if resamples < 100:
        raise ValueError(f"{who}: need at least 100 resamples, got {resamples}")


def percentile_bounds(values, level: float) -> tuple[float, float]:
    """The percentile interval of bootstrap ``values`` at ``level``: their quantiles at ``(1 -+ level) / 2``."""
    tail = (1.0 - level) / 2.0
    values = torch.as_tensor(values, dtype=torch.float64)
    low, high = torch.quantile(values, torch.tensor([tail, 1.0 - tail], dtype=torch.float64)).tolist()
    return low, high
