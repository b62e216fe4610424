"""Render loops on a tiny Cornell box (32x32): scalar_rgb (no JIT compile, fast at this size) for the
loops and tiles; llvm_ad_rgb, where it works, for per-pixel sampling (PixelRenderer)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

mi = pytest.importorskip("mitsuba")

from data_gen.plan import ImageTask, Job  # noqa: E402
from data_gen.render import scene_dict  # noqa: E402
from nriqa.inference.interval import ScoreInterval  # noqa: E402
from nriqa.inference.scorer import Scorer  # noqa: E402
from nriqa.models import create_model  # noqa: E402
from nriqa.render import (  # noqa: E402
    ReferenceScorer,
    allocate_samples,
    render_adaptive,
    render_until,
    true_ssim,
)
from nriqa.render.backend import SCALAR_VARIANT, init_worker  # noqa: E402
from nriqa.render.clock import Clock as _Clock  # noqa: E402
from nriqa.render.clock import next_step as _next_step  # noqa: E402
from nriqa.render.error_model import ErrorModel as _ErrorModel  # noqa: E402
from nriqa.render.film import check_pixel_filter  # noqa: E402
from nriqa.render.tiles import expected_gain as _expected_gain  # noqa: E402

SIZE = 32


@pytest.fixture(scope="module")
def scene():
    previous = mi.variant()
    init_worker(SCALAR_VARIANT, 1)
    job = Job("cornell", 0, 7, "path_independent", (SIZE, SIZE), 6, ())
    yield scene_dict(job, ImageTask("t", "test", 4, 1, "t.exr", "r.exr"))
    if previous is not None:
        mi.set_variant(previous)


@pytest.fixture(scope="module")
def reference(scene):
    return np.array(mi.render(mi.load_dict(scene), spp=128, seed=12345), dtype=np.float32)[..., :3]


@pytest.fixture(scope="module")
def scorer():
    torch.manual_seed(0)
    return Scorer(create_model("fcnn_fast"))


pytestmark = pytest.mark.usefixtures("one_thread")


def test_reference_scorer_is_the_true_ssim_map(reference):
    truth = ReferenceScorer(reference)
    same = truth(reference)
    assert same.map.shape == (SIZE, SIZE) and np.allclose(same.map, 1.0, atol=1e-4) and same.quantity == "ssim"
    noisy = reference + np.random.default_rng(0).normal(0, 0.1, reference.shape).astype(np.float32)
    result = truth(noisy)
    assert result.score == pytest.approx(float(result.map.mean())) and result.score < 0.99
    assert result.score == pytest.approx(true_ssim(noisy, reference))
    assert truth.higher_is_better


def test_render_until_runs_to_max_spp(scene, scorer, reference):
    image, log = render_until(
        scene,
        scorer,
        target_score=None,
        time_budget_s=60,
        spp_per_step=2,
        reference=reference,
        max_spp=8,
        max_overhead=None,
    )
    assert image.shape == (SIZE, SIZE, 3) and np.isfinite(image).all()
    assert [r["spp"] for r in log] == [2, 4, 6, 8] and log[-1]["stop"] == "max_spp"
    assert all(np.isfinite(r["predicted"]) and r["scored"] for r in log)
    assert log[-1]["true"] == pytest.approx(true_ssim(image, reference))
    assert log[-1]["true"] > log[0]["true"]  # more samples, closer to the reference
    assert all(b["seconds"] >= a["seconds"] for a, b in zip(log, log[1:]))
    assert log[-1]["seconds"] == pytest.approx(log[-1]["render_seconds"] + log[-1]["score_seconds"])


def test_render_until_steps_grow_and_end_on_max_spp(scene):
    _, log = render_until(scene, None, None, 60, spp_per_step=2, max_spp=20, growth=0.5)
    # Multiples of spp_per_step (3 -> 2 at 6 spp), the last one cut to end on max_spp.
    assert [r["spp"] for r in log] == [2, 4, 6, 8, 12, 18, 20] and log[-1]["stop"] == "max_spp"
    _, log = render_until(scene, None, None, 60, spp_per_step=2, max_spp=7, growth=0.0)
    assert [r["spp"] for r in log] == [2, 4, 6]
    with pytest.raises(ValueError, match="growth"):
        render_until(scene, None, None, 1, growth=-1)


def test_next_step_grows_and_is_cut_to_the_budget():
    clock = _Clock(None, 0.0, 0.0, None)
    assert _next_step(0, 4, 0.25, clock, 10.0, None) == 4  # nothing measured yet: the first step
    assert _next_step(40, 4, 0.25, clock, None, None) == 10
    assert _next_step(40, 4, 0.25, clock, None, 3) == 3  # what the spp budget has left
    clock.render, clock.score = 1.0, 0.1  # 40 spp took 1 s to render, 0.1 s to score
    assert _next_step(40, 4, 0.25, clock, 1.2, None) == pytest.approx(4.0)  # 0.1 s left: 4 spp at 40 spp/s
    assert _next_step(40, 4, 0.25, clock, 10.0, None) == 10  # plenty of time: the growth step
    assert _next_step(40, 4, 0.25, clock, 1.1, None) == 1.0  # no time left: one sample, then the loop stops


def test_render_until_stops_at_target(scene, reference):
    oracle = ReferenceScorer(reference)
    _, log = render_until(
        scene, oracle, target_score=0.5, time_budget_s=60, spp_per_step=2, max_spp=256, max_overhead=None
    )
    assert log[-1]["stop"] == "target" and log[-1]["predicted"] >= 0.5
    assert all(r["predicted"] < 0.5 for r in log[:-1])


class SlowScorer(ReferenceScorer):
    """The oracle, made to cost ``delay`` seconds per call."""

    def __init__(self, reference, delay):
        super().__init__(reference)
        self.delay = delay
        self.calls = 0

    def __call__(self, image, *, hdr=None):
        import time

        self.calls += 1
        time.sleep(self.delay)
        return super().__call__(image, hdr=hdr)


class RecordingScorer(ReferenceScorer):
    """The oracle, keeping every image it is asked to rate."""

    def __init__(self, reference):
        super().__init__(reference)
        self.images = []

    def __call__(self, image, *, hdr=None):
        self.images.append(np.array(image))
        return super().__call__(image, hdr=hdr)


class CalibratedOracle(ReferenceScorer):
    """The oracle with an interval of its own: ``low`` is the true score minus ``reach``."""

    interval = "stands in for a calibration"

    def __init__(self, reference, reach):
        super().__init__(reference)
        self.reach = reach

    def __call__(self, image, *, hdr=None):
        result = super().__call__(image, hdr=hdr)
        return dataclasses.replace(result, low=result.score - self.reach, high=min(result.score + self.reach, 1.0))


def test_render_until_sure_stops_on_the_low_end(scene, reference):
    oracle = CalibratedOracle(reference, 0.1)
    kwargs = dict(time_budget_s=60, spp_per_step=2, reference=reference, max_spp=512, max_overhead=None, map_spp=4)
    _, plain = render_until(scene, oracle, 0.8, **kwargs)
    _, sure = render_until(scene, oracle, 0.8, sure=True, **kwargs)
    assert plain[-1]["stop"] == "target" and sure[-1]["stop"] == "sure"
    # every row rates the image itself (map_spp does not apply), so every row has its low end
    assert all(r["scored"] and r["low"] == pytest.approx(r["predicted"] - 0.1) for r in sure)
    assert sure[-1]["low"] >= 0.8 and all(r["low"] < 0.8 for r in sure[:-1])
    assert sure[-1]["true"] >= 0.9 > plain[-1]["true"] and sure[-1]["spp"] > plain[-1]["spp"]
    # past map_spp the plain loop's prediction is the error model's: no low end there
    _, further = render_until(scene, oracle, 0.95, **kwargs)
    assert further[0]["low"] is not None and further[-1]["spp"] > 8 and further[-1]["low"] is None


def _flat_interval(offset: float) -> ScoreInterval:
    """An interval whose low end is the score plus ``offset`` in every band."""
    return ScoreInterval(0.9, (0.0, 1.0), (offset,), (0.05,), (100,))


def test_an_interval_calibrated_on_a_kind_of_loop_gives_that_loops_low_end(scene, reference):
    # The oracle's own low end is 0.1 below its score; a loop interval for uniform loops puts it 0.2
    # below in render_until, and leaves render_adaptive (placed by the map: "adaptive") on the result's.
    oracle = CalibratedOracle(reference, 0.1)
    oracle.loop_intervals = {"uniform": _flat_interval(-0.2)}
    kwargs = dict(time_budget_s=60, spp_per_step=2, reference=reference, max_spp=512, max_overhead=None)
    _, uniform = render_until(scene, oracle, 0.75, sure=True, **kwargs)
    assert uniform[-1]["stop"] == "sure" and uniform[-1]["low"] >= 0.75
    assert all(r["low"] == pytest.approx(r["predicted"] - 0.2) for r in uniform)
    adaptive_kwargs = dict(total_spp=256, initial_spp=2, spp_per_step=1, tile=16, fraction=0.25, reference=reference)
    _, adaptive = render_adaptive(scene, oracle, target_score=0.75, sure=True, max_overhead=None, **adaptive_kwargs)
    assert all(r["low"] == pytest.approx(r["predicted"] - 0.1) for r in adaptive)
    oracle.loop_intervals = {"adaptive": _flat_interval(-0.15)}
    _, adaptive = render_adaptive(scene, oracle, target_score=0.75, sure=True, max_overhead=None, **adaptive_kwargs)
    assert all(r["low"] == pytest.approx(r["predicted"] - 0.15) for r in adaptive)


def test_render_until_sure_needs_a_calibrated_single_image_ssim_scorer(scene, scorer, reference):
    with pytest.raises(ValueError, match="target_score"):
        render_until(scene, CalibratedOracle(reference, 0.1), None, 1, sure=True, warmup=False)
    with pytest.raises(ValueError, match="calibrated interval"):
        render_until(scene, scorer, 0.9, 1, sure=True, warmup=False)  # untrained, no card: no interval
    with pytest.raises(ValueError, match="an SSIM scorer"):
        render_until(scene, None, 0.9, 1, sure=True, warmup=False)
    torch.manual_seed(0)
    with pytest.raises(ValueError, match="an SSIM scorer"):
        render_until(scene, Scorer(create_model("patch_cnn")), 0.02, 1, sure=True, warmup=False)


def test_render_until_probes_beyond_the_scorers_range(scene, reference):
    # Past map_spp a due scoring rates a fresh 4-spp step alone, not the image; the prediction is
    # the error model's at the image's spp, every step, and it follows the true score.
    scorer = RecordingScorer(reference)
    image, log = render_until(
        scene,
        scorer,
        target_score=None,
        time_budget_s=60,
        spp_per_step=2,
        reference=reference,
        max_spp=40,
        max_overhead=None,
        map_spp=8,
        probe_spp=4,
        seed=3,
        warmup=False,
    )
    assert log[-1]["stop"] == "max_spp" and np.isfinite(image).all()
    assert [r["spp"] for r in log] == [2, 4, 6, 8, 10, 14, 18, 22, 26, 30, 34, 38, 40]
    assert all(r["scored"] for r in log[:-1]) and not log[-1]["scored"]  # the last step is cut to 2 spp: no probe
    assert len(scorer.images) == len(log) - 1
    for row, probe in zip(log[5:-1], scorer.images[5:]):
        assert true_ssim(probe, reference) < row["true"] - 0.05  # the probe is noisier than the image
        assert row["predicted"] != pytest.approx(true_ssim(probe, reference))
    assert log[-1]["predicted"] == pytest.approx(log[-1]["true"], abs=0.1)
    assert log[-1]["predicted"] > log[-2]["predicted"]  # the model's prediction moves with the samples
    # Stopping on the model's prediction: the same run stops at the first row that reaches it.
    target = log[8]["predicted"]
    first = next(i for i, r in enumerate(log) if r["predicted"] >= target)
    _, stopped = render_until(
        scene,
        RecordingScorer(reference),
        target_score=target,
        time_budget_s=60,
        spp_per_step=2,
        reference=reference,
        max_spp=40,
        max_overhead=None,
        map_spp=8,
        probe_spp=4,
        seed=3,
        warmup=False,
    )
    assert stopped[-1]["stop"] == "target" and len(stopped) == first + 1 and first >= 5


def test_render_until_bounds_the_scorer_overhead(scene, reference):
    # A scorer that costs about as much as several render steps may only run now and then.
    slow = SlowScorer(reference, delay=0.02)
    _, log = render_until(
        scene, slow, target_score=None, time_budget_s=60, spp_per_step=2, max_spp=64, max_overhead=0.1
    )
    last = log[-1]
    assert last["score_seconds"] <= 0.1 * last["render_seconds"] + 0.03  # the last step always scores
    assert 1 <= slow.calls - 1 < len(log)  # minus the warm-up scoring
    assert sum(r["scored"] for r in log) == slow.calls - 1 and last["scored"]
    unscored = [r for r in log if not r["scored"]]
    assert unscored and all(r["predicted"] is None or np.isfinite(r["predicted"]) for r in unscored)
    with pytest.raises(ValueError, match="max_overhead"):
        render_until(scene, slow, None, 1, max_overhead=0)


def test_render_until_time_budget_and_uniform_baseline(scene):
    _, log = render_until(scene, None, target_score=None, time_budget_s=0.0, spp_per_step=2)
    assert len(log) == 1 and log[0]["stop"] == "time" and log[0]["predicted"] is None


def test_render_adaptive_refines_some_tiles_only(scene, reference):
    oracle = ReferenceScorer(reference)
    image, log = render_adaptive(
        scene,
        oracle,
        total_spp=7,
        initial_spp=4,
        spp_per_step=1,
        tile=16,
        fraction=0.25,
        reference=reference,
        max_overhead=None,
    )
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and counts.mean() >= 7 and np.isfinite(image).all()
    assert log[-1]["spp"] == pytest.approx(counts.mean())
    # One 16x16 tile of four per step; counts are constant within tiles.
    tiles = counts.reshape(2, 16, 2, 16).transpose(0, 2, 1, 3).reshape(4, -1)
    assert (tiles == tiles[:, :1]).all()
    assert sorted(tiles[:, 0]) != [tiles[0, 0]] * 4  # not uniform
    assert [r["spp"] for r in log] == [4, 5, 6, 7]


def test_render_adaptive_with_all_tiles_is_uniform(scene, scorer, reference):
    image, log = render_adaptive(
        scene, scorer, total_spp=8, initial_spp=4, spp_per_step=4, tile=16, fraction=1.0, reference=reference
    )
    assert (log[-1]["spp_map"] == 8).all()
    assert log[-1]["true"] > log[0]["true"]


def test_render_adaptive_stops_at_a_target_or_when_sure(scene, reference):
    # Per tile (scalar_rgb): the plain target ends at the first score at the target, the sure rule at the
    # first low end there, later; the budget still ends a run whose target is never read.
    oracle = CalibratedOracle(reference, 0.1)
    kwargs = dict(total_spp=256, initial_spp=2, spp_per_step=1, tile=16, fraction=0.25, reference=reference)
    _, plain = render_adaptive(scene, oracle, target_score=0.8, max_overhead=None, **kwargs)
    _, sure = render_adaptive(scene, oracle, target_score=0.8, sure=True, max_overhead=None, **kwargs)
    assert plain[-1]["stop"] == "target" and plain[-1]["predicted"] >= 0.8
    assert all(r["predicted"] < 0.8 for r in plain[:-1])
    assert sure[-1]["stop"] == "sure" and sure[-1]["low"] >= 0.8 and all(r["low"] < 0.8 for r in sure[:-1])
    assert all(r["low"] == pytest.approx(r["predicted"] - 0.1) for r in sure)
    assert sure[-1]["spp"] > plain[-1]["spp"] and sure[-1]["true"] >= 0.9 > plain[-1]["true"]
    assert len(np.unique(sure[-1]["spp_map"])) > 1  # the samples were placed, not spread
    _, budget = render_adaptive(scene, oracle, target_score=0.9999, max_overhead=None, **{**kwargs, "total_spp": 12})
    assert budget[-1]["stop"] == "spp" and budget[-1]["spp"] >= 12


def test_render_adaptive_sure_needs_a_target_and_a_calibrated_scorer(scene, scorer, reference):
    with pytest.raises(ValueError, match="target_score"):
        render_adaptive(scene, CalibratedOracle(reference, 0.1), total_spp=8, sure=True, warmup=False)
    with pytest.raises(ValueError, match="calibrated interval"):
        render_adaptive(scene, scorer, total_spp=8, target_score=0.9, sure=True, warmup=False)
    with pytest.raises(ValueError, match="an SSIM scorer"):
        render_adaptive(scene, None, total_spp=8, target_score=0.9, sure=True, warmup=False)


def test_render_adaptive_needs_a_budget_and_a_dict(scene, scorer):
    with pytest.raises(ValueError, match="budget"):
        render_adaptive(scene, scorer)
    with pytest.raises(TypeError, match="dict"):
        render_adaptive(mi.load_dict(scene), scorer, total_spp=4, tile=16)


def _through(scene, rfilter):
    film = {**scene["sensor"]["film"], "rfilter": {"type": rfilter}}
    return {**scene, "sensor": {**scene["sensor"], "film": film}}


@pytest.mark.parametrize("rfilter", ["gaussian", "tent"])
def test_loops_that_render_whole_images_refuse_a_film_that_is_not_box_filtered(scene, scorer, rfilter):
    """Mitsuba's default filter (a Gaussian, mi.cornell_box()'s too) spreads samples: read as converged."""
    blurred = _through(scene, rfilter)
    match = (
        r"film filters with a (Gaussian of 0.5 pixel \(Mitsuba's default\)|TentFilter), which spreads each sample "
        r"over neighbouring pixels, and the "
        r"scorer reads box-filtered renders: set scene\['sensor'\]\['film'\]\['rfilter'\] = \{'type': 'box'\}"
    )
    with pytest.raises(ValueError, match=match):
        render_until(blurred, scorer, 0.9, time_budget_s=1, max_spp=8, warmup=False)
    with pytest.raises(ValueError, match=match):
        render_until(mi.load_dict(blurred), scorer, 0.9, time_budget_s=1, max_spp=8, warmup=False)
    with pytest.raises(ValueError, match=match):
        render_adaptive(blurred, scorer, total_spp=8, warmup=False)
    render_until(scene, scorer, 0.9, time_budget_s=1, max_spp=8, warmup=False)  # the box-filtered scene runs
    _, log = render_until(blurred, None, None, time_budget_s=1, max_spp=8, warmup=False)  # nothing scored: any filter
    assert log[-1]["spp"] == 8


def test_a_scorer_that_learnt_the_gaussian_needs_a_gaussian_film(scene):
    torch.manual_seed(0)
    gaussian = Scorer(create_model("fcnn_fast"), pixel_filter="gaussian")
    assert gaussian.pixel_filter == "gaussian" and Scorer(create_model("fcnn_fast")).pixel_filter == "box"
    _, log = render_until(_through(scene, "gaussian"), gaussian, 0.9, time_budget_s=1, max_spp=8, warmup=False)
    assert log[-1]["spp"] <= 8
    refused = r"film filters with a box, and the scorer reads gaussian-filtered renders: .*\{'type': 'gaussian'\}"
    with pytest.raises(ValueError, match=refused):
        render_until(scene, gaussian, 0.9, time_budget_s=1, max_spp=8, warmup=False)
    wider = {**scene["sensor"]["film"], "rfilter": {"type": "gaussian", "stddev": 1.0}}
    with pytest.raises(ValueError, match=r"film filters with a GaussianFilter, which spreads"):
        render_until(
            {**scene, "sensor": {**scene["sensor"], "film": wider}}, gaussian, 0.9, time_budget_s=1, warmup=False
        )
    with pytest.raises(ValueError, match="pixel_filter must be one of"):
        Scorer(create_model("fcnn_fast"), pixel_filter="tent")


def test_check_pixel_filter_names_what_to_do():
    check_pixel_filter("box", "box")
    check_pixel_filter("gaussian", "gaussian")
    with pytest.raises(ValueError, match=r"per-pixel sampling traces box-filtered pixels.*unet_fast"):
        check_pixel_filter("box", "gaussian", per_pixel=True)
    with pytest.raises(ValueError, match=r"a TentFilter, which spreads .* <rfilter type=\"box\"/>"):
        check_pixel_filter("TentFilter[radius=1.000000]", "box")


@pytest.mark.parametrize(
    "bad, match",
    [
        ({"probe_spp": 0}, "probe_spp"),
        ({"map_spp": -1}, "map_spp"),
        ({"growth": -0.5}, "growth"),
        ({"max_overhead": 0}, "max_overhead"),
    ],
)
def test_loops_refuse_bad_settings(scene, scorer, bad, match):
    # render_adaptive checks every setting whatever its mode (tiles, as here in scalar_rgb, use no probes).
    with pytest.raises(ValueError, match=match):
        render_until(scene, scorer, 0.9, time_budget_s=1, warmup=False, **bad)
    with pytest.raises(ValueError, match=match):
        render_adaptive(scene, scorer, total_spp=8, warmup=False, **bad)


def test_error_model_predicts_the_saturating_ssim_and_the_mae():
    # SSIM: a map of 0.5 at 10 spp gives odds b = 10, so at 30 spp 1 - 10/40 = 0.75; maps are
    # averaged weighted by their samples (a second map at 30 spp saying 0.75 agrees).
    model = _ErrorModel(higher_is_better=True)
    model.add(np.full((4, 4), 0.5), 10)
    assert model.predict(30) == pytest.approx(0.75) and model.predict(np.full((4, 4), 10.0)) == pytest.approx(0.5)
    model.add(np.full((4, 4), 0.75), 30)
    assert model.predict(30) == pytest.approx(0.75)
    # Extremes stay finite: a perfect pixel, a hopeless one (clipped to 0.999), NaN (the worst seen).
    model = _ErrorModel(higher_is_better=True)
    model.add(np.array([[1.0, 0.0], [np.nan, 0.9]]), np.array([[4.0, 4.0], [4.0, 4.0]]))
    assert np.isfinite(model.odds).all() and model.odds[0, 0] == 0.0
    assert 0.0 <= model.predict(1e6) <= 1.0 and model.predict(1e6) > model.predict(4.0)
    # MAE: a / sqrt(n) with a = e sqrt(n).
    model = _ErrorModel(higher_is_better=False)
    model.add(np.full((2, 2), 0.2), 16)
    assert model.predict(64) == pytest.approx(0.1) and model.odds is None


def test_expected_gain_prefers_worse_and_less_sampled_tiles():
    tiles = [(0, 0, 2, 2), (2, 0, 2, 2), (4, 0, 2, 2)]
    qmap = np.array([[0.9, 0.9, 0.5, 0.5, 0.5, 0.5]] * 2)
    count = np.array([[4, 4, 4, 4, 64, 64]] * 2, dtype=float)
    gain = _expected_gain(qmap, count, tiles, 4, higher_is_better=True)
    assert gain[1] > gain[0] and gain[1] > gain[2]  # worse than tile 0, fewer samples than tile 2
    mae_gain = _expected_gain(1 - qmap, count, tiles, 4, higher_is_better=False)
    np.testing.assert_allclose(mae_gain, gain)


def test_allocate_samples_spends_the_budget_where_the_noise_is():
    rng = np.random.default_rng(0)
    noise = np.ones((8, 8))
    noise[:, 4:] = 16.0  # right half: 16x the error at one sample
    count = np.full((8, 8), 4.0)
    extra = allocate_samples(noise, count, budget=256, alpha=1.0, uniform_share=0.25, rng=rng)
    assert extra.dtype == np.int64 and (extra >= 0).all()
    assert int(extra.sum()) == 256  # systematic rounding: the budget exactly
    assert extra[:, 4:].sum() > 2 * extra[:, :4].sum()
    assert (extra[:, :4] >= 0).all() and extra[:, :4].sum() > 0  # the uniform share reaches every half
    # Long run: the counts approach the optimum n ~ a ** (1 / (1 + alpha)): ratio sqrt(16) = 4.
    for _ in range(200):
        count += allocate_samples(noise, count, 256, 1.0, 0.0, rng)
    assert count[:, 4:].mean() / count[:, :4].mean() == pytest.approx(4.0, rel=0.1)


@pytest.mark.parametrize("noise", [np.zeros((4, 4)), np.full((4, 4), np.nan), np.full((4, 4), np.inf)])
def test_allocate_samples_degenerate_maps_fall_back_to_uniform(noise):
    extra = allocate_samples(
        noise, np.full((4, 4), 2.0), budget=64, alpha=1.0, uniform_share=0.25, rng=np.random.default_rng(1)
    )
    assert (extra == 4).all()


def test_allocate_samples_is_deterministic():
    noise = np.random.default_rng(3).random((16, 16))
    a, b = (allocate_samples(noise, np.full((16, 16), 4.0), 700, 0.5, 0.3, np.random.default_rng(9)) for _ in range(2))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="uniform_share"):
        allocate_samples(noise, np.ones((16, 16)), 10, 1.0, 1.5, np.random.default_rng(0))
