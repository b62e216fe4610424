"""The render loop's plug points without Mitsuba: a synthetic film (Gaussian noise per sample), the
driver with built-in and custom placement and stop rules, and the small parts (budgets, settings)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from nriqa.render import (
    PixelAllocation,
    Probes,
    ReferenceScorer,
    Schedule,
    SppBudget,
    StopRule,
    TargetScore,
    TimeBudget,
    render_loop,
    true_ssim,
)
from nriqa.render.placement import UniformSteps
from nriqa.render.rating import at_full_samples, spp_to_reach
from nriqa.render.stop import MaxSpp, Progress, budgets, spp_to_go

SIZE = 16

pytestmark = pytest.mark.usefixtures("one_thread")


class NoiseFilm:
    """Samples of a clean image with Gaussian noise of ``sigma`` per sample: the film protocol, in numpy."""

    log_counts = True
    quantum = 1

    def __init__(self, clean: np.ndarray, sigma: np.ndarray, seed: int = 0):
        self.clean, self.sigma = clean, sigma
        self.rng = np.random.default_rng(seed)
        self.sums = np.zeros(clean.shape)
        self.count = np.zeros(clean.shape[:2])
        self.image = None

    @property
    def spp(self) -> float:
        return float(self.count.mean())

    def _samples(self, counts: np.ndarray) -> np.ndarray:
        noise = self.rng.standard_normal(self.clean.shape) * (np.sqrt(counts) * self.sigma)[..., None]
        return counts[..., None] * self.clean + noise

    def warm_up(self, spp: int, seed: int = 0) -> np.ndarray:
        return (self.clean + self.rng.standard_normal(self.clean.shape) * self.sigma[..., None] / np.sqrt(spp)).astype(
            np.float32
        )

    def add(self, counts: np.ndarray) -> np.ndarray:
        sums = self._samples(np.asarray(counts, dtype=np.float64))
        self.sums += sums
        self.count += counts
        self.image = (self.sums / self.count[..., None]).astype(np.float32)
        return sums

    def add_uniform(self, spp: int) -> np.ndarray:
        return (self.add(np.full(self.count.shape, spp)) / spp).astype(np.float32)


@pytest.fixture
def scene():
    """A smooth image whose right half is four times as noisy per sample as its left half."""
    yy, xx = np.mgrid[0:SIZE, 0:SIZE] / SIZE
    clean = np.stack([0.4 + 0.3 * np.sin(3 * xx + c) * np.cos(2 * yy) for c in range(3)], axis=2).astype(np.float32)
    sigma = np.full((SIZE, SIZE), 0.05)
    sigma[:, SIZE // 2 :] = 0.2
    return clean, sigma


def test_pixel_allocation_samples_the_noisy_half_more_and_beats_uniform(scene):
    clean, sigma = scene
    oracle = ReferenceScorer(clean)
    common = dict(schedule=Schedule(4, 4, 0.0), max_overhead=None, reference=clean, warmup=False)
    image, log = render_loop(NoiseFilm(clean, sigma, 1), PixelAllocation(0.25, 1), [SppBudget(32)], oracle, **common)
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and counts.mean() == pytest.approx(32)
    assert counts[:, SIZE // 2 :].mean() > 1.5 * counts[:, : SIZE // 2].mean()
    assert [r["step"] for r in log] == list(range(len(log))) and all(r["scored"] for r in log)
    assert log[-1]["true"] == pytest.approx(true_ssim(image, clean))
    _, uniform = render_loop(NoiseFilm(clean, sigma, 1), PixelAllocation(0.0, 1), [SppBudget(32)], None, **common)
    assert (uniform[-1]["spp_map"] == 32).all() and uniform[-1]["predicted"] is None
    assert 1 - log[-1]["true"] < 1 - uniform[-1]["true"]  # same samples, less error where they went


@dataclasses.dataclass(frozen=True)
class AfterRows(StopRule):
    """A custom rule: stop at row ``rows``."""

    rows: int
    name = "rows"

    def reached(self, progress: Progress) -> bool:
        return progress.row["step"] + 1 >= self.rows


class LeftHalf:
    """A custom placement: each step's samples in the left half only, evenly."""

    needs_map = False

    def __init__(self):
        self.asked: list[float] = []

    def warm_up(self, film, schedule) -> None:
        pass

    def step(self, film, spp: float, model) -> None:
        self.asked.append(spp)
        counts = np.zeros(film.count.shape, dtype=np.int64)
        counts[:, : SIZE // 2] = round(2 * spp)
        film.add(counts)


def test_custom_placement_and_stop_rule_plug_into_the_driver(scene):
    clean, sigma = scene
    placement = LeftHalf()
    _, log = render_loop(
        NoiseFilm(clean, sigma),
        placement,
        [AfterRows(4), SppBudget(1000)],
        None,
        schedule=Schedule(2, 2, 0.5),
        warmup=False,
    )
    assert len(log) == 4 and log[-1]["stop"] == "rows"
    assert placement.asked == [2, 2, 3]  # spp_per_step, or growth 0.5 of the mean done (2, 4, 6 spp)
    counts = log[-1]["spp_map"]
    assert (counts[:, SIZE // 2 :] == 2).all() and (counts[:, : SIZE // 2] == 2 + 4 + 4 + 6).all()


def test_target_score_stops_on_a_fresh_prediction_and_probes_rate_the_step(scene):
    clean, sigma = scene
    oracle = ReferenceScorer(clean)
    images = []

    def scorer(image, *, hdr=None):
        images.append(image)
        return oracle(image)

    scorer.higher_is_better = True
    stops = [TargetScore(0.995), SppBudget(400)]
    _, log = render_loop(
        NoiseFilm(clean, sigma, 2),
        PixelAllocation(0.5, 2),
        stops,
        scorer,
        reference=clean,
        schedule=Schedule(4, 4, 0.25),
        probes=Probes(map_spp=16, probe_spp=8),
        max_overhead=None,
        warmup=False,
    )
    assert log[-1]["stop"] == "target" and log[-1]["predicted"] >= 0.995
    assert all(r["predicted"] < 0.995 for r in log[:-1])
    scored = [r for r in log if r["scored"]]
    assert len(images) == len(scored)
    # Past map_spp the scorer rates probes: fresh 8-spp steps, noisier than the image they join.
    probes = [(image, r) for image, r in zip(images, scored, strict=True) if r["spp"] > 16]
    assert probes and all(true_ssim(image, clean) < r["true"] for image, r in probes)


def test_budgets_are_the_tightest_the_rules_state():
    rules = [TargetScore(0.9), TimeBudget(5.0), SppBudget(64), MaxSpp(32, 4), TimeBudget(2.0)]
    assert budgets(rules) == (2.0, 32)
    assert budgets([TargetScore(0.9)]) == (None, None)


def test_target_score_reads_the_direction_and_freshness():
    rule = TargetScore(0.1)
    assert rule.reached(Progress(None, {"predicted": 0.05}, True, higher_is_better=False))
    assert not rule.reached(Progress(None, {"predicted": 0.05}, False, higher_is_better=False))  # stale
    assert not rule.reached(Progress(None, {"predicted": 0.05}, True, higher_is_better=True))
    assert not rule.reached(Progress(None, {"predicted": None}, True, higher_is_better=True))


def test_spp_to_reach_inverts_the_samples_law():
    # SSIM: 0.8 at 10 spp reaches 0.9 at 10 * 0.9 * 0.2 / (0.8 * 0.1) = 22.5 spp ...
    assert spp_to_reach(0.8, 10, 0.9) == pytest.approx(22.5)
    # ... which is at_full_samples read the other way: 10 of 22.5 samples rate 0.8, all of them 0.9.
    assert float(at_full_samples(np.float32(0.8), 10 / 22.5)) == pytest.approx(0.9, abs=1e-6)
    assert spp_to_reach(0.95, 40, 0.9) < 40  # already past: fewer samples than it has
    assert spp_to_reach(0.02, 16, 0.01, higher_is_better=False) == pytest.approx(64)  # MAE ~ 1/sqrt(spp)
    for score, target, hib in ((0.5, 1.0, True), (0.5, 0.0, True), (float("nan"), 0.9, True), (0.1, 0.0, False)):
        assert spp_to_reach(score, 8, target, hib) is None
    assert np.isfinite(spp_to_reach(0.0, 8, 0.9)) and np.isfinite(spp_to_reach(1.0, 8, 0.9))  # clipped, not 1/0


def test_target_score_expects_the_samples_to_its_target():
    class Film:
        spp = 10.0

    rule = TargetScore(0.9)
    assert rule.spp_to_go(Progress(Film(), {"predicted": 0.8}, True, True)) == pytest.approx(12.5)
    assert rule.spp_to_go(Progress(Film(), {"predicted": 0.8}, False, True)) is None  # stale: no new estimate
    assert rule.spp_to_go(Progress(Film(), {"predicted": 0.95}, True, True)) == 0.0
    assert rule.spp_to_go(Progress(Film(), {"predicted": None}, True, True)) is None
    # the fewest over the rules that estimate (0.85: 10 * 0.85 * 0.2 / (0.8 * 0.15) - 10 spp)
    progress = Progress(Film(), {"predicted": 0.8}, True, True)
    assert spp_to_go([TimeBudget(5.0), rule, TargetScore(0.85)], progress) == pytest.approx(4.1667, abs=1e-4)
    assert spp_to_go([TimeBudget(5.0)], progress) is None


def test_render_loop_lands_on_the_target_instead_of_stepping_past(scene):
    """Grown steps (a quarter of the samples done) step past a target window; cut to where the
    prediction should reach the target, the run ends just past it, in smaller last steps."""
    clean, sigma = scene
    oracle = ReferenceScorer(clean)
    target = 0.97
    ends = []
    for seed in range(4):
        _, log = render_loop(
            NoiseFilm(clean, sigma, seed),
            UniformSteps(),
            [TargetScore(target), SppBudget(4000)],
            oracle,
            reference=clean,
            schedule=Schedule(4, 1, 0.25),
            max_overhead=None,
            warmup=False,
        )
        assert log[-1]["stop"] == "target" and target <= log[-1]["true"]
        grown = 0.25 * log[-2]["spp"]
        assert log[-1]["spp"] - log[-2]["spp"] < grown  # the last step was cut, not grown
        ends.append(log[-1]["true"])
    assert max(ends) - target < 0.003, ends


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: Schedule(initial_spp=0), "initial_spp"),
        (lambda: Schedule(spp_per_step=0), "spp_per_step"),
        (lambda: Schedule(growth=-1), "growth"),
        (lambda: Probes(map_spp=-1), "map_spp"),
        (lambda: Probes(probe_spp=0), "probe_spp"),
        (lambda: PixelAllocation(uniform_share=2), "uniform_share"),
    ],
)
def test_settings_are_refused_with_their_name(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_render_loop_needs_a_stop_rule(scene):
    clean, sigma = scene
    with pytest.raises(ValueError, match="stop rule"):
        render_loop(NoiseFilm(clean, sigma), PixelAllocation(), [], None)


def test_backend_import_loads_neither_torch_nor_the_scorer():
    code = "import sys, nriqa.render.backend; print('torch' in sys.modules, 'nriqa.inference.scorer' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]
