"""The scorer benchmark's range and render sections run end to end and write their tables (tiny, scalar_rgb)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

mi = pytest.importorskip("mitsuba")

from data_gen.backend import SCALAR_VARIANT, init_worker  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def load_benchmark():
    spec = importlib.util.spec_from_file_location("bench_scorer", REPO / "benchmarks" / "scorer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.usefixtures("one_thread")
def test_render_section_writes_every_method(tmp_path):
    previous = mi.variant()
    init_worker(SCALAR_VARIANT, 1)
    try:
        load_benchmark().main(["--out", str(tmp_path), "--skip", "throughput,memory,accuracy", "--scenes", "cornell",
                               "--resolution", "32", "--budget", "0.3", "--reference-spp", "32", "--render-repeats", "2", "--range-spp", "4,8",
                               "--stop-targets", "0.5", "--stop-max-spp", "16",
                               "--tile", "16", "--threads", "1"])
    finally:
        if previous is not None:
            mi.set_variant(previous)
    table = (tmp_path / "scorer.md").read_text()
    for method in ("uniform", "early stop", "adaptive", "adaptive (oracle map)", "adaptive (16px tiles)"):
        assert f"| cornell | {method} |" in table
    assert (tmp_path / "render_loops.png").stat().st_size > 0
    assert "nan" not in table.lower()
    assert len(list(tmp_path.glob("render_cornell_*.json"))) == 5
    # the range section: one row per scene and spp, a map PCC and both error ratios
    for spp in (4, 8):
        (row,) = [line for line in table.splitlines() if line.startswith(f"| cornell | {spp} |")]
        assert len(row.strip("|").split("|")) == 7
    # the stop section: one row per scene, target and way of rating
    for method in ("image", "probes past 64 spp"):
        (row,) = [line for line in table.splitlines() if line.startswith("| cornell | 0.5 |") and f"| {method} |" in line]
        assert len(row.strip("|").split("|")) == 9
