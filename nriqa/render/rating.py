"""What the scorer rates in a render loop, and when: the image, a fresh probe, or nothing.

A scorer is only right on images like those it learnt from: ``fcnn_fast`` learnt from renders of at
most 64 samples per pixel (128 in the door scene), and beyond that its maps mark edges rather than
noise (the default ``unet_fast`` learnt up to 1024). So once the image passes ``map_spp`` samples
per pixel, a map comes from a probe: a fresh uniform step of ``probe_spp`` samples, rated alone and
folded into the image like any other samples; the image's predicted score is then the error model's at its counts
(:class:`~nriqa.render.error_model.ErrorModel`), updated at every step.

A two-buffer scorer (``needs_twin`` true) rates an image together with an independent twin. A loop
has no independent render of its image, but its half buffer splits the image's samples into two
independent halves (:meth:`~nriqa.render.film.HalfFilm.halves`): the scorer rates the first half with the second as
its twin, and :func:`at_full_samples` carries that map to the whole image's samples. Its estimate
does not saturate past a training range (the halves differ by their noise at any count), so it
rates the image's halves at every count and never a probe: ``map_spp`` applies to single-image
scorers only. Rated through probes and the error model instead, the two-buffer estimate of a
participating medium at ~300 spp read 0.018 above the true SSIM, and a glass Cornell box's 0.08
(docs/results/render_compare.md, run 5).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from nriqa.render.clock import Clock
from nriqa.render.error_model import ErrorModel
from nriqa.render.film import Film

__all__ = [
    "HalvesRating",
    "Probes",
    "Rater",
    "at_full_samples",
    "needs_twin",
    "rate_halves",
    "reads_pixel_filter",
    "spp_to_reach",
    "with_twin",
]


def needs_twin(scorer) -> bool:
    """Whether ``scorer`` rates an image together with its twin (a two-buffer scorer: ``scorer.needs_twin``)."""
    return bool(getattr(scorer, "needs_twin", False))


def reads_pixel_filter(scorer) -> str:
    """The pixel filter of the renders ``scorer`` learnt to read (``scorer.pixel_filter``; ``"box"`` if it has none)."""
    return str(getattr(scorer, "pixel_filter", "box"))


def with_twin(scorer, twin: np.ndarray | None):
    """``scorer`` called with ``twin=twin`` (``scorer`` itself when ``twin`` is ``None``)."""
    return scorer if twin is None else functools.partial(scorer, twin=twin)


def at_full_samples(quality: np.ndarray, share: np.ndarray) -> np.ndarray:
    r"""Per-pixel SSIM of an image from that of a subset of its samples, ``share`` of them.

    In one SSIM window, with local reference variance ``v`` and noise variance ``y`` (as in
    :mod:`nriqa.eval.baselines.dual_buffer`), ``SSIM ~ X / (X + y)`` with ``X = 2 v + C2``, and the
    noise variance falls as 1 / samples. A subset with ``share`` ``k`` of the samples has
    ``y / k``: from its rating ``q = X / (X + y / k)``, ``y / X = k (1 / q - 1)``, so the whole image
    rates ``q / (q + (1 - q) k)`` (``2 q / (1 + q)`` for ``k = 1/2``, the dual-buffer correction).
    ``quality`` is clipped to [0, 1] first; ``k = 1`` leaves it as it is.
    """
    q = np.clip(np.asarray(quality, dtype=np.float64), 0.0, 1.0)
    k = np.asarray(share, dtype=np.float64)
    den = q + (1.0 - q) * k
    return np.divide(q, den, out=np.zeros_like(q), where=den > 0).astype(np.float32)


def spp_to_reach(score: float, spp: float, target: float, higher_is_better: bool = True) -> float | None:
    r"""Samples per pixel at which a pooled ``score`` of an image of ``spp`` samples would reach ``target``.

    SSIM (``higher_is_better``): the law of :func:`at_full_samples` solved for the share, i.e. the
    noise variance falling as 1 / samples in ``q = X / (X + y)``: ``spp * t (1 - q) / (q (1 - t))``.
    The MAE (lower is better) falls as 1 / sqrt(samples): ``spp * (score / target)^2``. Applied to
    the pooled score rather than per pixel, it is an estimate, used to size a loop's steps
    (:meth:`~nriqa.render.stop.TargetScore.spp_to_go`). ``None`` where no count reaches the target
    (an SSIM target of 1 or more, an MAE target of 0 or less, a score that is not finite).
    """
    if not np.isfinite(score) or not spp > 0:
        return None
    if higher_is_better:
        if not 0.0 < target < 1.0:
            return None
        q = float(np.clip(score, 1e-6, 1.0 - 1e-6))
        return spp * target * (1.0 - q) / (q * (1.0 - target))
    if not target > 0.0:
        return None
    return spp * (max(score, 0.0) / target) ** 2


@dataclasses.dataclass(frozen=True)
class HalvesRating:
    """A two-buffer scorer's map of a whole image, rated from its halves: ``map`` ``(H, W)``, ``score`` its mean;
    ``low``: the low end of the scorer's calibrated interval carried to the whole image (``None`` without one)."""

    map: np.ndarray
    score: float
    low: float | None = None


def rate_halves(scorer, first: np.ndarray, *, second: np.ndarray, share: np.ndarray, **kwargs) -> HalvesRating:
    """Rate ``first`` with ``second`` as its twin, carried to the whole image by :func:`at_full_samples`.

    Where the scorer gives the first half's interval (``low``; it was calibrated on an image and its twin of
    equal samples, as the halves are), its low end is carried by the same law, at the mean share, and kept
    as an offset below the whole image's score. ``kwargs`` (e.g. ``hdr=True``) go to the scorer.
    """
    result = scorer(first, twin=second, **kwargs)
    qmap = at_full_samples(result.map, share)
    score = float(qmap.mean())
    low = getattr(result, "low", None)
    if low is not None:
        k = np.mean(share)
        reach = float(at_full_samples(result.score, k)) - float(at_full_samples(low, k))
        low = score - max(reach, 0.0)
    return HalvesRating(qmap, score, low)


def halves_scorer(scorer, second: np.ndarray, share: np.ndarray):
    """``scorer`` as a one-argument call on the first half: :func:`rate_halves` with ``second`` and ``share``."""
    return functools.partial(rate_halves, scorer, second=second, share=share)


@dataclasses.dataclass(frozen=True)
class Probes:
    """When the scorer rates a probe instead of the image.

    Args:
        map_spp: the most samples per pixel at which the scorer rates the image itself; beyond,
            it rates probes. ``None``: always the image.
        probe_spp: samples per pixel of a probe (within the scorer's range; rounded to whole
            multiples of the film's ``quantum``). A probe is skipped when the budget has no room for it.
        back_to_back: probes may follow each other. Where steps are uniform anyway a probe displaces
            nothing; where a probe displaces a placed step, every other step at most is one.
        grace_step: the step that takes the image past ``map_spp`` is still rated on the image
            (the range is judged on the image before the step, not after).
    """

    map_spp: float | None = 64
    probe_spp: int = 32
    back_to_back: bool = False
    grace_step: bool = False

    def __post_init__(self):
        if self.map_spp is not None and not self.map_spp >= 0:
            raise ValueError(f"map_spp must be >= 0 or None (the scorer always rates the image), got {self.map_spp}")
        if not self.probe_spp >= 1:
            raise ValueError(f"probe_spp must be >= 1, got {self.probe_spp}")


class Rater:
    """The scorer's side of a loop: rates the image or a probe when due, keeps the error model and the prediction.

    Args:
        scorer: a :class:`~nriqa.inference.scorer.Scorer` or anything called like one; ``None``
            rates nothing (``predicted`` stays ``None``).
        probes: when a probe stands in for the image.
        clock: the loop's clock (scoring time, cadence).
        needs_map: the placement needs a map: the first row is rated whatever the cadence. It places
            samples by the map, so the loop is of kind ``"adaptive"`` (else ``"uniform"``): where the
            scorer has an interval calibrated on that kind of loop (``Scorer.loop_intervals``), ``low`` is
            its low end; else the result's.
    """

    def __init__(self, scorer, probes: Probes, clock: Clock, needs_map: bool):
        self.scorer, self.probes, self.clock, self.needs_map = scorer, probes, clock, needs_map
        kind = "adaptive" if needs_map else "uniform"
        self.loop_interval = (getattr(scorer, "loop_intervals", None) or {}).get(kind)
        self.model = ErrorModel(scorer.higher_is_better) if scorer is not None else None
        self.higher_is_better = scorer.higher_is_better if scorer is not None else True
        self.needs_twin = needs_twin(scorer)
        self.predicted: float | None = None
        # the low end of the scorer's calibrated interval for ``predicted``: only where the prediction is the
        # Scorer's score of the image or of its halves (not the error model's past ``map_spp``)
        self.low: float | None = None

    def beyond(self, spp: float) -> bool:
        """Whether an image of ``spp`` samples per pixel is past the scorer's range (never for a
        two-buffer scorer: the halves' estimate holds at any count, see the module docstring)."""
        if self.scorer is None or self.needs_twin or self.probes.map_spp is None:
            return False
        return spp > self.probes.map_spp

    def rate(
        self, film: Film, probe: tuple[np.ndarray, int] | None, spp_before: float, final: bool
    ) -> tuple[bool, bool]:
        """Rate the step just rendered: the probe ``(image, spp)`` if it was one, else the image when due.

        ``spp_before``: samples per pixel before the step; ``final``: the run ends at this row.
        Returns ``(scored, fresh)``: whether the scorer ran, and whether ``predicted`` is new.
        """
        beyond = self.beyond(spp_before if self.probes.grace_step else film.spp)
        if probe is not None:  # single-image scorers only: a two-buffer scorer is never beyond its range
            self.model.add(self.clock.scored(self.scorer, probe[0]).map, probe[1])
            scored = True
        else:
            first = self.needs_map and self.model is not None and self.model.noise is None
            scored = self.scorer is not None and (first or (not beyond and (self.clock.score_due() or final)))
            if scored:
                result = self._rate_image(film)
                self.predicted = result.score
                self.low = getattr(result, "low", None)
                if self.loop_interval is not None:
                    self.low = self.loop_interval(result.score)[0]
                self.model.add(result.map, film.count.copy())
        if beyond and self.model.noise is not None:
            self.predicted, self.low = self.model.predict(film.count), None
        return scored, scored or beyond

    def _rate_image(self, film: Film):
        """The scorer's rating of the film's image, timed; a two-buffer scorer rates its halves."""
        if not self.needs_twin:
            return self.clock.scored(self.scorer, film.image)
        first, second, share = film.halves()
        return self.clock.scored(halves_scorer(self.scorer, second, share), first)

    def probe_size(self, film: Film) -> int:
        """Samples per pixel of a probe: ``probe_spp`` in whole multiples of the film's ``quantum``."""
        return film.quantum * max(1, round(self.probes.probe_spp / film.quantum))

    def probe_due(self, film: Film, scored: bool) -> bool:
        """Whether the next step should be a probe (if the budget has room for one)."""
        in_a_row = self.probes.back_to_back or not scored
        return self.beyond(film.spp) and self.clock.score_due() and in_a_row
