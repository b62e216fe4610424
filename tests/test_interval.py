"""The calibrated score interval: its fit (ranks, bands), its card entry, the Scorer and the commands that use it."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from nriqa.eval import coverage
from nriqa.inference.interval import EDGES, LOOP_KINDS, IntervalError, ScoreInterval, loop_card_key
from nriqa.inference.pretrained import PretrainedError, load_card, load_pretrained, save_pretrained, update_card
from nriqa.inference.scorer import Scorer
from nriqa.models import create_model


def _draw(rng, n):
    """Predicted scores over [0, 1] and truths whose error grows towards the middle of the range."""
    p = rng.random(n)
    t = np.clip(p + rng.normal(0.0, 0.01 + 0.05 * p * (1 - p), n) + 0.01, 0.0, 1.0)
    return p, t


def test_coverage_on_fresh_exchangeable_draws_is_the_level():
    rng = np.random.default_rng(0)
    iv = ScoreInterval.fit(*_draw(rng, 4000), level=0.9)
    p, t = _draw(rng, 20000)
    cov = iv.covers(p, t).mean()
    assert 0.88 <= cov <= 0.92
    lo, hi = iv(p)
    # the error is larger mid-range, so the bands there are wider than at the ends
    width = hi - lo
    assert width[(p > 0.4) & (p < 0.6)].mean() > 2 * width[p > 0.98].mean()


def test_offsets_are_the_conformal_order_statistics():
    p = np.full(9, 0.5)
    r = np.arange(1, 10) / 100.0  # residuals 0.01 .. 0.09
    iv = ScoreInterval.fit(p, p + r, level=0.8, edges=(0.0, 1.0), min_count=1)
    # a = 0.1, n = 9: ranks floor(1.0) = 1 and ceil(9.0) = 9
    assert iv.low == pytest.approx((0.01,)) and iv.high == pytest.approx((0.09,))
    assert iv(0.5) == pytest.approx((0.51, 0.59))
    # too few residuals for the level: no bound from the data on either side, the ends are 0 and 1
    iv = ScoreInterval.fit(p[:5], p[:5] + r[:5], level=0.9, edges=(0.0, 1.0), min_count=1)
    assert iv.low == (-math.inf,) and iv.high == (math.inf,)
    assert iv(0.5) == (0.0, 1.0)


def test_sparse_bands_merge_into_their_neighbours():
    rng = np.random.default_rng(1)
    p = np.concatenate([rng.uniform(0.0, 0.2, 100), rng.uniform(0.95, 1.0, 100), [0.5] * 5])
    iv = ScoreInterval.fit(p, p, level=0.9, min_count=30)
    assert iv.edges[0] == 0.0 and iv.edges[-1] == 1.0 and min(iv.counts) >= 30
    assert sum(iv.counts) == p.size and len(iv.counts) == len(iv.edges) - 1 < len(EDGES) - 1


def test_ends_are_clipped_and_nan_stays_nan():
    iv = ScoreInterval(0.9, (0.0, 1.0), (-0.5,), (0.5,), (100,))
    assert iv(0.9) == (0.4, 1.0) and iv(0.1) == (0.0, 0.6)
    lo, hi = iv(np.array([np.nan, 0.5]))
    assert np.isnan(lo[0]) and np.isnan(hi[0]) and (lo[1], hi[1]) == (0.0, 1.0)


def test_card_form_round_trips_and_malformed_entries_are_refused():
    iv = ScoreInterval(0.9, (0.0, 0.5, 1.0), (-math.inf, -0.02), (0.03, math.inf), (40, 50), "test")
    entry = json.loads(json.dumps(iv.to_dict()))  # infinities become null, which JSON can carry
    assert entry["low"][0] is None and ScoreInterval.from_dict(entry) == iv
    for bad in ({"level": 0.9}, {**entry, "low": [0.1]}, {**entry, "edges": [0.0, 0.7, 0.5]}, {**entry, "level": 1.5}):
        with pytest.raises(IntervalError):
            ScoreInterval.from_dict(bad)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"level": 1.0}, "level"),
        ({"edges": (0.1, 1.0)}, "edges"),
        ({"edges": (0.0, 0.6, 0.4, 1.0)}, "edges"),
    ],
)
def test_fit_refuses_bad_arguments(kwargs, match):
    with pytest.raises(IntervalError, match=match):
        ScoreInterval.fit(np.linspace(0, 1, 100), np.linspace(0, 1, 100), **kwargs)


def test_fit_refuses_mismatched_or_too_few_images():
    with pytest.raises(IntervalError, match="predicted"):
        ScoreInterval.fit([0.1, 0.2], [0.1])
    with pytest.raises(IntervalError, match="usable"):
        ScoreInterval.fit([0.1, np.nan] * 10, [0.1, 0.2] * 10, min_count=30)


# --- the shipped cards and the Scorer -------------------------------------------------------------


@pytest.mark.parametrize("name, images", [("unet_fast", 3132), ("dual_fast", 1592), ("fcnn_fast", 1592)])
def test_shipped_cards_carry_a_90_percent_interval_fitted_on_unlearnt_images(name, images):
    # rule X (stop 42) for each file then shipped; unet_fast refitted for its file (rule R71, stop 69; stops 71 and 80)
    entry = load_card(name)[0]["score_interval"]
    iv = ScoreInterval.from_dict(entry)
    assert iv.level == 0.9 and sum(iv.counts) == images and min(iv.counts) >= 30
    assert "never learnt" in iv.source and "external" in iv.source
    assert all(lo <= 0.0 <= hi for lo, hi in zip(iv.low, iv.high))


@pytest.mark.parametrize(
    "name, kinds, level",
    [("unet_fast", {"adaptive"}, 0.9), ("dual_fast", {"uniform", "adaptive"}, 0.96), ("fcnn_fast", set(), None)],
)
def test_shipped_loop_intervals_are_the_rules_fits_on_loop_rows(name, kinds, level):
    # rules LI and LI2 (stop 45, docs/results/render_compare.md): fitted on every step of render loops
    scorer = Scorer.from_pretrained(name)
    assert set(scorer.loop_intervals) == kinds
    for iv in scorer.loop_intervals.values():
        assert iv.level == level and min(iv.counts) >= 30 and "adaptive_interval.py" in iv.source
        assert sum(iv.counts) == (3128 if name == "unet_fast" else 3910)
        assert all(lo <= 0.0 for lo in iv.low)  # the low end is never above the score
    if name == "dual_fast":  # the halves' loop interval reaches further below than the twin's, carried
        assert min(scorer.loop_intervals["uniform"].low) < min(scorer.interval.low) / 2


def test_the_default_scorer_gives_ordered_ends_for_every_kind_of_input():
    scorer = Scorer.from_pretrained()
    rng = np.random.default_rng(0)
    noisy = rng.random((64, 64, 3)).astype(np.float32) * 2.0
    firefly = np.full((64, 64, 3), 0.2, np.float32)
    firefly[10, 10] = 1e6
    bad = noisy.copy()
    bad[0, 0] = np.nan
    bad[1, 1] = np.inf
    batch = np.stack([noisy, firefly, bad, np.zeros_like(noisy), np.full_like(noisy, 0.5)])
    result = scorer(batch, hdr=True)
    assert result.low.shape == result.high.shape == result.score.shape == (5,)
    assert np.isfinite(result.low).all() and np.isfinite(result.high).all()
    assert (0.0 <= result.low).all() and (result.low <= result.high).all() and (result.high <= 1.0).all()
    one = scorer(noisy)
    assert isinstance(one.low, float) and one.low == pytest.approx(float(result.low[0]), abs=1e-6)
    as_torch = scorer(torch.from_numpy(noisy).permute(2, 0, 1))
    assert as_torch.low == pytest.approx(one.low) and as_torch.high == pytest.approx(one.high)
    tb = scorer(torch.from_numpy(batch).permute(0, 3, 1, 2), hdr=True)
    assert isinstance(tb.low, torch.Tensor) and torch.allclose(tb.low, torch.from_numpy(result.low))


def test_images_taken_as_ldr_get_the_ldr_calibration():
    hdr_iv = ScoreInterval(0.9, (0.0, 1.0), (-0.1,), (0.1,), (100,))
    ldr_iv = ScoreInterval(0.9, (0.0, 1.0), (-0.3,), (0.0,), (100,))
    scorer = Scorer(load_pretrained("unet_fast"), interval=hdr_iv, ldr_interval=ldr_iv)
    rng = np.random.default_rng(0)
    ldr = rng.random((64, 64, 3)).astype(np.float32)
    batch = np.stack([ldr * 3.0, ldr])  # values above 1: HDR; within [0, 1]: LDR
    r = scorer(batch)
    assert r.hdr == [True, False]
    assert r.low[0] == pytest.approx(max(r.score[0] - 0.1, 0.0)) and r.high[0] == pytest.approx(r.score[0] + 0.1)
    assert r.low[1] == pytest.approx(max(r.score[1] - 0.3, 0.0)) and r.high[1] == pytest.approx(r.score[1])
    assert scorer(ldr, hdr=True).high == pytest.approx(scorer(ldr, hdr=True).score + 0.1)
    with pytest.raises(ValueError, match="give interval too"):
        Scorer(load_pretrained("unet_fast"), ldr_interval=ldr_iv)


def test_the_shipped_ldr_calibrations():
    scorer = Scorer.from_pretrained()
    assert scorer.ldr_interval is not None and sum(scorer.ldr_interval.counts) == 9396
    assert "rule LR" in scorer.ldr_interval.source
    dual = Scorer.from_pretrained("dual_fast").ldr_interval
    assert dual is not None and sum(dual.counts) == 5916 and "rule X4" in dual.source
    assert Scorer.from_pretrained("fcnn_fast").ldr_interval is None
    assert Scorer.from_pretrained(interval=None).ldr_interval is None


def test_a_scorer_without_a_calibration_gives_no_ends():
    assert Scorer.from_pretrained(interval=None)(np.zeros((64, 64, 3), np.float32)).low is None
    assert Scorer(load_pretrained("fcnn_fast")).interval is None
    with pytest.raises(ValueError, match="patch model"):
        Scorer(create_model("patch_cnn"), interval=ScoreInterval(0.9, (0.0, 1.0), (0.0,), (0.0,), (1,)))


def test_a_malformed_card_entry_is_one_line_at_load(tmp_path):
    save_pretrained(create_model("fcnn_fast"), "w", {"note": "test"}, dir=tmp_path, spec={"name": "fcnn_fast"})
    update_card("w", {"score_interval": {"level": 0.9}}, dir=tmp_path)
    with pytest.raises(PretrainedError, match=r"the card's score_interval: malformed .*nriqa\.eval\.coverage fit"):
        Scorer.from_pretrained("w", dir=tmp_path)
    # a spread entry names its own key and the tool that fits it
    update_card("w", {"score_interval": None, "score_interval_spread": {"level": 0.9}}, dir=tmp_path)
    with pytest.raises(PretrainedError, match=r"the card's score_interval_spread: .*nriqa\.eval\.spread fit"):
        Scorer.from_pretrained("w", dir=tmp_path)


def test_update_card_keeps_the_weights_and_refuses_their_own_keys(tmp_path):
    save_pretrained(create_model("fcnn_fast"), "w", {"note": "test"}, dir=tmp_path, spec={"name": "fcnn_fast"})
    before = load_card("w", tmp_path)[0]
    update_card("w", {"extra": 1}, dir=tmp_path)
    after = load_card("w", tmp_path)[0]
    assert after == {**before, "extra": 1}
    load_pretrained("w", dir=tmp_path)  # the checksum still holds
    with pytest.raises(PretrainedError, match="re-export"):
        update_card("w", {"sha256": "0"}, dir=tmp_path)


# --- the coverage command -------------------------------------------------------------------------------


def _images_csv(path: Path, seed: int, scenes=("a", "b", "c", "d")) -> Path:
    rng = np.random.default_rng(seed)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["predictor", "id", "scene", "variant", "algorithm", "spp", "true", "predicted", "mapped"])
        for scene in scenes:
            p, t = _draw(rng, 120)
            for i, (pi, ti) in enumerate(zip(p, t)):
                w.writerow(["m", f"{scene}/{i}", scene, 0, "path", 4, ti, pi, pi])
    return path


def test_coverage_fit_check_and_leave_one_out(tmp_path, capsys):
    cal, test = _images_csv(tmp_path / "cal.csv", 0), _images_csv(tmp_path / "test.csv", 1)
    out = tmp_path / "iv.json"
    assert coverage.main(["fit", str(cal), "--predictor", "m", "--out", str(out), "--source", "synthetic"]) == 0
    assert ScoreInterval.from_dict(json.loads(out.read_text())).source == "synthetic"
    assert coverage.main(["check", str(test), "--predictor", "m", "--interval", str(out), "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader((tmp_path / "coverage.csv").open()))
    assert rows[0]["group"] == "all" and int(rows[0]["n"]) == 480 and 0.8 <= float(rows[0]["coverage"]) <= 0.97
    assert {r["group"] for r in rows} >= {"scene a", "scene d"}
    capsys.readouterr()
    assert coverage.main(["cv", str(cal), "--predictor", "m", "--exclude-scene", "d"]) == 0
    printed = capsys.readouterr().out
    assert "all (each scene held out) | 360" in printed and "scene d" not in printed


def test_coverage_command_errors_are_one_line(tmp_path, capsys):
    cal = _images_csv(tmp_path / "cal.csv", 0)
    cases = [
        ["fit", str(cal), "--predictor", "nope", "--out", str(tmp_path / "x.json")],
        ["fit", str(cal), "--predictor", "m"],
        ["check", str(cal), "--predictor", "m"],
        ["check", str(cal), "--predictor", "m", "--interval", str(tmp_path / "missing.json")],
        ["fit", str(tmp_path / "missing.csv"), "--predictor", "m", "--out", str(tmp_path / "x.json")],
    ]
    for argv in cases:
        assert coverage.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("python -m nriqa.eval.coverage: error:") and "\n" not in err
    assert not (tmp_path / "x.json").exists()


def test_predict_prints_the_interval_of_the_shipped_default(tmp_path, capsys):
    from nriqa.cli import predict
    from nriqa.io.exr import write_exr

    rng = np.random.default_rng(0)
    path = tmp_path / "render.exr"
    write_exr(path, (rng.random((64, 64, 3)) * 2.0).astype(np.float32))
    out = tmp_path / "out"
    assert predict.main([str(path), "--out", str(out), "--no-figures"]) == 0
    name, score, low, high = capsys.readouterr().out.split()
    assert name == str(path) and float(low) <= float(high)
    assert predict.main([str(path), "--out", str(out), "--no-figures", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["level"] == 0.9 and row["low"] == pytest.approx(float(low), abs=2e-6) and row["score"] == float(score)
    # weights without a calibration: the line stays 'path score'
    assert predict.main([str(path), "--out", str(out), "--no-figures", "--model", "fcnn"]) == 0
    assert len(capsys.readouterr().out.split()) == 2


def test_coverage_fit_writes_the_card_and_check_reads_it(tmp_path, capsys):
    save_pretrained(create_model("fcnn_fast"), "w", {"note": "test"}, dir=tmp_path, spec={"name": "fcnn_fast"})
    cal = _images_csv(tmp_path / "cal.csv", 0)
    weights = ["--weights", "w", "--dir", str(tmp_path)]
    assert coverage.main(["fit", str(cal), "--predictor", "m", *weights, "--ldr"]) == 0
    card = load_card("w", tmp_path)[0]
    assert "score_interval_ldr" in card and "score_interval" not in card
    load_pretrained("w", dir=tmp_path)  # the weights' checksum still holds
    capsys.readouterr()
    assert coverage.main(["check", str(cal), "--predictor", "m", *weights, "--ldr"]) == 0
    assert coverage.main(["check", str(cal), "--predictor", "m", *weights]) == 2
    assert "has no score_interval;" in capsys.readouterr().err


def test_ladder_stops_on_the_score_and_on_the_low_end(tmp_path, capsys):
    # an interval 0.02 below and 0.01 above every score
    iv = ScoreInterval(0.9, (0.0, 1.0), (-0.02,), (0.01,), (100,))
    spp = [2, 4, 8, 16, 32]

    def ladder(scene, variant, true, pred):
        return [
            {"scene": scene, "variant": variant, "algorithm": "path", "spp": str(n), "true": t, "mapped": p}
            for n, t, p in zip(spp, true, pred)
        ]

    rows = (
        # reads high: the score reaches 0.9 a rung before the truth (stops short); the low end on the truth's rung
        ladder("a", 0, [0.80, 0.85, 0.90, 0.95, 0.97], [0.85, 0.91, 0.93, 0.96, 0.98])
        # reads right: the score stops on the truth's rung, the low end one rung later
        + ladder("b", 0, [0.80, 0.88, 0.91, 0.93, 0.95], [0.80, 0.88, 0.91, 0.93, 0.95])
        # the truth never reaches 0.9: not counted
        + ladder("c", 0, [0.50, 0.60, 0.70, 0.80, 0.85], [0.50, 0.60, 0.70, 0.80, 0.95])
        # the same scene in another file is another ladder; its low end never reaches 0.9
        + [dict(r, _file=1) for r in ladder("b", 0, [0.80, 0.85, 0.89, 0.90, 0.91], [0.8, 0.85, 0.89, 0.90, 0.91])]
    )
    table = {r["rule"]: r for r in coverage.ladder_stops(rows, iv, [0.9])}
    score, low = table["score"], table["low end"]
    assert score["ladders"] == low["ladders"] == 3
    assert score["stopped"] == 3 and score["at or above"] == "2/3"
    assert score["true at the stop"] == pytest.approx((0.85 + 0.91 + 0.90) / 3)
    assert score["spp over the truth's"] == pytest.approx((0.5 * 1 * 1) ** (1 / 3))
    assert low["stopped"] == 2 and low["at or above"] == "2/2"
    assert low["true at the stop"] == pytest.approx((0.90 + 0.93) / 2)
    assert low["spp over the truth's"] == pytest.approx((1 * 2) ** 0.5)
    # the command, on a card's interval; bad targets are one line
    cal = _images_csv(tmp_path / "cal.csv", 0)
    assert coverage.main(["stops", str(cal), "--predictor", "m", "--weights", "unet_fast", "--out", str(tmp_path)]) == 0
    assert [r["rule"] for r in csv.DictReader((tmp_path / "stops.csv").open())] == ["score", "low end"] * 3
    capsys.readouterr()
    assert coverage.main(["stops", str(cal), "--predictor", "m", "--weights", "unet_fast", "--targets", "0.9,1"]) == 2
    assert "--targets" in capsys.readouterr().err


# --- intervals calibrated on render loops --------------------------------------------------------------


def _loop_rows_csv(path: Path, seed: int, families=("a", "b", "c", "d")) -> Path:
    """Rows as benchmarks/adaptive_interval.py writes them: the adaptive loops' scores read 0.05 high."""
    rng = np.random.default_rng(seed)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scorer", "loop", "family", "variant", "seed", "spp", "score", "low", "true", "band"])
        for family in families:
            p, t = _draw(rng, 80)
            for loop, shift in (("uniform", 0.0), ("adaptive", 0.05)):
                for i, (pi, ti) in enumerate(zip(p, t)):
                    w.writerow(["two-buffer", loop, family, 0, 0, 4 * (i + 1), pi + shift, pi - 0.01, ti, ""])
    return path


def test_a_loop_interval_is_fitted_on_loop_rows_into_the_card_and_the_scorer_reads_it(tmp_path, capsys):
    save_pretrained(create_model("fcnn_fast"), "w", {"note": "test"}, dir=tmp_path, spec={"name": "fcnn_fast"})
    update_card("w", {"score_interval": ScoreInterval(0.9, (0.0, 1.0), (-0.01,), (0.01,), (50,)).to_dict()}, tmp_path)
    rows = _loop_rows_csv(tmp_path / "rows.csv", 0)
    weights = ["--weights", "w", "--dir", str(tmp_path)]
    for kind in ("uniform", "adaptive"):
        assert coverage.main(["fit", str(rows), "--predictor", "two-buffer", "--loop", kind, *weights]) == 0
    card = load_card("w", tmp_path)[0]
    uniform = ScoreInterval.from_dict(card["score_interval_loop_uniform"])
    adaptive = ScoreInterval.from_dict(card["score_interval_loop_adaptive"])
    assert sum(uniform.counts) == sum(adaptive.counts) == 320
    # the adaptive rows read 0.05 high, so their interval reaches further below the score
    assert np.mean(adaptive.low) < np.mean(uniform.low) - 0.03
    scorer = Scorer.from_pretrained("w", dir=tmp_path)
    assert scorer.interval is not None and set(scorer.loop_intervals) == {"uniform", "adaptive"}
    assert scorer.loop_intervals["adaptive"] == adaptive
    assert Scorer.from_pretrained("w", dir=tmp_path, interval=None).loop_intervals == {}
    capsys.readouterr()
    fresh = _loop_rows_csv(tmp_path / "fresh.csv", 1)
    assert coverage.main(["check", str(fresh), "--predictor", "two-buffer", "--loop", "adaptive", *weights]) == 0
    assert "| all | 320 |" in capsys.readouterr().out
    assert coverage.main(["cv", str(rows), "--predictor", "two-buffer", "--loop", "uniform"]) == 0


def test_loop_interval_mistakes_are_one_line(tmp_path, capsys):
    images = _images_csv(tmp_path / "images.csv", 0)
    rows = _loop_rows_csv(tmp_path / "rows.csv", 0)
    out = ["--out", str(tmp_path / "x.json")]
    cases = [
        (["fit", str(images), "--predictor", "m", "--loop", "uniform", *out], "is not a rows.csv of"),
        (["fit", str(rows), "--predictor", "single", "--loop", "uniform", *out], "no rows of predictor 'single'"),
        (["fit", str(rows), "--predictor", "two-buffer", "--loop", "uniform", "--ldr", *out], "two different"),
    ]
    for argv, message in cases:
        assert coverage.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("python -m nriqa.eval.coverage: error:") and message in err and "\n" not in err
    assert not (tmp_path / "x.json").exists()
    with pytest.raises(ValueError, match="loop kinds"):
        Scorer(create_model("fcnn_fast"), loop_intervals={"peer": ScoreInterval(0.9, (0.0, 1.0), (0.0,), (0.0,), (1,))})
    with pytest.raises(TypeError, match="ScoreInterval"):
        Scorer(create_model("fcnn_fast"), loop_intervals={"uniform": (0.0, 1.0)})


def test_loop_card_keys_name_each_loop_kind_once():
    assert [loop_card_key(k) for k in LOOP_KINDS] == ["score_interval_loop_uniform", "score_interval_loop_adaptive"]
    with pytest.raises(ValueError, match="loop kinds"):
        loop_card_key("tiles")
