"""A calibrated interval for a pooled score: where the true mean SSIM lies, at a stated level.

A single-image scorer errs by a few hundredths on most renders and by more on some (dark, sparse
low-sample images; fine texture read as noise). The interval says how far, measured: split conformal
prediction on images the weights never learnt. The predicted scores are cut into bands; in a band of
``n`` calibration residuals ``r = true - predicted``, sorted, the offsets are the ``floor(a (n + 1))``-th
and the ``ceil((1 - a) (n + 1))``-th smallest, ``a = (1 - level) / 2``, so that a new image exchangeable
with the band's calibration images has its truth below ``score + low`` with probability at most ``a``
and above ``score + high`` with probability at most ``a``. Images of one scene are not exchangeable with
another scene's, so the level is a target, not a guarantee: the coverage measured on scenes outside the
calibration is on the weights' card (``score_interval``, docs/scoring.md).

The interval is for the true mean SSIM, so it need not contain the score itself where a band's
residuals are all of one sign; both ends are clipped to [0, 1].

Example:
    >>> iv = ScoreInterval.fit(predicted, true, level=0.9)   # doctest: +SKIP
    >>> iv(0.93)                                               # doctest: +SKIP
    (0.905, 0.951)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from nriqa.errors import NriqaError

__all__ = ["ScoreInterval", "IntervalError", "EDGES", "LOOP_KINDS", "conformal_ranks", "loop_card_key"]

#: default band edges of the predicted score: finer where most renders end (near convergence)
EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 0.98, 1.0)

#: the render loops an interval can be calibrated on apart (``Scorer.loop_intervals``): samples spread
#: evenly, or placed by the scorer's map
LOOP_KINDS = ("uniform", "adaptive")


def loop_card_key(kind: str) -> str:
    """The model card's key of the interval calibrated on render loops of ``kind`` (one of :data:`LOOP_KINDS`)."""
    if kind not in LOOP_KINDS:
        raise ValueError(f"loop intervals are for loop kinds {list(LOOP_KINDS)}, got {kind!r}")
    return f"score_interval_loop_{kind}"


def conformal_ranks(n: int, level: float) -> tuple[int, int]:
    """1-based ranks of the low and high ends among ``n`` sorted calibration residuals for a two-sided ``level``:
    ``floor(a (n + 1))`` and ``ceil((1 - a) (n + 1))``, ``a = (1 - level) / 2``; below 1 or above ``n``: no bound."""
    a = (1.0 - level) / 2.0
    # ranks as exact as the level allows: (1 - 0.8) / 2 * 10 must be 1, not 0.999...
    return math.floor(a * (n + 1) + 1e-9), math.ceil((1.0 - a) * (n + 1) - 1e-9)


class IntervalError(NriqaError):
    """A calibration that cannot be made or read (too few images, bad level, malformed entry)."""


@dataclasses.dataclass(frozen=True)
class ScoreInterval:
    """Offsets per band of the predicted score; call it on a score (or an array of them).

    Attributes:
        level: the two-sided target level, e.g. 0.9.
        edges: band edges, increasing, from 0 to 1 (``len(bands) + 1`` of them).
        low, high: per band, the offsets added to a score for the interval's ends (``-inf``/``+inf``:
            no bound from the data, the end is then 0 or 1).
        counts: calibration images per band.
        source: what the calibration images were (free text, for the card).
    """

    level: float
    edges: tuple[float, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    counts: tuple[int, ...]
    source: str = ""

    @classmethod
    def fit(
        cls,
        predicted: Sequence[float] | np.ndarray,
        true: Sequence[float] | np.ndarray,
        *,
        level: float = 0.9,
        edges: Sequence[float] = EDGES,
        min_count: int = 30,
        source: str = "",
    ) -> ScoreInterval:
        """Fit the offsets from calibration images' predicted and true scores.

        A band with fewer than ``min_count`` images is merged into its neighbour with fewer images
        (the one below on a tie), until every band has enough. Non-finite pairs are dropped.

        Raises:
            IntervalError: a level outside (0, 1), edges not increasing from 0 to 1, mismatched
                lengths, or fewer than ``min_count`` usable images in all.
        """
        if not 0.0 < level < 1.0:
            raise IntervalError(f"level must be in (0, 1), got {level}")
        edges = [float(e) for e in edges]
        if len(edges) < 2 or edges[0] != 0.0 or edges[-1] != 1.0 or any(b <= a for a, b in zip(edges, edges[1:])):
            raise IntervalError(f"band edges must increase from 0 to 1, got {edges}")
        p = np.asarray(predicted, dtype=np.float64).ravel()
        t = np.asarray(true, dtype=np.float64).ravel()
        if p.shape != t.shape:
            raise IntervalError(f"{p.size} predicted scores but {t.size} true ones")
        keep = np.isfinite(p) & np.isfinite(t)
        p, t = p[keep], t[keep]
        if p.size < max(min_count, 1):
            raise IntervalError(f"{p.size} usable calibration images; need at least {max(min_count, 1)}")
        band = _band_of(np.clip(p, 0.0, 1.0), edges)
        counts = np.bincount(band, minlength=len(edges) - 1).tolist()
        while len(counts) > 1 and min(counts) < min_count:
            i = int(np.argmin(counts))
            j = i - 1 if i == len(counts) - 1 or (i > 0 and counts[i - 1] <= counts[i + 1]) else i + 1
            # drop the edge between bands i and j; band indices above it shift down by one
            cut = max(i, j)
            edges.pop(cut)
            counts[min(i, j)] += counts.pop(cut)
        band = _band_of(np.clip(p, 0.0, 1.0), edges)
        low, high = [], []
        for k in range(len(edges) - 1):
            r = np.sort(t[band == k] - p[band == k])
            n = r.size
            lo_rank, hi_rank = conformal_ranks(n, level)
            low.append(float(r[lo_rank - 1]) if lo_rank >= 1 else -math.inf)
            high.append(float(r[hi_rank - 1]) if hi_rank <= n else math.inf)
        return cls(float(level), tuple(edges), tuple(low), tuple(high), tuple(int(c) for c in counts), source)

    def __call__(self, score: float | np.ndarray) -> tuple[float, float] | tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` ends for a score, or arrays of them for an array of scores (NaN stays NaN)."""
        s = np.asarray(score, dtype=np.float64)
        band = self.band(s)
        lo = np.clip(s + np.asarray(self.low)[band], 0.0, 1.0)
        hi = np.clip(s + np.asarray(self.high)[band], 0.0, 1.0)
        if s.ndim == 0:
            return float(lo), float(hi)
        return lo, hi

    def band(self, score: float | np.ndarray) -> np.ndarray:
        """Index of the band each score falls in (scores outside [0, 1], and NaN, count as the nearest end)."""
        s = np.asarray(score, dtype=np.float64)
        return _band_of(np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0), self.edges)

    def covers(self, predicted: np.ndarray, true: np.ndarray) -> np.ndarray:
        """Per image, whether its true score lies in the interval of its predicted one."""
        lo, hi = self(np.asarray(predicted, dtype=np.float64))
        t = np.asarray(true, dtype=np.float64)
        return (lo <= t) & (t <= hi)

    def to_dict(self) -> dict:
        """A JSON-ready form (infinite offsets as ``null``), for a model card."""

        def finite(xs):
            return [x if math.isfinite(x) else None for x in xs]

        return {
            "level": self.level,
            "edges": list(self.edges),
            "low": finite(self.low),
            "high": finite(self.high),
            "counts": list(self.counts),
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, entry: Mapping) -> ScoreInterval:
        """Read :meth:`to_dict`'s form back; a malformed entry raises :class:`IntervalError`."""
        try:
            edges = tuple(float(e) for e in entry["edges"])
            low = tuple(-math.inf if x is None else float(x) for x in entry["low"])
            high = tuple(math.inf if x is None else float(x) for x in entry["high"])
            counts = tuple(int(c) for c in entry["counts"])
            level = float(entry["level"])
        except (KeyError, TypeError, ValueError) as exc:
            raise IntervalError(f"malformed score_interval entry ({type(exc).__name__}: {exc})") from None
        n = len(edges) - 1
        if n < 1 or not (len(low) == len(high) == len(counts) == n) or not 0.0 < level < 1.0:
            raise IntervalError(
                f"malformed score_interval entry: {len(edges)} edges, {len(low)}/{len(high)} offsets, level {level}"
            )
        if edges[0] != 0.0 or edges[-1] != 1.0 or any(b <= a for a, b in zip(edges, edges[1:])):
            raise IntervalError(f"malformed score_interval entry: edges {list(edges)} do not increase from 0 to 1")
        return cls(level, edges, low, high, counts, str(entry.get("source", "")))


def _band_of(scores: np.ndarray, edges: Sequence[float]) -> np.ndarray:
    """Band index of each score in [0, 1]: ``edges[k] <= s < edges[k + 1]``, 1 in the last band."""
    inner = np.asarray(edges[1:-1], dtype=np.float64)
    return np.searchsorted(inner, scores, side="right")
