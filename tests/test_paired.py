"""The paired cluster bootstrap of two scorers' errors (nriqa.eval.paired) and `nriqa-evaluate --base`."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from nriqa.eval.evaluate import main as evaluate_main
from nriqa.eval.paired import PairedError, main, paired_difference, read_rows


def _rows(offsets: dict[str, float], clusters: int = 6, per: int = 5, noise: float = 0.0, seed: int = 0):
    """Rows of ``images.csv`` form: each predictor reads every image ``offset`` too good (+ noise)."""
    rng = np.random.default_rng(seed)
    rows = []
    for c in range(clusters):
        for i in range(per):
            true = 0.1 + 0.8 * rng.random()
            for name, offset in offsets.items():
                err = offset + noise * rng.standard_normal()
                rows.append(
                    {
                        "predictor": name,
                        "id": f"s{c}/v/{i}",
                        "scene": f"s{c}",
                        "variant": 0,
                        "true": true,
                        "mapped": true + err,
                    }
                )
    return rows


def test_the_difference_is_the_mean_of_the_paired_absolute_errors():
    rows = _rows({"base": 0.03, "cand": -0.01})
    out = paired_difference(rows, "base", "cand")
    assert out["n"] == 30 and out["clusters"] == 6
    assert out["mae"] == pytest.approx(0.01) and out["base_mae"] == pytest.approx(0.03)
    assert out["diff"] == pytest.approx(-0.02)
    # every image errs by the same amount: every resample gives the same difference
    assert out["low"] == pytest.approx(-0.02) and out["high"] == pytest.approx(-0.02) and out["better"]


def test_a_candidate_that_differs_by_noise_alone_is_not_better_and_the_interval_holds_the_estimate():
    rows = _rows({"base": 0.0, "cand": 0.0}, clusters=12, noise=0.02, seed=3)
    out = paired_difference(rows, "base", "cand")
    assert out["low"] < out["diff"] < out["high"]
    assert out["low"] < 0.0 < out["high"] and not out["better"]
    assert paired_difference(rows, "base", "cand") == out  # deterministic for a seed
    assert paired_difference(rows, "base", "cand", seed=1)["low"] != out["low"]


def test_clusters_not_images_are_resampled():
    # one cluster carries all the gain: a resample without it shows none, so the interval reaches 0
    rows = _rows({"base": 0.02, "cand": 0.02}, clusters=8)
    for r in rows:
        if r["predictor"] == "cand" and r["scene"] == "s0":
            r["mapped"] = r["true"]
    out = paired_difference(rows, "base", "cand")
    assert out["diff"] == pytest.approx(-0.02 / 8)
    assert out["high"] == pytest.approx(0.0) and not out["better"]


def test_only_images_both_scored_finitely_are_paired():
    rows = _rows({"base": 0.03, "cand": 0.01})
    rows[1]["mapped"] = float("nan")  # cand's first image
    rows = [r for r in rows if not (r["predictor"] == "base" and r["id"] == "s5/v/4")]
    assert paired_difference(rows, "base", "cand")["n"] == 28


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"base": "nobody"}, "no rows of predictor 'nobody'"),
        ({"resamples": 10}, "at least 100 resamples"),
    ],
)
def test_bad_requests_are_one_line(kwargs, message):
    args = {"rows": _rows({"base": 0.0, "cand": 0.0}), "base": "base", "candidate": "cand", **kwargs}
    with pytest.raises(PairedError, match=message):
        paired_difference(**args)


def test_cli_rereads_an_images_csv(tmp_path):
    rows = _rows({"base": 0.03, "cand": 0.01, "other": 0.05})
    path = tmp_path / "images.csv"
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    main([str(path), "--base", "base"])
    table = (tmp_path / "paired.md").read_text()
    assert "| cand | base | 30 | 6 |" in table and "| other | base |" in table
    assert len(read_rows(path)) == 90
    with pytest.raises(SystemExit) as exc:
        main([str(tmp_path / "missing.csv"), "--base", "base"])
    assert str(exc.value).startswith("error: cannot read") and "\n" not in str(exc.value)
    with pytest.raises(SystemExit) as exc:
        main([str(tmp_path / "paired.csv"), "--base", "base"])
    assert "is not an nriqa-evaluate images.csv" in str(exc.value)


def test_evaluate_base_writes_the_paired_table(synthetic_dataset, tmp_path):
    evaluate_main(
        [str(synthetic_dataset), "--out", str(tmp_path), "--baselines", "dual_buffer,wavelet_sigma"]
        + ["--base", "dual_buffer", "--no-figures"]
    )
    table = (tmp_path / "paired.md").read_text()
    assert "| wavelet_sigma | dual_buffer |" in table
    with open(tmp_path / "paired.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    assert float(row["low"]) <= float(row["diff"]) <= float(row["high"])
    with pytest.raises(SystemExit) as exc:
        evaluate_main([str(synthetic_dataset), "--out", str(tmp_path), "--baselines", "dual_buffer", "--base", "nope"])
    assert str(exc.value).startswith("error: --base nope: not one of the predictors")
