"""A rule's figures per scorer from evaluations' images.csv (nriqa.eval.scorecard)."""

from __future__ import annotations

import pytest

from nriqa.eval.scorecard import ScorecardError, by_group, main, read_rows, scorecard
from nriqa.io.tables import write_csv

COLUMNS = ["predictor", "id", "scene", "variant", "algorithm", "spp", "true", "predicted", "mapped"]
LADDER = (2, 4, 8, 16, 64, 256)


def _rows(errors: dict[str, dict[str, float]], scenes=("bright", "dark"), variants=(0, 1)) -> list[dict]:
    """A ladder per (scene, variant); ``errors[predictor][scene]`` is added to the truth at <= 8 spp."""
    rows = []
    for scene in scenes:
        for v in variants:
            for k, spp in enumerate(LADDER):
                true = 0.3 + 0.1 * k + 0.01 * v
                for name, err in errors.items():
                    e = err.get(scene, 0.0) if spp <= 8 else 0.0
                    rows.append(
                        {
                            "predictor": name,
                            "id": f"{scene}/{v}/{spp}",
                            "scene": scene,
                            "variant": v,
                            "algorithm": "path",
                            "spp": spp,
                            "true": true,
                            "predicted": true + e,
                            "mapped": true + e,
                        }
                    )
    return rows


def _write(tmp_path, name, rows):
    path = tmp_path / name
    write_csv(path, rows, COLUMNS)
    return path


def test_a_perfect_scorer_and_one_that_reads_dark_renders_too_good(tmp_path):
    path = _write(tmp_path, "images.csv", _rows({"exact": {}, "high": {"dark": 0.06}}))
    exact, high = scorecard(read_rows([path]), base="exact")
    assert exact["n"] == 24 and exact["mae"] == 0.0 and exact["bias"] == 0.0
    assert exact["srocc"] == pytest.approx(1.0, abs=1e-6) and exact["scene_srocc_worst"] == pytest.approx(1.0, abs=1e-6)
    assert exact["families_off"] == "" and exact["ladders"] == 4 and exact["ladders_falling"] == 0
    # 6 of its 24 images (dark, <= 8 spp) read 0.06 high: 12 low-spp images, half of them off
    assert high["low_n"] == 12 and high["low_bias"] == pytest.approx(0.03) and high["low_mae"] == pytest.approx(0.03)
    assert high["mae"] == pytest.approx(6 * 0.06 / 24) and high["bias"] == pytest.approx(6 * 0.06 / 24)
    # the dark family's bias over its 12 images is 0.03 > 0.02; the base has none off
    assert high["families_off"] == "dark:+0.030" and high["newly_off"] == "dark"


def test_a_fall_along_a_ladder_is_counted_and_lowers_the_within_scene_ranking(tmp_path):
    # 0.15 added at <= 8 spp on a rising ladder: 8 spp (0.65) reads above 16 spp (0.6)
    path = _write(tmp_path, "images.csv", _rows({"falls": {"dark": 0.15}}))
    (c,) = scorecard(read_rows([path]))
    assert c["ladders"] == 4 and c["ladders_falling"] == 2
    assert c["scene_srocc_worst"] < 1.0 and c["scene_srocc_mean"] < 1.0


def test_pooled_sets_keep_their_scene_variants_apart(tmp_path):
    a = _write(tmp_path, "a.csv", _rows({"exact": {}}, scenes=("bright",), variants=(0,)))
    b = _write(tmp_path, "b.csv", _rows({"exact": {}}, scenes=("bright",), variants=(0,)))
    rows = read_rows([a, b])
    assert len({r["id"] for r in rows}) == 12
    (c,) = scorecard(rows)
    assert c["n"] == 12 and c["ladders"] == 2


def test_bad_input_gets_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("predictor,id\nx,1\n")
    with pytest.raises(ScorecardError, match="bad.csv is not an nriqa-evaluate images.csv"):
        read_rows([bad])
    with pytest.raises(ScorecardError, match="cannot read"):
        read_rows([tmp_path / "missing.csv"])
    good = _write(tmp_path, "images.csv", _rows({"exact": {}}))
    with pytest.raises(ScorecardError, match="no rows of predictor 'other'; the rows have: exact"):
        scorecard(read_rows([good]), base="other")
    with pytest.raises(SystemExit, match="^error: .*bad.csv is not"):
        main([str(bad)])


def test_the_command_prints_and_writes_the_table(tmp_path, capsys):
    path = _write(tmp_path, "images.csv", _rows({"exact": {}, "high": {"dark": 0.06}}))
    main([str(path), "--base", "exact", "--out", str(tmp_path / "card")])
    out = capsys.readouterr().out
    assert "| high |" in out and "dark:+0.030" in out
    written = (tmp_path / "card" / "scorecard.md").read_text()
    assert "images.csv" in written and "dark:+0.030" in written
    assert (tmp_path / "card" / "scorecard.csv").read_text().startswith("predictor,n,srocc,mae")


def test_raw_scale_baselines_are_left_out_unless_named(tmp_path, capsys):
    rows = _rows({"exact": {}})
    rows += [dict(r, predictor="wavelet_sigma", mapped="") for r in rows]
    path = _write(tmp_path, "images.csv", rows)
    assert [c["predictor"] for c in scorecard(read_rows([path]))] == ["exact"]
    main([str(path)])
    out = capsys.readouterr()
    assert "| exact |" in out.out and "wavelet_sigma" not in out.out
    assert "left out (no reading on the SSIM scale): wavelet_sigma" in out.err
    with pytest.raises(ScorecardError, match="no finite rows of predictor 'wavelet_sigma'"):
        scorecard(read_rows([path]), ["wavelet_sigma"])


def test_a_family_can_be_left_out(tmp_path, capsys):
    path = _write(tmp_path, "images.csv", _rows({"high": {"dark": 0.06}}))
    main([str(path), "--without", "dark"])
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("| high |"))
    assert "| 12 |" in line and "dark" not in line


def test_rows_by_algorithm_and_by_family_show_where_the_error_lives(tmp_path, capsys):
    rows = _rows({"exact": {}, "high": {"dark": 0.06}})
    for r in rows:
        r["algorithm"] = "ptracer" if r["scene"] == "dark" else "path"
    path = _write(tmp_path, "images.csv", rows)
    pooled = scorecard(read_rows([path]))
    grouped = by_group(read_rows([path]), pooled, "algorithm")
    assert [(c["predictor"], c["group"]) for c in grouped] == [
        ("exact", "all"),
        ("high", "all"),
        ("exact", "path"),
        ("exact", "ptracer"),
        ("high", "path"),
        ("high", "ptracer"),
    ]
    high = {c["group"]: c for c in grouped if c["predictor"] == "high"}
    # the pooled row is the ungrouped card; the 0.06 lives in the dark renders' algorithm only
    assert high["all"]["mae"] == pytest.approx(pooled[1]["mae"]) and high["all"]["n"] == 24
    assert high["path"]["n"] == 12 and high["path"]["mae"] == 0.0
    assert high["ptracer"]["n"] == 12 and high["ptracer"]["bias"] == pytest.approx(6 * 0.06 / 12)
    assert high["ptracer"]["low_bias"] == pytest.approx(0.06)
    by_scene = by_group(read_rows([path]), pooled, "scene")
    assert [c["group"] for c in by_scene] == ["all", "all", "bright", "dark", "bright", "dark"]
    with pytest.raises(ScorecardError, match="cannot group by 'spp'; choose one of: scene, algorithm"):
        by_group(read_rows([path]), pooled, "spp")
    main([str(path), "--by", "algorithm", "--out", str(tmp_path / "card")])
    out = capsys.readouterr().out
    assert "| predictor | group | n |" in out and "| high | ptracer | 12 |" in out
    assert (tmp_path / "card" / "scorecard.csv").read_text().startswith("predictor,group,n,srocc")
