"""benchmarks/adaptive_interval.py: the interval's low end along uniform and adaptive loops on a dataset's scenes
(the tiny preset, llvm_ad_rgb); bad options are one line."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "adaptive_interval.py"


def run(*argv: str, env=None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *argv], capture_output=True, text=True, cwd=REPO, env=env, timeout=600
    )


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--data", "nowhere"], "nowhere: no manifest.json"),
        (["--seeds", "0"], "--seeds must be >= 1"),
        (["--scorer", "dual_fast"], "--scorer dual_fast: a two-buffer scorer; pass it as --twin-scorer"),
        (["--twin-scorer", "unet_fast"], "--twin-scorer unet_fast: no two-buffer scorer"),
        (["--scorer", "fcnn"], "--scorer fcnn: no calibrated interval"),
        (["--loops", "uniform,spiral"], "--loops spiral: not a loop kind"),
        (["--loops", ","], "--loops (none): not a loop kind"),
    ],
)
def test_bad_options_are_one_line(synthetic_dataset, argv, message):
    argv = ["--data", str(synthetic_dataset), *argv] if "--data" not in argv else argv
    proc = run(*argv)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and message in proc.stderr


def rows_on_the_tiny_preset(tiny, out: Path, max_spp: int, *extra: str) -> list[dict]:
    """The rows.csv of a run on the tiny preset's cornell scene, one seed (skipped without llvm_ad_rgb)."""
    pytest.importorskip("mitsuba")
    from nriqa.render.backend import llvm_env, probe_llvm

    ok, reason = probe_llvm()
    if not ok:
        pytest.skip(f"llvm_ad_rgb unusable here: {reason}")
    argv = ["--data", str(tiny), "--out", str(out), "--scenes", "cornell", "--max-spp", str(max_spp), "--seeds", "1"]
    proc = run(*argv, *extra, env={**os.environ, **llvm_env()})
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(out / "rows.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_rows_and_coverage_on_the_tiny_preset(tiny, tmp_path):
    out = tmp_path / "out"
    rows = rows_on_the_tiny_preset(tiny, out, 32, "--twin-scorer", "dual_fast")
    assert {(r["scorer"], r["loop"]) for r in rows} == {
        (s, loop) for s in ("single", "two-buffer") for loop in ("uniform", "adaptive")
    }
    assert {r["family"] for r in rows} == {"cornell"}
    steps = [tuple(r[k] for k in ("scorer", "loop", "variant", "seed", "spp")) for r in rows]
    assert len(steps) == len(set(steps)), "each scene variant runs once"
    for r in rows:
        score, low, true = float(r["score"]), float(r["low"]), float(r["true"])
        assert (
            0.0 <= low <= score <= 1.0 and 0.0 <= true <= 1.0 and float(r["spp"]) <= 33
        )  # budgets end within a sample
    with open(out / "summary.csv", newline="") as fh:
        summary = list(csv.DictReader(fh))
    overall = [s for s in summary if s["band"] == "all"]
    assert len(overall) == 4 and sum(int(s["rows"]) for s in overall) == len(rows)
    assert all(0.0 <= float(s["true >= low"]) <= 1.0 for s in summary)
    assert "true >= low" in (out / "adaptive_interval.md").read_text()


def test_one_kind_of_loop(tiny, tmp_path):
    """--loops uniform runs the uniform loops only (the rows a uniform loop interval is fitted on)."""
    rows = rows_on_the_tiny_preset(tiny, tmp_path / "out", 16, "--loops", "uniform")
    assert rows and {(r["scorer"], r["loop"]) for r in rows} == {("single", "uniform")}
