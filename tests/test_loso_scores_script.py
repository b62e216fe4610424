"""scripts/loso_scores.py: a plan's per-family scoring sets merged into one CSV per family, pooled by the scorecard."""

import importlib.util
from pathlib import Path

from nriqa.eval import scorecard
from nriqa.io.tables import read_csv, write_csv

ROOT = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("loso_scores", ROOT / "scripts" / "loso_scores.py")
loso_scores = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(loso_scores)

COLUMNS = ["predictor", "id", "scene", "variant", "algorithm", "spp", "true", "predicted", "mapped", "low", "high"]


def images(scene: str, variant: int, truth: list[float], pred: list[float]) -> list[dict]:
    return [
        {
            "predictor": "crossval",
            "id": f"{scene}/v{variant:03d}/path_independent/spp{2**k:05d}_a",
            "scene": scene,
            "variant": str(variant),
            "algorithm": "path_independent",
            "spp": str(2**k),
            "true": str(t),
            "predicted": str(p),
            "mapped": str(p),
            "low": "nan",
            "high": "nan",
        }
        for k, (t, p) in enumerate(zip(truth, pred), start=1)
    ]


def test_sets_are_merged_per_family_and_keep_their_ladders_apart(tmp_path, capsys):
    scores = tmp_path / "scores"
    # the same variant number in two sets: two ladders, not one of six rungs
    write_csv(scores / "lamps" / "setA" / "images.csv", images("lamps", 70, [0.2, 0.5, 0.8], [0.25, 0.5, 0.7]), COLUMNS)
    write_csv(
        scores / "lamps" / "setB" / "images.csv", images("lamps", 70, [0.3, 0.6, 0.9], [0.3, 0.65, 0.85]), COLUMNS
    )
    (scores / "door" / "setA").mkdir(parents=True)  # a fold still training: no images.csv yet
    assert loso_scores.main([str(scores), "--plan", "LL", "--out", str(tmp_path / "out")]) == 0
    assert "door: no images.csv yet, skipped" in capsys.readouterr().out
    assert not (tmp_path / "out" / "LL" / "door.csv").exists()
    rows = read_csv(tmp_path / "out" / "LL" / "lamps.csv", scorecard.NEED, "merged")
    assert len(rows) == 6 and {r["predictor"] for r in rows} == {"LL"}
    assert {r["variant"] for r in rows} == {"setA:70", "setB:70"}
    assert rows[0]["id"] == "setA/lamps/v070/path_independent/spp00002_a"
    assert list(rows[0]) == COLUMNS
    # the scorecard pools the merged file: six images, two ladders, the mean absolute error of the six
    scorecard.main([str(tmp_path / "out" / "LL" / "lamps.csv"), "--out", str(tmp_path / "card")])
    (row,) = read_csv(tmp_path / "card" / "scorecard.csv", {"predictor", "n", "mae", "ladders"}, "scorecard")
    assert row["n"] == "6" and row["ladders"] == "2"
    assert abs(float(row["mae"]) - (0.05 + 0 + 0.1 + 0 + 0.05 + 0.05) / 6) < 1e-9


def test_bad_input_is_one_line_and_nothing_written(tmp_path, capsys):
    assert loso_scores.main([str(tmp_path / "missing"), "--plan", "LL", "--out", str(tmp_path / "out")]) == 2
    assert "is not a folder" in capsys.readouterr().err
    bad = tmp_path / "scores" / "lamps" / "setA" / "images.csv"
    bad.parent.mkdir(parents=True)
    bad.write_text("a,b\n1,2\n")
    assert loso_scores.main([str(tmp_path / "scores"), "--plan", "LL", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(bad) in err and "need columns" in err
    assert not (tmp_path / "out").exists()
    assert loso_scores.main([str(tmp_path / "scores"), "--plan", "../x", "--out", str(tmp_path / "out")]) == 2


def test_a_family_scored_on_fewer_sets_than_another_is_held_back_and_named(tmp_path, capsys):
    scores, out = tmp_path / "scores", tmp_path / "out"
    for s in ("setA", "setB"):
        write_csv(scores / "lamps" / s / "images.csv", images("lamps", 70, [0.2, 0.5], [0.2, 0.5]), COLUMNS)
    # textured's scoring on setB failed (no folder); blinds has a set of its own and lacks nothing
    write_csv(scores / "textured" / "setA" / "images.csv", images("textured", 70, [0.2, 0.5], [0.3, 0.5]), COLUMNS)
    write_csv(scores / "blinds" / "own" / "images.csv", images("blinds", 70, [0.2, 0.5], [0.2, 0.4]), COLUMNS)
    assert loso_scores.main([str(scores), "--plan", "LL", "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "textured: not scored on setB (other families were); held back" in printed
    assert sorted(p.name for p in (out / "LL").iterdir()) == ["blinds.csv", "lamps.csv"]
    assert loso_scores.main([str(scores), "--plan", "LL", "--out", str(out), "--partial"]) == 0
    assert len(read_csv(out / "LL" / "textured.csv", scorecard.NEED, "merged")) == 2
