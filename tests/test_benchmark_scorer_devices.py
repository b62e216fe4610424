"""benchmarks/scorer_devices.py: the same renders scored on two devices, twins found by name, one-line refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import load_script

from nriqa.io.exr import write_exr


def load_benchmark():
    return load_script("benchmarks/scorer_devices.py")


def _renders(folder: Path) -> None:
    rng = np.random.default_rng(0)
    for name in ("scene/path - 4 - 1.exr", "scene/path - 4 - 2.exr", "other/lone.exr"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        write_exr(folder / name, (rng.random((48, 64, 3)) * 2).astype(np.float32))


@pytest.mark.usefixtures("one_thread")
def test_the_cpu_against_itself_agrees_exactly_and_twins_are_found_by_name(tmp_path, capsys):
    _renders(tmp_path / "in")
    rc = load_benchmark().main(
        [str(tmp_path / "in"), "--device", "cpu", "--models", "unet_fast,dual_fast", "--out", str(tmp_path / "out")]
    )
    assert rc == 0
    rows = {
        r[0].strip(): [c.strip() for c in r[1:]]
        for r in (line.split("|")[1:-1] for line in (tmp_path / "out" / "scorer_devices.md").read_text().splitlines())
        if r and r[0].strip() in ("unet_fast", "dual_fast")
    }
    assert rows["unet_fast"][0] == "3"  # every render
    assert rows["dual_fast"][0] == "1"  # only "... - 1" with its "... - 2" beside it
    for name in rows:
        assert float(rows[name][1]) == 0.0 and float(rows[name][2]) == 0.0
        assert float(rows[name][3]) > 0 and float(rows[name][4]) > 0


def test_refusals_are_one_line_and_exit_2(tmp_path, capsys):
    bench = load_benchmark()
    (tmp_path / "empty").mkdir()
    assert bench.main([str(tmp_path / "empty"), "--device", "cpu", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no *.exr under" in err and "\n" not in err
    assert not (tmp_path / "out").exists()
    if not torch.cuda.is_available():
        assert bench.main([str(tmp_path / "empty"), "--device", "cuda"]) == 2
        err = capsys.readouterr().err.strip()
        assert "not usable here" in err and "\n" not in err
