"""Per-pixel sampling in llvm_ad_rgb (PixelRenderer, per-pixel render_adaptive) on a tiny Cornell box (32x32).

Split from test_render_loop.py (the scalar_rgb loops and tiles); skipped where llvm_ad_rgb does not run.
"""

from __future__ import annotations

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")

from test_render_loop import SIZE, CalibratedOracle, RecordingScorer  # noqa: E402

from data_gen.plan import ImageTask, Job  # noqa: E402
from data_gen.render import scene_dict  # noqa: E402
from nriqa.render import PixelRenderer, ReferenceScorer, render_adaptive, true_ssim  # noqa: E402
from nriqa.render.backend import SCALAR_VARIANT, init_worker  # noqa: E402
from nriqa.render.pixel_renderer import _aligned  # noqa: E402


@pytest.fixture(scope="module")
def llvm_scene():
    """The test scene in llvm_ad_rgb (skipped where libLLVM 19 is missing: CI installs it)."""
    from nriqa.render.backend import LLVM_VARIANT, probe_llvm

    ok, reason = probe_llvm()
    if not ok:
        pytest.skip(f"llvm_ad_rgb unusable here: {reason}")
    previous = mi.variant()
    init_worker(LLVM_VARIANT, 1)
    job = Job("cornell", 0, 7, "path_independent", (SIZE, SIZE), 6, ())
    scene = scene_dict(job, ImageTask("t", "test", 4, 1, "t.exr", "r.exr"))
    reference = np.array(mi.render(mi.load_dict(scene), spp=256, seed=12345), dtype=np.float32)[..., :3]
    yield scene, reference
    mi.set_variant(previous or SCALAR_VARIANT)


def test_pixel_renderer_matches_mi_render_and_is_deterministic(llvm_scene):
    scene, reference = llvm_scene
    renderer = PixelRenderer(mi.load_dict(scene))
    counts = np.full((SIZE, SIZE), 64)
    ours = renderer(counts, seed=1) / 64
    theirs = np.array(mi.render(mi.load_dict(scene), spp=64, seed=2), dtype=np.float64)[..., :3]
    # Same estimator, different samples: image means agree within noise, and both are close to the reference.
    assert ours.mean() == pytest.approx(theirs.mean(), rel=0.03)
    assert ours.mean() == pytest.approx(reference.mean(), rel=0.03)
    assert true_ssim(ours.astype(np.float32), reference) == pytest.approx(
        true_ssim(theirs.astype(np.float32), reference), abs=0.03
    )
    np.testing.assert_array_equal(renderer(counts, seed=5), renderer(counts, seed=5))
    assert not np.array_equal(renderer(counts, seed=5), renderer(counts, seed=6))
    # Counts per pixel are honoured: zero samples give zero, a pixel's sum scales with its count.
    mixed = np.zeros((SIZE, SIZE), dtype=int)
    mixed[:, SIZE // 2 :] = 16
    sums = renderer(mixed, seed=3)
    assert (sums[:, : SIZE // 2] == 0).all() and sums[:, SIZE // 2 :].sum() > 0
    with pytest.raises(ValueError, match="counts"):
        renderer(np.ones((2, 2), dtype=int), seed=0)
    with pytest.raises(ValueError, match="sampling integrator"):
        PixelRenderer(mi.load_dict({**scene, "integrator": {"type": "ptracer", "max_depth": 6}}))


def test_a_sensor_that_cannot_be_frozen_is_traced_every_call(llvm_scene, caplog):
    # The thin-lens camera (the dof family) fails Dr.Jit's recording: the renderer warns once and traces instead,
    # with the sums an unfrozen renderer gives; loops on such a scene work per pixel.
    from data_gen.render import loop_scene
    from nriqa.render.film import load_scene

    scene = load_scene(loop_scene("dof", (SIZE, SIZE)))
    counts = np.full((SIZE, SIZE), 2)
    with caplog.at_level("WARNING", logger="nriqa.render.pixel_renderer"):
        renderer = PixelRenderer(scene)
        first = renderer(counts, seed=3)
        again = renderer(counts, seed=3)
    assert not renderer.frozen and len([r for r in caplog.records if "cannot record" in r.message]) == 1
    np.testing.assert_array_equal(first, PixelRenderer(scene, freeze=False)(counts, seed=3))
    np.testing.assert_array_equal(first, again)
    assert np.isfinite(first).all() and first.sum() > 0
    _, log = render_adaptive(loop_scene("dof", (SIZE, SIZE)), None, total_spp=8, warmup=False, seed=1)
    assert log[-1]["stop"] == "spp"


def test_frozen_pixel_renderer_gives_the_traced_sums(llvm_scene):
    # The frozen kernel replays for new seeds and wavefront sizes, bit for bit what tracing every call gives.
    scene, _ = llvm_scene
    loaded = mi.load_dict(scene)
    frozen, traced = PixelRenderer(loaded), PixelRenderer(loaded, freeze=False)
    rng = np.random.default_rng(0)
    for k in range(6):
        counts = rng.integers(0, 3 + 2 * k, size=(SIZE, SIZE))
        np.testing.assert_array_equal(frozen(counts, seed=k), traced(counts, seed=k))
    assert 1 <= frozen._samples.n_recordings <= 3  # replayed, not traced again on every call


def test_frozen_pixel_renderer_records_once_whatever_the_sample_memory(llvm_scene):
    # Dr.Jit maps the index array's memory; a frozen function records anew when its alignment changes,
    # which numpy leaves to chance (2 recordings in 30 calls before the index was aligned).
    scene, _ = llvm_scene
    renderer = PixelRenderer(mi.load_dict(scene))
    rng = np.random.default_rng(0)
    for k in range(30):
        renderer(rng.integers(1, 4 + k, size=(SIZE, SIZE)), seed=k)
    assert renderer._samples.n_recordings == 1


@pytest.mark.parametrize("dtype, size", [(np.uint32, 1), (np.uint32, 12345), (np.float64, 77)])
def test_aligned_copies_onto_the_boundary(dtype, size):
    array = np.arange(size, dtype=dtype)
    out = _aligned(array)
    assert out.dtype == array.dtype and out.ctypes.data % 64 == 0
    np.testing.assert_array_equal(out, array)


def test_render_adaptive_per_pixel(llvm_scene):
    scene, reference = llvm_scene
    oracle = ReferenceScorer(reference)
    image, log = render_adaptive(
        scene, oracle, total_spp=24, initial_spp=4, spp_per_step=4, reference=reference, seed=3
    )
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and counts.mean() >= 24 and np.isfinite(image).all()
    assert counts.min() >= 4 + 3 and counts.max() > 2 * counts.min()  # uniform share everywhere, more where it is worse
    assert log[-1]["true"] > log[0]["true"]
    assert log[-1]["spp"] == pytest.approx(counts.mean())
    # Determinism: same seed, same image and counts (the clock does not steer anything with max_overhead=None).
    again, log2 = render_adaptive(
        scene, oracle, total_spp=24, initial_spp=4, spp_per_step=4, reference=reference, seed=3, max_overhead=None
    )
    first, log1 = render_adaptive(
        scene, oracle, total_spp=24, initial_spp=4, spp_per_step=4, reference=reference, seed=3, max_overhead=None
    )
    np.testing.assert_array_equal(again, first)
    np.testing.assert_array_equal(log1[-1]["spp_map"], log2[-1]["spp_map"])


def test_render_adaptive_per_pixel_stops_when_sure(llvm_scene):
    # Per pixel, sure=True rates the image itself at every count (map_spp does not apply, as for
    # render_until): every row has its low end, and the run ends at the first one at the target.
    scene, reference = llvm_scene
    oracle = CalibratedOracle(reference, 0.05)
    image, log = render_adaptive(
        scene,
        oracle,
        total_spp=400,
        initial_spp=4,
        spp_per_step=4,
        map_spp=8,
        max_overhead=None,
        reference=reference,
        seed=5,
        target_score=0.9,
        sure=True,
        warmup=False,
    )
    assert log[-1]["stop"] == "sure" and np.isfinite(image).all()
    assert all(r["scored"] and r["low"] is not None for r in log)
    assert log[-1]["low"] >= 0.9 and all(r["low"] < 0.9 for r in log[:-1])
    assert log[-1]["spp"] > 8 and log[-1]["true"] >= 0.9 + 0.05 - 1e-6
    counts = log[-1]["spp_map"]
    assert counts.max() > 2 * counts.min()


def test_render_adaptive_without_a_scorer_renders_uniformly(llvm_scene):
    scene, reference = llvm_scene
    image, log = render_adaptive(scene, None, total_spp=40, initial_spp=4, spp_per_step=4, reference=reference, seed=3)
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and counts.mean() >= 40 and np.isfinite(image).all()
    assert counts.max() - counts.min() <= 1  # grown steps are fractional: systematic rounding, at most one apart
    assert all(r["predicted"] is None and not r["scored"] and r["score_seconds"] == 0 for r in log)
    assert log[-1]["true"] > log[0]["true"]
    with pytest.raises(ValueError, match="needs a scorer"):
        render_adaptive(scene, None, total_spp=8, tile=8)


def test_render_adaptive_probes_beyond_the_scorers_range(llvm_scene):
    scene, reference = llvm_scene
    scorer = RecordingScorer(reference)
    image, log = render_adaptive(
        scene,
        scorer,
        total_spp=40,
        initial_spp=4,
        spp_per_step=4,
        map_spp=8,
        probe_spp=4,
        max_overhead=None,
        reference=reference,
        seed=2,
        warmup=False,
    )
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and np.isfinite(image).all()
    beyond = [r for r in log if r["spp"] > 8]
    assert beyond and all(0.0 <= r["predicted"] <= 1.0 for r in beyond)
    # Beyond map_spp every other step is a uniform 4-spp probe (scoring is due every step here),
    # and the scorer rates the probe, not the image: it is noisier than the image.
    probes = sum(r["scored"] for r in beyond)
    assert probes >= 2
    assert not any(a["scored"] and b["scored"] for a, b in zip(beyond, beyond[1:]))
    assert len(scorer.images) == sum(r["scored"] for r in log)
    probe_true = true_ssim(scorer.images[-1], reference)
    assert probe_true < log[-1]["true"] - 0.05
    assert abs(true_ssim(scorer.images[1], reference) - log[1]["true"]) < 1e-6  # at 8 spp: the image itself
    # Probes are uniform and count like any samples; the model's prediction tracks the true score.
    assert counts.min() >= 4 + 4 * probes and log[-1]["spp"] == pytest.approx(counts.mean())
    assert log[-1]["predicted"] == pytest.approx(log[-1]["true"], abs=0.1)


def test_render_adaptive_takes_a_probe_larger_than_its_grown_steps(llvm_scene):
    # Steps of 2-3 spp past map_spp=8: a due map still comes from a full 8-spp probe, as in render_until.
    scene, reference = llvm_scene
    scorer = RecordingScorer(reference)
    _, log = render_adaptive(
        scene,
        scorer,
        total_spp=24,
        initial_spp=4,
        spp_per_step=2,
        map_spp=8,
        probe_spp=8,
        max_overhead=None,
        reference=reference,
        seed=4,
        warmup=False,
    )
    first = next(i for i, r in enumerate(log) if r["spp"] > 8)
    assert not log[first]["scored"]  # the step that passes map_spp is not rated itself
    probe = log[first + 1]
    assert probe["scored"] and probe["spp"] - log[first]["spp"] == pytest.approx(8)
    assert true_ssim(scorer.images[-1], reference) < probe["true"] - 0.05  # the scorer rated the probe, not the image


def test_per_pixel_sampling_refuses_a_scorer_of_gaussian_filtered_renders(llvm_scene):
    """Per-pixel films trace box-filtered pixels whatever the film says: a Gaussian scorer would read them low."""
    scene, reference = llvm_scene
    gaussian = ReferenceScorer(reference)
    gaussian.pixel_filter = "gaussian"
    with pytest.raises(ValueError, match=r"per-pixel sampling traces box-filtered pixels .* gaussian-filtered renders"):
        render_adaptive(scene, gaussian, total_spp=8, warmup=False)
