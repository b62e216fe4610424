"""Stop rules: when a render loop ends, and the budgets its steps are sized to.

A loop checks its rules in order after every row of its log; the first one reached ends the run
and names the row's ``stop``. A rule may also state a budget: ``time_budget()`` (seconds of render
plus scoring) and ``spp_budget()`` (mean samples per pixel) cut the steps so that the last one
does not overshoot; and, from the latest row, ``spp_to_go()``: the samples per pixel it expects the
run still needs, to which the next step is cut (:class:`TargetScore`: where the prediction should
reach the target, so that the run lands on it instead of stepping past it). A rule that knows the
run ends at a row whatever the score (``final``) makes the loop rate that row, so the log ends on
a fresh prediction.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import ClassVar

from nriqa.render.film import Film
from nriqa.render.rating import spp_to_reach

__all__ = [
    "MaxSpp",
    "Progress",
    "SppBudget",
    "StopRule",
    "SureOfTarget",
    "TargetScore",
    "TimeBudget",
    "budgets",
    "first_reached",
    "spp_to_go",
]


@dataclasses.dataclass(frozen=True)
class Progress:
    """What a stop rule sees after a row: the film, the row, and whether ``row["predicted"]`` is fresh.

    ``fresh``: the prediction was made at this row (the scorer rated the image or a probe, or the
    error model predicted the image's score), not carried over from an earlier one.
    ``higher_is_better``: the scorer's direction (SSIM: higher; the MAE: lower).
    """

    film: Film
    row: dict
    fresh: bool
    higher_is_better: bool


class StopRule(abc.ABC):
    """A condition that ends a loop; ``name`` is the ``stop`` it writes in the last row."""

    name: ClassVar[str]

    @abc.abstractmethod
    def reached(self, progress: Progress) -> bool:
        """Whether the run ends at this row."""

    def final(self, film: Film) -> bool:
        """Whether the run ends at this row whatever the score (checked before the row is rated)."""
        return False

    def time_budget(self) -> float | None:
        """Seconds of render plus scoring this rule allows, if it limits them."""
        return None

    def spp_budget(self) -> float | None:
        """Mean samples per pixel this rule allows, if it limits them."""
        return None

    def spp_to_go(self, progress: Progress) -> float | None:
        """Mean samples per pixel more this rule expects the run to need after this row (``None``: no estimate)."""
        return None


@dataclasses.dataclass(frozen=True)
class TargetScore(StopRule):
    """The fresh predicted pooled score reaches ``target`` (``>=`` for SSIM, ``<=`` for the MAE).

    Steps toward the target: after a fresh prediction short of it, :meth:`spp_to_go` is the samples
    per pixel more at which the prediction should reach it (:func:`~nriqa.render.rating.spp_to_reach`),
    and the loop cuts its next step to that (never below the schedule's least step). Grown steps
    (a quarter of the samples done) would otherwise move SSIM past a narrow window in one step:
    at 20-30 spp one such step adds about 0.02.
    """

    target: float
    name: ClassVar[str] = "target"

    def reached(self, progress: Progress) -> bool:
        predicted = progress.row["predicted"]
        if not progress.fresh or predicted is None:
            return False
        return predicted >= self.target if progress.higher_is_better else predicted <= self.target

    def spp_to_go(self, progress: Progress) -> float | None:
        predicted = progress.row["predicted"]
        aim = self.aim(progress)
        if not progress.fresh or predicted is None or aim is None:
            return None
        spp = float(progress.film.spp)
        need = spp_to_reach(predicted, spp, aim, progress.higher_is_better)
        return None if need is None else max(need - spp, 0.0)

    def aim(self, progress: Progress) -> float | None:
        """The score the next step should bring the prediction to (``None``: no aim from this row)."""
        return self.target


@dataclasses.dataclass(frozen=True)
class SureOfTarget(TargetScore):
    """The low end of the scorer's calibrated interval for a fresh score of the image reaches ``target``.

    The interval (``ScoreResult.low``; :class:`~nriqa.inference.interval.ScoreInterval`) is two-sided at
    the card's level, each side at half its miss rate: a 90 % interval's low end lies above the true mean
    SSIM of about one image in twenty, on scenes like those it was calibrated on. A row whose prediction
    has no low end (the error model's, past ``map_spp``; a scorer without a calibration) never stops here.

    Steps toward it as :class:`TargetScore` does, aiming the prediction at ``target`` plus the interval's
    lower reach at the latest score (:meth:`aim`).
    """

    name: ClassVar[str] = "sure"

    def reached(self, progress: Progress) -> bool:
        low = progress.row.get("low")
        return progress.fresh and low is not None and low >= self.target

    def aim(self, progress: Progress) -> float | None:
        predicted, low = progress.row["predicted"], progress.row.get("low")
        if predicted is None or low is None:
            return None
        return min(self.target + max(predicted - low, 0.0), 0.9999)


@dataclasses.dataclass(frozen=True)
class TimeBudget(StopRule):
    """Render plus scoring time reaches ``seconds``."""

    seconds: float
    name: ClassVar[str] = "time"

    def reached(self, progress: Progress) -> bool:
        return progress.row["seconds"] >= self.seconds

    def time_budget(self) -> float:
        return self.seconds


@dataclasses.dataclass(frozen=True)
class SppBudget(StopRule):
    """The mean samples per pixel reach ``spp`` (the last step is cut to end there)."""

    spp: float
    name: ClassVar[str] = "spp"

    def reached(self, progress: Progress) -> bool:
        return progress.film.count.mean() >= self.spp

    def spp_budget(self) -> float:
        return self.spp


@dataclasses.dataclass(frozen=True)
class MaxSpp(StopRule):
    """One more step of ``step_spp`` would pass ``spp`` samples per pixel (a larger step is cut to fit).

    The run's last row is known before it is rated, so the loop rates it (see :class:`StopRule`).
    """

    spp: float
    step_spp: float
    name: ClassVar[str] = "max_spp"

    def reached(self, progress: Progress) -> bool:
        return self.final(progress.film)

    def final(self, film: Film) -> bool:
        return film.spp + self.step_spp > self.spp

    def spp_budget(self) -> float:
        return self.spp


def first_reached(rules: list[StopRule], progress: Progress) -> StopRule | None:
    """The first rule in ``rules`` that ends the run at this row, or ``None``."""
    return next((rule for rule in rules if rule.reached(progress)), None)


def spp_to_go(rules: list[StopRule], progress: Progress) -> float | None:
    """The fewest samples per pixel more that any of ``rules`` expects the run to need (``None``: no estimate)."""
    return min((s for s in (rule.spp_to_go(progress) for rule in rules) if s is not None), default=None)


def budgets(rules: list[StopRule]) -> tuple[float | None, float | None]:
    """``(seconds, spp)``: the tightest time and samples-per-pixel budgets the rules state (``None``: unlimited)."""
    seconds = [s for s in (rule.time_budget() for rule in rules) if s is not None]
    spp = [s for s in (rule.spp_budget() for rule in rules) if s is not None]
    return min(seconds, default=None), min(spp, default=None)
