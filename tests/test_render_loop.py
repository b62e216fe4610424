"""Render loops on a tiny Cornell box (32x32, scalar_rgb: no JIT compile, fast at this size)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

mi = pytest.importorskip("mitsuba")

from data_gen.backend import SCALAR_VARIANT, init_worker  # noqa: E402
from data_gen.plan import ImageTask, Job  # noqa: E402
from data_gen.render import scene_dict  # noqa: E402
from nriqa.models import create_model  # noqa: E402
from nriqa.render_loop import _expected_gain, render_adaptive, render_until, true_ssim  # noqa: E402
from nriqa.scorer import Scorer, ScoreResult  # noqa: E402

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


class OracleScorer:
    """Duck-typed scorer whose map is the true SSIM map: makes the stopping rule testable."""

    higher_is_better = True

    def __init__(self, reference):
        self.reference = reference

    def __call__(self, image, *, hdr=None):
        from nriqa.ssim import ssim_map
        from nriqa.tonemap import tonemap

        x, y = (tonemap(torch.from_numpy(np.ascontiguousarray(a)).permute(2, 0, 1)[None]) for a in (image, self.reference))
        m = ssim_map(x, y)[0, 0].numpy()
        return ScoreResult(m, float(m.mean()), "ssim", True)


pytestmark = pytest.mark.usefixtures("one_thread")


def test_render_until_runs_to_max_spp(scene, scorer, reference):
    image, log = render_until(scene, scorer, target_score=None, time_budget_s=60, spp_per_step=2, reference=reference, max_spp=8)
    assert image.shape == (SIZE, SIZE, 3) and np.isfinite(image).all()
    assert [r["spp"] for r in log] == [2, 4, 6, 8] and log[-1]["stop"] == "max_spp"
    assert all(np.isfinite(r["predicted"]) for r in log)
    assert log[-1]["true"] == pytest.approx(true_ssim(image, reference))
    assert log[-1]["true"] > log[0]["true"]  # more samples, closer to the reference
    assert all(b["seconds"] >= a["seconds"] for a, b in zip(log, log[1:]))
    assert log[-1]["seconds"] == pytest.approx(log[-1]["render_seconds"] + log[-1]["score_seconds"])


def test_render_until_stops_at_target(scene, reference):
    oracle = OracleScorer(reference)
    _, log = render_until(scene, oracle, target_score=0.5, time_budget_s=60, spp_per_step=2, max_spp=256)
    assert log[-1]["stop"] == "target" and log[-1]["predicted"] >= 0.5
    assert all(r["predicted"] < 0.5 for r in log[:-1])


def test_render_until_time_budget_and_uniform_baseline(scene):
    _, log = render_until(scene, None, target_score=None, time_budget_s=0.0, spp_per_step=2)
    assert len(log) == 1 and log[0]["stop"] == "time" and log[0]["predicted"] is None


def test_render_adaptive_refines_some_tiles_only(scene, reference):
    oracle = OracleScorer(reference)
    image, log = render_adaptive(scene, oracle, total_spp=7, initial_spp=4, spp_per_step=4, tile=16, fraction=0.25, reference=reference)
    counts = log[-1]["spp_map"]
    assert log[-1]["stop"] == "spp" and counts.mean() >= 7 and np.isfinite(image).all()
    assert log[-1]["spp"] == pytest.approx(counts.mean())
    # One 16x16 tile of four per step; counts are constant within tiles.
    tiles = counts.reshape(2, 16, 2, 16).transpose(0, 2, 1, 3).reshape(4, -1)
    assert (tiles == tiles[:, :1]).all()
    assert sorted(tiles[:, 0]) != [tiles[0, 0]] * 4  # not uniform
    assert [r["spp"] for r in log] == [4, 5, 6, 7]


def test_render_adaptive_with_all_tiles_is_uniform(scene, scorer, reference):
    image, log = render_adaptive(scene, scorer, total_spp=8, initial_spp=4, spp_per_step=4, tile=16, fraction=1.0, reference=reference)
    assert (log[-1]["spp_map"] == 8).all()
    assert log[-1]["true"] > log[0]["true"]


def test_render_adaptive_needs_a_budget_and_a_dict(scene, scorer):
    with pytest.raises(ValueError, match="budget"):
        render_adaptive(scene, scorer)
    with pytest.raises(TypeError, match="dict"):
        render_adaptive(mi.load_dict(scene), scorer, total_spp=4)


def test_expected_gain_prefers_worse_and_less_sampled_tiles():
    tiles = [(0, 0, 2, 2), (2, 0, 2, 2), (4, 0, 2, 2)]
    qmap = np.array([[0.9, 0.9, 0.5, 0.5, 0.5, 0.5]] * 2)
    count = np.array([[4, 4, 4, 4, 64, 64]] * 2, dtype=float)
    gain = _expected_gain(qmap, count, tiles, 4, higher_is_better=True)
    assert gain[1] > gain[0] and gain[1] > gain[2]  # worse than tile 0, fewer samples than tile 2
    mae_gain = _expected_gain(1 - qmap, count, tiles, 4, higher_is_better=False)
    np.testing.assert_allclose(mae_gain, gain)
