"""How far to trust a score: its spread over the image's flips and turns, and an interval that widens with it.

A render flipped or turned a quarter is the same render, and its true SSIM is the same; a network reads the
eight views a little differently, and most differently where it is least sure what it sees (dense sparkle,
stones, thin geometry: the families it misreads). The spread is the standard deviation of the pooled score over
the eight views (the plain one, turned 90°, 180°, 270°, and the four of its mirror image). On 2670 in-house
renders it never learnt (stop 70) it ranks the error of the score at a Spearman correlation of 0.57: the tenth of
renders with the widest spread err 8× more than the half with the narrowest.

:class:`SpreadInterval` is split conformal prediction with offsets scaled by the spread: residuals
``r = true - score`` are divided by ``floor + spread`` (``floor``, the calibration's median spread, keeps a
render the network reads the same every way from a zero-width interval), and the interval is
``score + q * (floor + spread)`` for the ``floor(a (n + 1))``-th and ``ceil((1 - a) (n + 1))``-th of the ``n``
sorted normalised residuals, ``a = (1 - level) / 2``; both ends are clipped to [0, 1]. The score itself stays the
plain view's. It costs seven more passes of the network, so a Scorer computes it only when asked
(``Scorer(..., spread=True)``, ``nriqa-predict --spread``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import torch
from torch import Tensor

from nriqa.inference.interval import IntervalError, conformal_ranks

__all__ = ["SpreadInterval", "VIEWS", "view_scores", "score_spread"]

#: the views a spread is taken over: the image and its mirror image, each turned 0, 90, 180 and 270 degrees
VIEWS = 8


def _views(batch: Tensor, turns: tuple[int, ...]) -> Tensor:
    """``(len(turns) * 2 * B, C, ., .)``: for each turn ``k``, the batch and its mirror image turned ``k`` quarters."""
    return torch.cat([torch.rot90(x, k, (-2, -1)) for k in turns for x in (batch, batch.flip(-1))])


def view_scores(score: Callable[[Tensor], Tensor], batch: Tensor, plain: Tensor | None = None) -> Tensor:
    """``(B, 8)`` pooled scores of every view of each image of ``batch`` ``(B, C, H, W)``.

    ``score`` maps a batch of views to their pooled scores ``(N,)``; it is called twice, once with the views of the
    image's own shape (turned 0 and 180 degrees) and once with the quarter-turned ones (``(W, H)``), so images
    need not be square. Column 0 is the image itself: ``plain``, its scores ``(B,)``, where the caller has them
    already (the image is then not scored again).
    """
    b = batch.shape[0]
    upright = _views(batch, (0, 2))  # blocks: plain, mirror, 180, mirror 180
    if plain is None:
        upright = score(upright).reshape(4, b)
    else:
        upright = torch.cat([plain.reshape(1, b).to(upright.device), score(upright[b:]).reshape(3, b)])
    sideways = score(_views(batch, (1, 3))).reshape(4, b)
    return torch.cat([upright, sideways]).T


def score_spread(scores: Tensor) -> Tensor:
    """``(B,)`` standard deviation (over the views, population form) of :func:`view_scores`' ``(B, 8)``."""
    return scores.double().std(dim=1, correction=0).float()


@dataclasses.dataclass(frozen=True)
class SpreadInterval:
    """Offsets in units of ``floor + spread``; call it on a score and its spread (or arrays of them).

    Attributes:
        level: the two-sided target level, e.g. 0.9.
        floor: added to every spread (the calibration's median spread).
        low, high: the normalised offsets (``low`` < 0 < ``high`` as a rule).
        count: calibration images.
        views: views the spread is taken over (:data:`VIEWS`).
        source: what the calibration images were (free text, for the card).
    """

    level: float
    floor: float
    low: float
    high: float
    count: int
    views: int = VIEWS
    source: str = ""

    @classmethod
    def fit(
        cls,
        predicted: Sequence[float] | np.ndarray,
        true: Sequence[float] | np.ndarray,
        spread: Sequence[float] | np.ndarray,
        *,
        level: float = 0.9,
        source: str = "",
    ) -> SpreadInterval:
        """Calibrate on images the weights never learnt: their scores, true mean SSIMs and spreads.

        Raises:
            IntervalError: a level outside (0, 1), arrays of different lengths, non-finite values, or too few
                images for the level (each end needs ``a (n + 1) >= 1``).
        """
        p, t, s = (np.asarray(x, dtype=np.float64).ravel() for x in (predicted, true, spread))
        if not 0.0 < level < 1.0:
            raise IntervalError(f"level must lie in (0, 1), got {level}")
        if not (p.size == t.size == s.size):
            raise IntervalError(f"{p.size} scores, {t.size} true values, {s.size} spreads: give one of each per image")
        if not (np.isfinite(p).all() and np.isfinite(t).all() and np.isfinite(s).all()) or (s < 0).any():
            raise IntervalError("scores, true values and spreads must be finite, spreads >= 0")
        n = p.size
        lo_rank, hi_rank = conformal_ranks(n, level)
        if lo_rank < 1 or hi_rank > n:
            raise IntervalError(f"{n} calibration images are too few for a {level:.0%} interval")
        floor = float(np.median(s))
        if floor <= 0.0:
            raise IntervalError("the median spread of the calibration images is 0: nothing to scale by")
        z = np.sort((t - p) / (floor + s))
        return cls(float(level), floor, float(z[lo_rank - 1]), float(z[hi_rank - 1]), int(n), VIEWS, source)

    def __call__(
        self, score: float | np.ndarray, spread: float | np.ndarray
    ) -> tuple[float, float] | tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` ends for a score and its spread, or arrays of them (NaN stays NaN)."""
        p, s = np.asarray(score, dtype=np.float64), np.asarray(spread, dtype=np.float64)
        unit = self.floor + np.maximum(s, 0.0)
        lo, hi = np.clip(p + self.low * unit, 0.0, 1.0), np.clip(p + self.high * unit, 0.0, 1.0)
        if lo.ndim == 0:
            return float(lo), float(hi)
        return lo, hi

    def to_dict(self) -> dict:
        """A JSON-ready form, for a model card (``score_interval_spread``)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, entry: Mapping) -> SpreadInterval:
        """Read :meth:`to_dict`'s form back; a malformed entry raises :class:`IntervalError`."""
        try:
            iv = cls(
                float(entry["level"]),
                float(entry["floor"]),
                float(entry["low"]),
                float(entry["high"]),
                int(entry["count"]),
                int(entry.get("views", VIEWS)),
                str(entry.get("source", "")),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise IntervalError(f"malformed score_interval_spread entry ({type(exc).__name__}: {exc})") from None
        finite = all(math.isfinite(x) for x in (iv.floor, iv.low, iv.high))
        if not (0.0 < iv.level < 1.0 and finite and iv.floor > 0.0 and iv.low <= iv.high and iv.views == VIEWS):
            raise IntervalError(
                f"malformed score_interval_spread entry: level {iv.level}, floor {iv.floor}, offsets "
                f"{iv.low}/{iv.high}, views {iv.views} (this package takes {VIEWS})"
            )
        return iv
