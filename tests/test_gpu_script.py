"""scripts/gpu/render_train.sh, the script for a lent GPU machine, run with the CPU backend: it renders in
cumulative stages, keeps the last complete one, gates it and writes its manifest where the run's files go."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mitsuba")

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "gpu" / "render_train.sh"


def run_script(tmp_path: Path, *runs: str, **env: str) -> subprocess.CompletedProcess:
    settings = {
        "OUT": str(tmp_path / "out"),
        "DATA": str(tmp_path / "data"),
        "SITE": "",
        "PY": sys.executable,
        "BACKEND": "scalar_rgb",
        "TRAINER": "cpu",
        "WORKERS": "0",
        "JOBS": "1",
        "RES": "16",
        "TOP": "4",
        "SCENES": "[cornell]",
        **env,
    }
    return subprocess.run(
        ["bash", str(SCRIPT), *runs],
        cwd=ROOT,
        env={**os.environ, **settings},
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_stages_render_a_complete_gated_dataset(tmp_path):
    proc = run_script(tmp_path, STAGES="1 2")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    variants = {r["variant"] for r in manifest["records"]}
    assert variants == {0, 1}
    assert {r["backend"] for r in manifest["records"]} == {"scalar_rgb"}
    log = (tmp_path / "out" / "device.log").read_text()
    assert "stage variants=1 rc=0" in log and "stage variants=2 rc=0" in log
    assert "dataset: 2 variants" in log and "no runs named" in log


def test_a_backend_that_does_not_work_stops_before_rendering(tmp_path):
    proc = run_script(tmp_path, BACKEND="no_such_variant")
    assert proc.returncode == 2
    assert "no_such_variant does not work here" in proc.stdout
    assert not (tmp_path / "data").exists()
