"""Render loops in Mitsuba 3 driven by a scorer: one driver, with pluggable placement and stop rules.

:func:`render_loop` renders a uniform first pass into a film, then step after step: the scorer
rates the image (or a probe) when due, a row goes into the log, the stop rules are checked, and
the placement puts the next step's samples. Two loops are built on it:

* :func:`render_until` -- progressive rendering until the predicted quality reaches a target or
  the time runs out (early stopping): uniform steps, :class:`~nriqa.render.stop.TargetScore`.
* :func:`render_adaptive` -- after a uniform first pass, each step spends as many samples as a
  uniform step would, where the predicted map expects them to remove the most error: per pixel
  (:class:`~nriqa.render.placement.PixelAllocation`, JIT variants) or per tile through film crops
  (:class:`~nriqa.render.tiles.TileRefinement`, ``tile=N``; the only way in ``scalar_rgb``).

The caller chooses the Mitsuba variant before calling, e.g. with the renderer's own choice::

    from nriqa.render.backend import init_worker, select_backend
    init_worker(select_backend("auto"), threads=2)   # llvm_ad_rgb where it works, else scalar_rgb

or :func:`~nriqa.render.backend.ensure_variant`, which does exactly that when no variant is set.

Timing: ``seconds`` in the logs is render plus scoring time; render time covers placing, rendering
and folding in each step's samples. With ``llvm_ad_rgb`` every distinct kernel is JIT-compiled on
its first use, so the loop first runs each once, untimed and discarded (``warmup=True``), and
scores the warm-up image once to learn the scorer's cost; that time is logged as
``setup_seconds`` in every row. The true score (``true``, when a reference is given) is computed
outside the timed region.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import numpy as np

from nriqa.render.backend import is_jit_variant
from nriqa.render.clock import Clock, Schedule, check_overhead, next_step, timed_score
from nriqa.render.film import Film, HalfFilm, ImageFilm, PixelFilm, check_pixel_filter, load_scene
from nriqa.render.pixel_renderer import PixelRenderer
from nriqa.render.placement import PixelAllocation, Placement, UniformSteps
from nriqa.render.rating import Probes, Rater, needs_twin, reads_pixel_filter, with_twin
from nriqa.render.stop import (
    MaxSpp,
    Progress,
    SppBudget,
    StopRule,
    SureOfTarget,
    TargetScore,
    TimeBudget,
    budgets,
    first_reached,
    spp_to_go,
)
from nriqa.render.tiles import TileFilm, TileRefinement

if TYPE_CHECKING:
    from nriqa.inference.scorer import Scorer

__all__ = ["render_adaptive", "render_loop", "render_until"]

log = logging.getLogger(__name__)


def _warm_up(film: Film, placement: Placement, scorer, schedule: Schedule) -> tuple[float, float]:
    """Run the first pass's and the steps' kernels once, discarded, and score once: ``(seconds, score cost)``."""
    t0 = time.perf_counter()
    image = film.warm_up(schedule.initial_spp)
    placement.warm_up(film, schedule)
    # A two-buffer scorer's cost is learnt with the image as its own twin: only the time counts here.
    cost = (
        timed_score(with_twin(scorer, image if needs_twin(scorer) else None), image)[1] if scorer is not None else 0.0
    )
    return time.perf_counter() - t0, cost


def _step(
    film: Film,
    placement: Placement,
    rater: Rater,
    scored: bool,
    schedule: Schedule,
    stops: list[StopRule],
    to_go: float | None = None,
) -> tuple[np.ndarray, int] | None:
    """Render the next step into ``film``: a probe when one is due and fits the budget of ``stops``
    (returned as ``(image, spp)``, for the scorer to rate), else the placement's step (``None``),
    cut to ``to_go`` samples per pixel (what the rules expect the run to need; at least a least step)."""
    done, pixels, clock = film.spp, film.count.size, rater.clock
    seconds, spp = budgets(stops)
    left = None if spp is None else spp - done
    probe_spp = rater.probe_size(film)
    # A probe whenever the budget has room for one, however small the grown steps are.
    if rater.probe_due(film, scored) and next_step(done, probe_spp, 0.0, clock, seconds, left, pixels) >= probe_spp:
        return film.add_uniform(probe_spp), probe_spp
    if to_go is not None:
        to_go = max(to_go, schedule.spp_per_step)
        left = to_go if left is None else min(left, to_go)
    placement.step(
        film, next_step(done, schedule.spp_per_step, schedule.growth, clock, seconds, left, pixels), rater.model
    )
    return None


def render_loop(
    film: Film,
    placement: Placement,
    stops: list[StopRule],
    scorer: Scorer | None = None,
    *,
    schedule: Schedule | None = None,
    probes: Probes | None = None,
    max_overhead: float | None = 0.05,
    reference: np.ndarray | None = None,
    warmup: bool = True,
) -> tuple[np.ndarray, list[dict]]:
    """The render loop: a uniform first pass, then steps placed by ``placement`` until a rule in ``stops``.

    After each step the scorer rates the image, or the probe the step was (see
    :mod:`nriqa.render.rating`), when scoring is due; a row goes into the log; the first stop
    rule reached ends the run. Otherwise the next step is a probe, if one is due and fits the
    budget, or the placement's step of ``next_step`` mean samples per pixel, sized by
    ``schedule`` and the rules' budgets, and cut to end where the rules expect the run to end
    (``spp_to_go``, e.g. where the prediction should reach a target score).

    Args:
        film: where the samples go (:class:`~nriqa.render.film.ImageFilm`, ``PixelFilm``,
            :class:`~nriqa.render.tiles.TileFilm`), fresh.
        placement: where each step's samples go (:mod:`nriqa.render.placement`).
        stops: the stop rules, in order (:mod:`nriqa.render.stop`); at least one.
        scorer: the :class:`~nriqa.inference.scorer.Scorer` (or anything called like one) whose
            maps place the samples and whose score the rules read; ``None``: nothing is scored.
            A two-buffer scorer (``needs_twin``) rates the image's two halves: the film must keep a
            half buffer (:class:`~nriqa.render.film.HalfFilm`). The film's pixel filter must be the one the
            scorer learnt (``scorer.pixel_filter``, ``"box"`` if it has none; ``ValueError`` otherwise).
        schedule: the first pass's and the steps' samples per pixel (default: ``Schedule()``).
        probes: when the scorer rates a probe instead of the image (default: ``Probes()``).
        max_overhead: score only while scoring time stays within this share of render time
            (the cost of a scoring is the last one's); ``None`` scores after every step. A stop
            on the score can come up to that many steps late: the price of a bounded overhead.
        reference: converged ``(H, W, 3)`` linear image; adds the true mean SSIM to every row.
        warmup: run every kernel once, untimed (LLVM variants), and score once to learn the cost.

    Returns:
        ``(image, log)``: the ``(H, W, 3)`` float32 linear mean, and one dict per step with
        ``step, seconds, render_seconds, score_seconds, setup_seconds, spp, spp_min, spp_max,
        predicted, scored, true, low`` (``spp`` the mean over pixels; ``predicted`` the latest
        prediction, ``scored`` whether this step ran the scorer; ``predicted``/``true`` are
        ``None`` without scorer/reference; ``low`` the low end of the scorer's calibrated interval
        where ``predicted`` is its score of the image or its halves, else ``None``); the last row's ``stop``
        is the rule's name and, for films with per-pixel counts, its ``spp_map`` the ``(H, W)`` counts.
    """
    check_overhead(max_overhead)
    if not stops:
        raise ValueError("render_loop needs at least one stop rule")
    if needs_twin(scorer) and not hasattr(film, "halves"):
        raise ValueError(
            f"the scorer rates an image with its twin, and {type(film).__name__} keeps no half buffer: "
            "use a HalfFilm (per pixel, llvm_ad_rgb)"
        )
    if scorer is not None:
        film_filter = getattr(film, "pixel_filter", "box")  # a film of one's own that says none: box
        check_pixel_filter(film_filter, reads_pixel_filter(scorer), per_pixel=isinstance(film, PixelFilm))
    schedule, probes = schedule or Schedule(), probes or Probes()
    setup, cost = _warm_up(film, placement, scorer, schedule) if warmup else (0.0, 0.0)
    clock = Clock(reference, setup, cost, max_overhead)
    rater = Rater(scorer, probes, clock, placement.needs_map)
    with clock.rendering():
        film.add_uniform(schedule.initial_spp)
    probe, spp_before, aim = None, 0.0, None
    while True:
        scored, fresh = rater.rate(film, probe, spp_before, any(rule.final(film) for rule in stops))
        row = clock.row(film.image, film.count, rater.predicted, scored)
        row["low"] = rater.low
        progress = Progress(film, row, fresh, rater.higher_is_better)
        stop = first_reached(stops, progress)
        if stop is not None:
            row["stop"] = stop.name
            if film.log_counts:
                row["spp_map"] = film.count
            return film.image, clock.log
        spp_before = film.spp
        to_go = spp_to_go(stops, progress)
        if to_go is not None:  # where the rules expect to end; kept until a fresh prediction moves it
            aim = film.spp + to_go
        to_go = None if aim is None or aim <= film.spp else aim - film.spp
        with clock.rendering():
            probe = _step(film, placement, rater, scored, schedule, stops, to_go)


def render_until(
    scene,
    scorer: Scorer | None,
    target_score: float | None,
    time_budget_s: float,
    spp_per_step: int = 4,
    reference: np.ndarray | None = None,
    *,
    max_spp: int | None = None,
    max_overhead: float | None = 0.05,
    growth: float = 0.25,
    map_spp: float | None = 64,
    probe_spp: int = 32,
    seed: int = 0,
    warmup: bool = True,
    sure: bool = False,
) -> tuple[np.ndarray, list[dict]]:
    """Progressive rendering until the predicted quality reaches ``target_score`` (early stopping).

    Each step renders ``spp_per_step`` samples per pixel, or a multiple of it up to ``growth``
    times those done so far, with a new seed and folds them into the running mean; then, when
    scoring is due (``max_overhead``), the scorer rates the mean (as linear HDR), or past
    ``map_spp`` a probe (:mod:`nriqa.render.rating`; probes may follow each other, and the step
    that passes ``map_spp`` is still rated on the image). The loop stops at the first fresh
    prediction that reaches the target (``>=`` for SSIM, ``<=`` for the patch model's MAE), when
    the time budget (render + scoring seconds) is spent, or at ``max_spp`` (whose last step is
    always rated). Near the target, steps are cut to where the latest prediction should reach it
    (:class:`~nriqa.render.stop.TargetScore`), so the run lands on the target rather than a grown
    step past it.

    Args:
        scene: a Mitsuba scene dict (with film and sampler) or a loaded ``mi.Scene``.
        scorer: the :class:`~nriqa.inference.scorer.Scorer`; ``None`` renders uniformly without scoring
            (the baseline: it runs until the time budget or ``max_spp``). A two-buffer scorer
            (``needs_twin``) renders through a :class:`~nriqa.render.film.HalfFilm` (per-pixel
            renderer, JIT variants), whose half buffer splits the image into the two halves it rates.
        target_score: predicted pooled score to stop at (``None``: never stop early).
        time_budget_s: wall-clock budget in seconds for rendering plus scoring.
        spp_per_step: samples per pixel of the first step, and the least of any but the last.
        reference: converged ``(H, W, 3)`` linear image; adds the true mean SSIM to every row.
        max_spp: stop before a step would exceed this many samples per pixel (a large step is cut).
        max_overhead, warmup: as for :func:`render_loop`.
        growth: as for :class:`~nriqa.render.clock.Schedule`; the last step is cut to the time left.
        map_spp, probe_spp: as for :class:`~nriqa.render.rating.Probes`; a two-buffer scorer
            rates the image's halves at every count, never a probe.
        seed: seed of the first step; step ``k`` uses ``seed + k``.
        sure: stop when the low end of the scorer's calibrated interval reaches ``target_score``
            instead of the score (:class:`~nriqa.render.stop.SureOfTarget`): the true mean SSIM is then
            at or above the target about 19 times in 20 on scenes like the calibration's. Needs an SSIM
            :class:`~nriqa.inference.scorer.Scorer` with a calibrated interval (the shipped ``unet_fast``,
            ``fcnn_fast`` and ``dual_fast``). A single-image scorer then rates the image itself at every
            count (``map_spp`` does not apply: the interval is calibrated on the Scorer's score of an
            image); a two-buffer one rates the halves as always, its interval carried to the whole image
            (:func:`~nriqa.render.rating.rate_halves`).

    Returns:
        ``(image, log)`` as for :func:`render_loop`; the last row's ``stop`` is ``"target"`` (``"sure"``
        with ``sure=True``), ``"time"`` or ``"max_spp"``.
    """
    check_overhead(max_overhead)
    if sure:
        _check_sure(scorer, target_score)
        map_spp = None
    schedule = Schedule(spp_per_step, spp_per_step, growth)
    probes = Probes(map_spp, probe_spp, back_to_back=True, grace_step=True)
    stops = _target_stops(target_score, sure)
    stops.append(TimeBudget(time_budget_s))
    if max_spp is not None:
        stops.append(MaxSpp(max_spp, spp_per_step))
    if needs_twin(scorer):
        film = HalfFilm(PixelRenderer(load_scene(scene)), seed)
    else:
        film = ImageFilm(load_scene(scene), seed, quantum=spp_per_step)
    return render_loop(
        film,
        UniformSteps(),
        stops,
        scorer,
        schedule=schedule,
        probes=probes,
        max_overhead=max_overhead,
        reference=reference,
        warmup=warmup,
    )


def _target_stops(target_score: float | None, sure: bool) -> list[StopRule]:
    """The first stop rule: the score reaching ``target_score``, or its low end (``sure``); none without a target."""
    if target_score is None:
        return []
    return [SureOfTarget(target_score) if sure else TargetScore(target_score)]


def _check_sure(scorer, target_score: float | None) -> None:
    """Raise a one-line ``ValueError`` unless ``sure=True`` can work with this scorer and target."""
    if target_score is None:
        raise ValueError("sure=True stops on a target: give target_score")
    if scorer is None or not scorer.higher_is_better:
        raise ValueError(
            "sure=True needs an SSIM scorer (not the patch model's MAE), e.g. Scorer.from_pretrained('unet_fast')"
        )
    if getattr(scorer, "interval", None) is None:
        raise ValueError(
            "sure=True needs a scorer with a calibrated interval (ScoreResult.low); this one has none: "
            "use shipped weights (Scorer.from_pretrained) or give Scorer(interval=...)"
        )


def render_adaptive(
    scene,
    scorer: Scorer | None,
    total_spp: float | None = None,
    time_budget_s: float | None = None,
    *,
    initial_spp: int = 4,
    spp_per_step: int = 4,
    tile: int | None = None,
    uniform_share: float = 0.5,
    fraction: float = 0.25,
    max_overhead: float | None = 0.05,
    growth: float = 0.25,
    map_spp: float | None = 64,
    probe_spp: int = 32,
    reference: np.ndarray | None = None,
    seed: int = 0,
    warmup: bool = True,
    target_score: float | None = None,
    sure: bool = False,
) -> tuple[np.ndarray, list[dict]]:
    """Adaptive sampling: spend samples where the predicted map expects them to remove the most error.

    A uniform pass of ``initial_spp`` samples, then per step ``spp_per_step`` samples per pixel on
    average (grown by ``growth`` as in :func:`render_until`), placed by the latest predicted map:
    per pixel (``tile=None``, JIT variants; :class:`~nriqa.render.placement.PixelAllocation`) or
    per tile (``tile=N``, the fallback in ``scalar_rgb``; :class:`~nriqa.render.tiles.TileRefinement`).
    Every pixel keeps its sample count and the mean of its samples. The map is re-predicted when
    scoring is due (``max_overhead``); in between, the counts added since keep the error model
    current (:class:`~nriqa.render.error_model.ErrorModel`). Per pixel, past ``map_spp`` the maps
    come from probes (:mod:`nriqa.render.rating`; never two in a row, and not the step that passes
    ``map_spp``); per tile, the scorer always rates the image. Stops when the mean samples per
    pixel reach ``total_spp`` or the render + scoring time reaches ``time_budget_s`` (give at least one),
    or, with ``target_score``, at the first fresh prediction that reaches it, as :func:`render_until` does
    (its steps cut to where the prediction should reach it): adaptive sampling that ends itself.

    Args:
        scene: a Mitsuba scene dict with ``sensor.film`` (box filter) and sampler; per pixel also a
            loaded ``mi.Scene``, per tile a dict only (a cropped sensor per tile is added to it).
        scorer: the :class:`~nriqa.inference.scorer.Scorer` whose map places the samples. ``None`` (per
            pixel only): every step spread evenly and nothing scored, i.e. uniform progressive
            rendering through the same renderer and steps, the control for what placement gains.
            A two-buffer scorer (``needs_twin``; per pixel only) renders into a
            :class:`~nriqa.render.film.HalfFilm`, whose half buffer gives the two halves.
        total_spp: budget in mean samples per pixel.
        time_budget_s: budget in seconds (render + scoring).
        initial_spp, spp_per_step, growth: as for :class:`~nriqa.render.clock.Schedule` (per tile,
            steps are neither grown nor cut below a uniform step).
        tile: ``None`` for per-pixel sampling, else the tile side in pixels (edge tiles may be smaller).
        uniform_share: per pixel, the share of each step's samples spread evenly, in [0, 1].
        fraction: per tile, the share of tiles refined per step, in (0, 1].
        max_overhead, reference, warmup: as for :func:`render_loop`; the first map is always predicted.
        map_spp, probe_spp: per pixel, as for :class:`~nriqa.render.rating.Probes` (single-image
            scorers; a two-buffer scorer rates the image's halves at every count).
        seed: base seed; every render call gets a distinct one.
        target_score: predicted pooled score to stop at (``None``: run to the budget). The budget
            still bounds the run: a target the scorer never reads stops there.
        sure: stop when the low end of the scorer's calibrated interval reaches ``target_score``, as
            for :func:`render_until` (the single-image scorer then rates the image at every count:
            ``map_spp`` does not apply). The interval was calibrated on uniformly sampled renders; how
            often adaptive runs stopped this way end at or above the target is measured by
            ``benchmarks/render_compare.py --stop-methods adaptive-sure``, and the interval along
            adaptive loops by ``benchmarks/adaptive_interval.py`` (docs/results/render_compare.md).

    Returns:
        ``(image, log)`` as for :func:`render_loop`; the last row's ``stop`` is ``"target"`` (``"sure"``
        with ``sure=True``), ``"spp"`` or ``"time"``, and ``spp_map`` in it holds the ``(H, W)`` counts.
    """
    if total_spp is None and time_budget_s is None:
        raise ValueError("render_adaptive needs a budget: total_spp, time_budget_s or both")
    check_overhead(max_overhead)
    if sure:
        _check_sure(scorer, target_score)
        map_spp = None
    schedule = Schedule(initial_spp, spp_per_step, growth)
    probes = Probes(map_spp, probe_spp)
    stops = _target_stops(target_score, sure)
    if total_spp is not None:
        stops.append(SppBudget(total_spp))
    if time_budget_s is not None:
        stops.append(TimeBudget(time_budget_s))
    film, placement = _adaptive_parts(scene, scorer, tile, uniform_share, fraction, spp_per_step, seed)
    if isinstance(film, TileFilm):
        probes = Probes(None, probe_spp)  # per tile, the scorer always rates the image
    return render_loop(
        film,
        placement,
        stops,
        scorer,
        schedule=schedule,
        probes=probes,
        max_overhead=max_overhead,
        reference=reference,
        warmup=warmup,
    )


def _adaptive_parts(scene, scorer, tile, uniform_share, fraction, spp_per_step, seed) -> tuple[Film, Placement]:
    """:func:`render_adaptive`'s film and placement: per pixel, or per tile (also where no JIT variant runs)."""
    if tile is None and not is_jit_variant():
        import mitsuba as mi

        log.warning(
            "per-pixel adaptive sampling needs a JIT variant (llvm_ad_rgb), not %s: using 16x16 tiles", mi.variant()
        )
        tile = 16
    if tile is None:
        film = (HalfFilm if needs_twin(scorer) else PixelFilm)(PixelRenderer(load_scene(scene)), seed)
        return film, PixelAllocation(uniform_share if scorer is not None else 0.0, seed)
    if scorer is None:
        raise ValueError("render_adaptive per tile needs a scorer (scorer=None is uniform rendering per pixel)")
    if needs_twin(scorer):
        raise ValueError("a two-buffer scorer (needs_twin) needs per-pixel sampling (tile=None, llvm_ad_rgb)")
    film = TileFilm(scene, tile, seed)
    return film, TileRefinement(film, fraction, spp_per_step)
