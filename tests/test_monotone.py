"""nriqa.eval.monotone: rung-to-rung falls and low predictions where the truth is converged."""

from __future__ import annotations

import math

import pytest

from nriqa.eval.monotone import ladder_row, ladders, monotonicity


def _rows(predicted, true, predictor="m", scene="s", variant=0, algorithm="path"):
    spps = [2 ** (k + 1) for k in range(len(predicted))]
    rows = [
        {
            "predictor": predictor,
            "scene": scene,
            "variant": variant,
            "algorithm": algorithm,
            "spp": n,
            "predicted": p,
            "true": t,
        }
        for n, p, t in zip(spps, predicted, true)
    ]
    return rows[::-1]  # out of order on purpose: ladders sort by spp


def test_rising_ladder_passes():
    rows = _rows([0.2, 0.5, 0.9, 0.97], [0.1, 0.4, 0.95, 0.985])
    ((key, rungs),) = ladders(rows).items()
    row = ladder_row(key, rungs)
    assert row["largest_drop"] == 0.0 and row["drop_at_spp"] == ""
    assert row["converged_rungs"] == 1 and row["low_where_converged"] == pytest.approx(0.97)
    assert row["passes"] == "yes"


def test_fall_is_found_at_its_rung():
    rows = _rows([0.3, 0.25, 0.245, 0.5], [0.1, 0.2, 0.3, 0.5])
    row = ladder_row(*next(iter(ladders(rows).items())))
    assert row["largest_drop"] == pytest.approx(0.05) and row["drop_at_spp"] == 4
    assert math.isnan(row["low_where_converged"]) and row["passes"] == "no"


def test_small_fall_passes_but_low_converged_prediction_fails():
    rows = _rows([0.90, 0.895, 0.93], [0.97, 0.98, 0.99])  # falls 0.005 only
    row = ladder_row(*next(iter(ladders(rows).items())))
    assert row["largest_drop"] == pytest.approx(0.005)
    assert row["low_where_converged"] == pytest.approx(0.895) and row["passes"] == "no"


def test_summary_counts_per_predictor_and_skips_raw_scorers():
    rows = (
        _rows([0.2, 0.5, 0.9], [0.1, 0.5, 0.99], variant=0)
        + _rows([0.5, 0.4, 0.97], [0.1, 0.5, 0.99], variant=1)
        + _rows([5.0, 1.0, 0.1], [0.1, 0.5, 0.99], predictor="raw")
    )
    per_ladder, summary = monotonicity(rows, ["m"])
    assert {r["predictor"] for r in per_ladder} == {"m"} and len(per_ladder) == 2
    (s,) = summary
    assert s["ladders"] == 2 and s["passing"] == 0
    assert s["largest_drop"] == pytest.approx(0.1) and s["ladders_with_drop"] == 1
    assert s["converged_rungs"] == 2 and s["low_where_converged"] == pytest.approx(0.9) and s["ladders_low"] == 1


def test_images_at_one_sample_count_are_one_rung():
    """Two images rendered at one count (a sampler that rounded) are one rung: their means, no fall between them."""
    rows = _rows([0.30, 0.26, 0.50], [0.2, 0.18, 0.4])
    rows = [{**r, "spp": 4 if r["spp"] <= 4 else 16} for r in rows]  # asked 2, 4, 8: rendered 4, 4, 16
    row = ladder_row(*next(iter(ladders(rows).items())))
    assert row["rungs"] == 2 and row["largest_drop"] == 0.0 and row["passes"] == "yes"


def test_square_spp_is_the_next_power_of_four_and_relabels_only_named_algorithms():
    from nriqa.eval.sample_counts import count_as_rendered, square_spp

    assert [square_spp(n) for n in (1, 2, 4, 8, 16, 32, 64, 128, 256, 512)] == [1, 4, 4, 16, 16, 64, 64, 256, 256, 1024]
    with pytest.raises(ValueError, match="at least 1"):
        square_spp(0)
    rows = _rows([0.1, 0.2, 0.3], [0.1, 0.2, 0.3], algorithm="path_ldsampler") + _rows([0.1], [0.1])
    out = count_as_rendered(rows, "*ldsampler")
    assert sorted((r["algorithm"], r["spp"], r.get("spp_asked")) for r in out) == [
        ("path", 2, None),
        ("path_ldsampler", 4, 2),
        ("path_ldsampler", 4, 4),
        ("path_ldsampler", 16, 8),
    ]
    assert count_as_rendered(rows, "") == rows
