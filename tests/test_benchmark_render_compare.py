"""benchmarks/render_compare.py and nriqa.render.compare: the quick mode writes every output (llvm_ad_rgb),
bad options are one line; the equal-quality interpolation, ratios and threshold choice on known numbers."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nriqa.inference import DEFAULT_WEIGHTS
from nriqa.render.compare import (
    choose_threshold,
    equal_time_rows,
    method_summary,
    on_target,
    spp_for_error,
    uniform_reaches,
)

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "render_compare.py"


def test_spp_for_error_interpolates_uniforms_curve_in_log_log():
    spp = np.array([4.0, 8.0, 16.0, 32.0])
    curve = 0.4 / spp  # error halves as the samples double
    assert spp_for_error(0.4 / 11.0, spp, curve) == (pytest.approx(11.0), "")
    assert spp_for_error(0.1, spp, curve) == (pytest.approx(4.0), "")
    assert spp_for_error(0.001, spp, curve) == (32.0, ">")  # better than uniform's best: a bound
    assert spp_for_error(0.5, spp, curve) == (4.0, "<")
    # A curve that goes up by noise: uniform's best so far counts.
    expected = 16 * 2 ** (np.log(1.25) / np.log(2.5))
    assert spp_for_error(0.04, spp, np.array([0.1, 0.05, 0.06, 0.02]))[0] == pytest.approx(expected)
    assert uniform_reaches(0.95, spp, curve, 16) and not uniform_reaches(0.95, spp, curve, 4)
    assert not uniform_reaches(0.999, spp, curve, 1e6)


def test_equal_time_rows_give_ratios_to_uniform_per_seed_and_the_speed_up():
    spp = np.array([4.0, 8.0, 16.0, 32.0, 64.0])
    runs = (("uniform", 16, (0.025, 0.025)), ("peer", 10, (0.02, 0.03)), ("x", 20, (0.0125, 0.0125)))
    records = [
        {"scene": "a", "method": m, "seed": s, "true": 1 - e, "spp": n, "seconds": 1.0}
        for m, n, errors in runs
        for s, e in zip((1, 2), errors, strict=True)
    ]
    rows = {r["method"]: r for r in equal_time_rows(records, {"a": (spp, 0.4 / spp)})}
    assert rows["uniform"]["error ratio"] == 1.0 and rows["uniform"]["speed-up"] == pytest.approx(1.0)
    assert rows["peer"]["error ratio"] == pytest.approx((0.8 + 1.2) / 2)
    assert rows["x"]["speed-up"] == pytest.approx(2.0) and rows["x"]["bound"] == ""
    summary = {r["method"]: r for r in method_summary(list(rows.values()))}
    assert summary["x"]["beats the peer on"] == "1/1" and summary["uniform"]["beats the peer on"] == "0/1"


def test_choose_threshold_picks_the_one_on_target_most_often():
    runs = [{0.2: (10, 0.88), 0.1: (20, 0.905), 0.05: (40, 0.93)}, {0.2: (12, 0.86), 0.1: (25, 0.93), 0.05: (50, 0.96)}]
    assert choose_threshold(runs, 0.9) == (0.1, 0.5)
    assert choose_threshold(runs, 0.95) == (0.05, 0.5)
    assert on_target([0.894, 0.895, 0.92, 0.921], 0.9).tolist() == [False, True, True, False]


def test_scenes_take_families_learnt_later_or_held_back(tmp_path):
    sys.path.insert(0, str(REPO / "benchmarks"))
    from render_compare import parse

    scenes = ["foliage", "strands", "blinds", "shafts", "cornell"]
    assert parse(["--out", str(tmp_path), "--scenes", ",".join(scenes)]).scenes == scenes


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--scenes", "cornell,nowhere"], "unknown scene(s) nowhere"),
        (["--targets", "0.9,1.5"], "--targets must lie in (0, 1)"),
        (["--seeds", "0"], "--seeds"),
        (["--stop-margins", "0,-0.01"], "--stop-margins must lie in [0, 0.1)"),
        (["--scorer", "dual_fast"], "--scorer dual_fast needs a twin"),
        (["--scorer", "no_such_model"], "--scorer no_such_model:"),
        (["--twin-scorer", "fcnn_fast"], "--twin-scorer fcnn_fast is no two-buffer scorer"),
        (["--scorer", "fcnn_fast", "--overlap"], "--overlap: --scorer fcnn_fast is not read in windows"),
        (["--map-spp", "-1"], "--map-spp must be >= 0 or 'none'"),
        (["--stop-methods", "peer,guess"], "--stop-methods: unknown method(s) guess"),
        (["--stop-methods", "adaptive-sure-twin"], "need(s) a two-buffer scorer: give --twin-scorer"),
        (["--scorer", "fcnn", "--stop-methods", "adaptive-sure"], "adaptive-sure: --scorer fcnn has no calibrated"),
    ],
)
def test_bad_options_are_one_line(tmp_path, argv, message):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--out", str(tmp_path), *argv], capture_output=True, text=True, cwd=REPO
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and message in proc.stderr


def run_quick(out: Path, *argv: str) -> None:
    """``render_compare.py --quick --out OUT ARGV`` in llvm_ad_rgb (skipped where it is unusable); must succeed."""
    pytest.importorskip("mitsuba")
    from nriqa.render.backend import llvm_env, probe_llvm

    ok, reason = probe_llvm()
    if not ok:
        pytest.skip(f"llvm_ad_rgb unusable here: {reason}")
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick", "--out", str(out), *argv],
        capture_output=True,
        text=True,
        cwd=REPO,
        env={**os.environ, **llvm_env()},
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_quick_mode_writes_the_tables_the_csvs_and_the_plot(tmp_path):
    out = tmp_path / "out"
    run_quick(out)
    table = (out / "render_compare.md").read_text()
    assert "## Equal time" in table and "## Early stopping" in table and "## Keeping the half buffer" in table
    assert "nan" not in table.lower()
    with open(out / "render_compare.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    scenes = {r["scene"] for r in rows}
    assert len(scenes) == 2
    for scene in scenes:
        methods = {r["method"] for r in rows if r["scene"] == scene}
        assert methods == {"uniform", "uniform (per pixel)", "peer", "adaptive", "oracle map"}
    assert all(float(r["error ratio"]) > 0 and float(r["speed-up"]) > 0 for r in rows)
    assert all(float(r["error ratio"]) == 1.0 for r in rows if r["method"] == "uniform")
    with open(out / "render_compare_stop.csv", newline="") as fh:
        stops = list(csv.DictReader(fh))
    assert {(r["method"], float(r["target"])) for r in stops} == {
        (m, t) for m in ("peer", "learned") for t in (0.9, 0.95, 0.98)
    }
    runs = json.loads((out / "runs.json").read_text())
    assert len(runs["equal_time"]) == 2 * 2 * 5 and set(runs["stop_thresholds"]) == {"0.9", "0.95", "0.98"}
    assert (out / "render_compare.png").stat().st_size > 10_000
    assert "No --twin-scorer" in table
    held = "Over the held-out scenes alone (cbox_official;"
    assert (held in table) == ("cbox_official" in scenes), "a scene no scorer learnt gets a summary of its own"


def test_every_data_gen_family_is_a_scene_and_those_not_tuned_on_get_a_summary_of_their_own():
    sys.path.insert(0, str(REPO / "benchmarks"))
    from omegaconf import OmegaConf
    from render_compare_stop import FAMILIES, held_out_summary

    from data_gen.scenes import list_scenes

    held_back = OmegaConf.load(REPO / "data_gen" / "configs" / "preset" / "heldout.yaml").scenes
    assert set(FAMILIES) < set(list_scenes()), "the peer's eight and the later families"
    assert {"foliage", "blinds", *held_back} <= set(list_scenes()), "learnt later or held back alike"

    def row(scene, on):
        return {"scene": scene, "target": 0.9, "method": "learned", "true SSIM": 0.9, "spp": 64.0,
                "uniform needs": "64", "reachable": True, "on target": on, "reached": on}  # fmt: skip

    rows = [row("cornell", "3/3"), row("foliage", "1/3"), row("shafts", "2/3")]
    text = "\n".join(held_out_summary(rows, 512))
    assert "(foliage, shafts; nothing was tuned on them)" in text and "3/6 (50 %)" in text
    assert held_out_summary(rows[:1], 512) == [] and held_out_summary(rows[1:], 512) == [], "all or none held out"


def test_overlap_adds_the_blended_map_to_the_equal_time_methods(tmp_path):
    out = tmp_path / "out"
    run_quick(out, "--overlap", "--skip", "stop,half_cost")
    with open(out / "render_compare.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for scene in {r["scene"] for r in rows}:
        methods = {r["method"] for r in rows if r["scene"] == scene}
        assert methods == {"uniform", "uniform (per pixel)", "peer", "adaptive", "adaptive (overlap)", "oracle map"}


def test_the_stopping_section_runs_alone_with_curves_of_its_own(tmp_path):
    """``--skip equal_time``: no clock, so no quiet machine needed; uniform's curves are measured for it."""
    out = tmp_path / "out"
    run_quick(out, "--skip", "equal_time,half_cost", "--map-spp", "none", "--sure", "--twin-scorer", "dual_fast")
    table = (out / "render_compare.md").read_text()
    assert "## Early stopping" in table and "## Equal time" not in table and "nan" not in table.lower()
    assert not (out / "render_compare.csv").exists()
    with open(out / "render_compare_stop.csv", newline="") as fh:
        stops = list(csv.DictReader(fh))
    assert stops and all(float(r["uniform needs"].lstrip("<>")) > 0 for r in stops)  # '>N': past the curve
    runs = json.loads((out / "runs.json").read_text())
    assert runs["args"]["map_spp"] == "None" and runs["args"]["scorer"] == DEFAULT_WEIGHTS
    assert len(runs["curves"]) == 2 and all(max(c["spp"]) >= 2 * 64 for c in runs["curves"].values())
    # the learned rule's margin, tuned on the family (cornell) from the quick grid (0, 0.01)
    assert runs["stop_margins"]["learned"] in (0.0, 0.01) and "Learned stop rules" in table
    assert {r["margin"] for r in runs["stop_margin_tuning"]} == {0.0, 0.01}
    # --sure: the shipped scorer stopping on its interval's low end, nothing tuned; runs end on it or at max_spp
    # and the two-buffer scorer likewise (its halves' interval carried to the whole image)
    methods = ["peer", "learned", "two-buffer", "sure (low end)", "sure, two-buffer (low end)"]
    assert {r["method"] for r in stops} == set(methods)
    sure = [r for r in stops if r["method"].startswith("sure")]
    assert len(sure) == 2 * len(stops) // 5 and "runs at or above" in table
    assert all(set(r["stops"].split("/")) <= {"sure", "max_spp"} for r in sure)


def test_the_sure_stop_in_render_adaptive_is_a_stopping_method_of_its_own(tmp_path):
    """``--stop-methods``: only the methods asked for run (no peer tuning, no margins); adaptive-sure places samples."""
    out = tmp_path / "out"
    methods = ("adaptive-sure,adaptive-sure-twin", "--twin-scorer", "dual_fast")
    run_quick(out, "--skip", "equal_time,half_cost", "--stop-methods", *methods)
    with open(out / "render_compare_stop.csv", newline="") as fh:
        stops = list(csv.DictReader(fh))
    labels = {"adaptive, sure (low end)", "adaptive, sure, two-buffer (low end)"}
    assert {r["method"] for r in stops} == labels and len(stops) == 2 * 3 * 2  # scenes x targets x methods
    assert all(set(r["stops"].split("/")) <= {"sure", "spp"} for r in stops)
    assert any("sure" in r["stops"] for r in stops)
    runs = json.loads((out / "runs.json").read_text())
    assert runs["stop_thresholds"] == {} and runs["stop_margins"] == {}
    table = (out / "render_compare.md").read_text()
    assert "Peer thresholds" not in table and "Learned stop rules" not in table and "runs at or above" in table
