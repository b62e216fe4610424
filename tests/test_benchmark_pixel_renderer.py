"""benchmarks/pixel_renderer.py runs end to end and prints its table (tiny, llvm_ad_rgb)."""

from __future__ import annotations

import pytest
from conftest import load_script

mi = pytest.importorskip("mitsuba")


@pytest.mark.usefixtures("one_thread")
def test_pixel_renderer_benchmark_prints_both_ratios(capsys):
    from nriqa.render.backend import LLVM_VARIANT, SCALAR_VARIANT, init_worker, probe_llvm

    ok, reason = probe_llvm()
    if not ok:
        pytest.skip(f"llvm_ad_rgb unusable here: {reason}")
    module = load_script("benchmarks/pixel_renderer.py")
    previous = mi.variant()
    init_worker(LLVM_VARIANT, 1)
    try:
        module.main(["--scenes", "cornell", "--resolution", "32", "--spp", "8", "--repeats", "1"])
    finally:
        mi.set_variant(previous or SCALAR_VARIANT)
    (row,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| cornell |")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert len(cells) == 9 and all(float(cells[i]) > 0 for i in range(1, 8))
