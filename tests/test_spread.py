"""The score's spread over an image's flips and turns, the interval that scales with it, the Scorer's opt-in, the
shipped calibration and its command (nriqa.inference.spread, nriqa.eval.spread)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from nriqa.eval import spread as spread_cli
from nriqa.inference.interval import IntervalError
from nriqa.inference.scorer import Scorer
from nriqa.inference.spread import VIEWS, SpreadInterval, score_spread, view_scores


def test_the_views_are_the_eight_flips_and_turns_and_need_no_square():
    x = torch.rand(2, 3, 5, 7)
    seen = []
    views = view_scores(lambda v: (seen.append(tuple(v.shape)), v.flatten(1)[:, :4].sum(1))[1], x)
    assert views.shape == (2, VIEWS) and seen == [(8, 3, 5, 7), (8, 3, 7, 5)]
    assert torch.allclose(views[:, 0], x.flatten(1)[:, :4].sum(1))  # column 0: the image itself
    # a mean over the whole image is the same in every view: no spread
    flat = view_scores(lambda v: v.mean(dim=(1, 2, 3)), x)
    assert torch.allclose(score_spread(flat), torch.zeros(2), atol=1e-6)
    # the views of a flipped image are the views of the image, in another order
    corner = view_scores(lambda v: v[:, 0, 0, 0], x)
    mirrored = view_scores(lambda v: v[:, 0, 0, 0], x.flip(-1))
    assert torch.equal(corner.sort(1).values, mirrored.sort(1).values)


def test_a_spread_interval_covers_errors_that_grow_with_the_spread():
    rng = np.random.default_rng(0)

    def draw(n):
        s = rng.gamma(1.5, 0.004, n)
        p = rng.uniform(0.2, 0.95, n)
        return p, p + rng.normal(0, 1, n) * (0.002 + 2 * s), s

    iv = SpreadInterval.fit(*draw(4000), level=0.9, source="synthetic")
    assert iv.low < 0 < iv.high and iv.count == 4000 and iv.floor > 0
    p, t, s = draw(4000)
    lo, hi = iv(p, s)
    assert abs(np.mean((lo <= t) & (t <= hi)) - 0.9) < 0.02
    wide = s > np.quantile(s, 0.9)
    assert np.mean(hi - lo)[()] > 0 and np.mean((hi - lo)[wide]) > 2 * np.mean((hi - lo)[~wide])
    assert iv(0.5, 0.0) == (pytest.approx(0.5 + iv.low * iv.floor), pytest.approx(0.5 + iv.high * iv.floor))
    assert iv(0.999, 1.0)[1] == 1.0 and iv(0.001, 1.0)[0] == 0.0  # clipped to [0, 1]
    assert SpreadInterval.from_dict(json.loads(json.dumps(iv.to_dict()))) == iv


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (([0.5] * 10, [0.5] * 10, [0.01] * 10), "too few"),
        (([0.5] * 40, [0.5] * 40, [0.0] * 40), "median spread"),
        (([0.5] * 40, [0.5] * 39, [0.01] * 40), "one of each per image"),
        (([0.5] * 40, [math.nan] * 40, [0.01] * 40), "finite"),
    ],
)
def test_a_spread_interval_that_cannot_be_fitted_is_one_line(args, message):
    with pytest.raises(IntervalError, match=message):
        SpreadInterval.fit(*args)


@pytest.mark.parametrize(
    "entry", [{}, {"level": 0.9, "floor": 0.0, "low": -1, "high": 1, "count": 5}, {"level": 0.9, "floor": 0.01}]
)
def test_a_malformed_spread_entry_is_one_line(entry):
    with pytest.raises(IntervalError, match="score_interval_spread"):
        SpreadInterval.from_dict(entry)


def test_the_scorer_gives_a_spread_only_when_asked_and_its_interval_to_hdr_images():
    rng = np.random.default_rng(1)
    hdr = (rng.random((2, 48, 64, 3)) * 3).astype(np.float32)
    plain, asked = Scorer.from_pretrained(), Scorer.from_pretrained(spread=True)
    a, b = plain(hdr), asked(hdr)
    assert a.spread is None and b.spread.shape == (2,) and np.all(np.isfinite(b.spread)) and np.all(b.spread >= 0)
    np.testing.assert_array_equal(a.score, b.score)  # the score stays the plain view's
    lo, hi = asked.spread_interval(b.score.astype(np.float64), b.spread.astype(np.float64))
    np.testing.assert_allclose(b.low, lo, atol=1e-6)
    np.testing.assert_allclose(b.high, hi, atol=1e-6)
    ldr = hdr[0] / hdr[0].max()  # within [0, 1]: taken as LDR, gets the LDR spread calibration
    one = asked(ldr)
    assert isinstance(one.spread, float)
    assert (one.low, one.high) == pytest.approx(asked.spread_ldr_interval(one.score, one.spread), abs=1e-6)
    assert (one.low, one.high) != (plain(ldr).low, plain(ldr).high)
    no_ldr = Scorer.from_pretrained(spread=True, spread_ldr_interval=None)(ldr)  # without one: score_interval_ldr
    assert (no_ldr.low, no_ldr.high) == (plain(ldr).low, plain(ldr).high)
    t = asked(torch.from_numpy(hdr).permute(0, 3, 1, 2))
    assert isinstance(t.spread, torch.Tensor) and torch.allclose(t.spread, torch.from_numpy(b.spread), atol=1e-6)
    with pytest.raises(ValueError, match="single-image SSIM map models"):
        Scorer.from_pretrained("dual_fast", spread=True)
    assert Scorer.from_pretrained(interval=None, spread=True).spread_interval is None


def test_the_shipped_spread_calibrations():
    scorer = Scorer.from_pretrained()
    iv, ldr = scorer.spread_interval, scorer.spread_ldr_interval
    assert iv is not None and iv.count == 3132 and iv.level == 0.9 and "rule R73" in iv.source
    assert ldr is not None and ldr.count == 9396 and "rule R74" in ldr.source
    assert Scorer.from_pretrained("fcnn_fast").spread_interval is None


def test_the_command_fits_checks_and_holds_out_families(synthetic_dataset, tmp_path, capsys):
    data = str(synthetic_dataset)
    out = tmp_path / "iv.json"
    assert spread_cli.main(["fit", data, "--level", "0.5", "--out", str(out)]) == 0
    iv = SpreadInterval.from_dict(json.loads(out.read_text()))
    assert iv.count == 12 and iv.level == 0.5
    assert spread_cli.main(["check", data, "--interval", str(out), "--out", str(tmp_path / "check")]) == 0
    text = (tmp_path / "check" / "spread.md").read_text()
    assert "| all: spread | 12 |" in text and "| all: score_interval | 12 |" in text and "family gamma" in text
    assert spread_cli.main(["cv", data, "--level", "0.5", "--min-count", "4"]) == 0
    assert "all (each family held out): spread" in capsys.readouterr().out
    # through two displays: twice the rows, scored as LDR, beside score_interval_ldr
    argv = ["check", data, "--interval", str(out), "--display", "srgb", "--display", "gamma22:8"]
    assert spread_cli.main(argv) == 0
    text = capsys.readouterr().out
    assert "| all: spread | 24 |" in text and "| all: score_interval_ldr | 24 |" in text
    assert spread_cli.main(["check", data, "--display", "srgb", "--weights", "fcnn_fast"]) == 2
    assert "weights 'fcnn_fast' carry no score_interval_ldr" in capsys.readouterr().err  # names them
    assert spread_cli.main(["check", data, "--display", "sepia"]) == 2
    assert "--display" in capsys.readouterr().err
    for argv, message in (
        (["fit", data], "--out FILE.json or --write"),
        (["check", str(tmp_path)], "no manifest.json"),
        (["check", data, "--weights", "fcnn_fast"], "no score_interval_spread"),
    ):
        assert spread_cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err


def test_the_command_reads_an_external_folder_by_its_pattern(synthetic_dataset, tmp_path, capsys):
    import shutil

    for scene in ("alpha", "beta", "gamma"):
        (tmp_path / "ext" / scene).mkdir(parents=True)
        shutil.copy(synthetic_dataset / scene / "reference.exr", tmp_path / "ext" / scene / "reference.exr")
        for spp in (1, 4, 16, 64):
            shutil.copy(
                synthetic_dataset / scene / f"path-{spp:04d}-test.exr", tmp_path / "ext" / scene / f"path - {spp}.exr"
            )
    ext = str(tmp_path / "ext")
    assert spread_cli.main(["cv", ext, "--level", "0.5", "--min-count", "4"]) == 2  # no manifest, no pattern
    assert "no manifest.json" in capsys.readouterr().err
    argv = ["cv", ext, "--pattern", "{scene}/{algorithm} - {spp}", "--level", "0.5", "--min-count", "4"]
    assert spread_cli.main(argv) == 0
    assert "| all (each family held out): spread | 12 |" in capsys.readouterr().out
