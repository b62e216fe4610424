"""The scorer benchmark's range and render sections run end to end and write their tables (tiny, scalar_rgb)."""

from __future__ import annotations

import pytest
from conftest import load_script

mi = pytest.importorskip("mitsuba")

from nriqa.inference.pretrained import list_pretrained  # noqa: E402
from nriqa.inference.scorer import Scorer  # noqa: E402
from nriqa.render.backend import SCALAR_VARIANT, init_worker  # noqa: E402


def load_benchmark():
    return load_script("benchmarks/scorer.py")


@pytest.mark.usefixtures("one_thread")
def test_render_section_writes_every_method(tmp_path):
    previous = mi.variant()
    init_worker(SCALAR_VARIANT, 1)
    try:
        load_benchmark().main(
            [
                "--out",
                str(tmp_path),
                "--skip",
                "throughput,memory,accuracy",
                "--scenes",
                "cornell",
                "--resolution",
                "32",
                "--budget",
                "0.3",
                "--reference-spp",
                "32",
                "--render-repeats",
                "2",
                "--range-spp",
                "4,8",
                "--stop-targets",
                "0.5",
                "--stop-max-spp",
                "16",
                "--tile",
                "16",
                "--threads",
                "1",
            ]
        )
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
        (row,) = [
            line for line in table.splitlines() if line.startswith("| cornell | 0.5 |") and f"| {method} |" in line
        ]
        assert len(row.strip("|").split("|")) == 9


@pytest.mark.usefixtures("one_thread")
def test_accuracy_section_gives_intervals_paired_differences_and_the_scores(tmp_path):
    import json

    from conftest import make_dataset

    from nriqa.core.correlation import srocc

    data = make_dataset(tmp_path / "data", size=48, scenes=("alpha",), spps=(1, 2, 4, 8, 16, 32, 64, 128), twins=False)
    load_benchmark().main(
        [
            "--out",
            str(tmp_path / "out"),
            "--skip",
            "throughput,memory,range,stop,render",
            "--data",
            str(data),
            "--val-scene",
            "alpha",
            "--threads",
            "1",
        ]
    )
    table = (tmp_path / "out" / "scorer.md").read_text()
    scores = json.loads((tmp_path / "out" / "accuracy_scores.json").read_text())
    assert len(scores["ids"]) == len(scores["true_ssim"]) == 8
    rows = {
        line.split("|")[1].strip(): [c.strip() for c in line.strip("|").split("|")]
        for line in table.splitlines()
        if line.startswith("| shipped:")
    }
    single = {f"shipped:{n}" for n in list_pretrained() if not Scorer.from_pretrained(n).needs_twin}
    assert set(rows) == set(scores["predicted"]) == single and {"shipped:fcnn_fast", "shipped:fcnn"} <= single
    for name, row in rows.items():
        rho = srocc(scores["predicted"][name]["scores"], scores["true_ssim"])
        assert float(row[3]) == pytest.approx(rho, abs=5e-4)
        low, high = (float(v) for v in row[4].split("–"))
        assert low <= float(row[3]) <= high
    # One is the best; the others carry their paired difference to it, with an interval around it.
    (better,) = [name for name, row in rows.items() if row[5] == "(the base)"]
    worse = sorted(name for name in rows if name != better)[0]
    diff = float(rows[worse][5].split()[0])
    low, high = (float(v) for v in rows[worse][5].split("(")[1].rstrip(")").split(" to "))
    assert diff <= 0 and low <= diff <= high
    # --against makes another one the base: the same difference, the other way round.
    load_benchmark().main(
        [
            "--out",
            str(tmp_path / "out2"),
            "--skip",
            "throughput,memory,range,stop,render",
            "--data",
            str(data),
            "--val-scene",
            "alpha",
            "--threads",
            "1",
            "--against",
            worse,
        ]
    )
    table = (tmp_path / "out2" / "scorer.md").read_text()
    row = [
        c.strip()
        for c in next(line for line in table.splitlines() if line.startswith(f"| {better} |")).strip("|").split("|")
    ]
    assert float(row[5].split()[0]) == pytest.approx(-diff, abs=1e-3)
    assert f"| {worse} |" in table and "(the base)" in table
    load_benchmark().main(
        [
            "--out",
            str(tmp_path / "out3"),
            "--skip",
            "throughput,memory,range,stop,render",
            "--data",
            str(data),
            "--val-scene",
            "alpha",
            "--threads",
            "1",
            "--against",
            "nothing.ckpt",
        ]
    )
    assert (
        "--against 'nothing.ckpt' is not among the weights scored here" in (tmp_path / "out3" / "scorer.md").read_text()
    )


def test_accuracy_section_with_a_checkpoint_dir_scores_only_its_checkpoints(tmp_path):
    from conftest import make_dataset

    data = make_dataset(tmp_path / "data", size=32, scenes=("alpha",), spps=(1, 4), twins=False)
    (tmp_path / "ckpts").mkdir()
    load_benchmark().main(
        [
            "--out",
            str(tmp_path / "out"),
            "--skip",
            "throughput,memory,range,stop,render",
            "--data",
            str(data),
            "--val-scene",
            "alpha",
            "--checkpoint-dir",
            str(tmp_path / "ckpts"),
        ]
    )
    table = (tmp_path / "out" / "scorer.md").read_text()
    assert "no weights: no *.ckpt under" in table and "shipped:" not in table


@pytest.mark.usefixtures("one_thread")
def test_throughput_section_times_folded_against_unfolded(tmp_path):
    load_benchmark().main(
        [
            "--out",
            str(tmp_path),
            "--skip",
            "memory,accuracy,range,stop,render",
            "--models",
            "fcnn_fast,unet_fast",
            "--size",
            "64",
            "--repeats",
            "2",
            "--unfolded",
        ]
    )
    table = (tmp_path / "scorer.md").read_text()
    for name in ("fcnn_fast", "unet_fast"):
        row = next(line for line in table.splitlines() if line.startswith(f"| {name} (unfolded"))
        ratio = float(row.split("folded / unfolded ")[1].split(";")[0])
        diff = float(row.split("maps differ by ")[1].split(")")[0])
        assert ratio > 0 and diff < 1e-4


@pytest.mark.usefixtures("one_thread")
def test_throughput_section_times_windows_side_by_side_overlapping_and_the_spread(tmp_path):
    load_benchmark().main(
        ["--out", str(tmp_path), "--skip", "memory,accuracy,range,stop,render", "--models", "unet_fast,fcnn_fast"]
        + ["--size", "128", "--repeats", "1", "--shipped"]
    )
    rows = [line.split("|")[1:-1] for line in (tmp_path / "scorer.md").read_text().splitlines() if "| 128 |" in line]
    kinds = [(r[0].strip(), r[2].strip()) for r in rows]
    assert kinds == [
        ("unet_fast", "-"),
        ("unet_fast", "overlap"),
        ("unet_fast", "spread"),
        ("fcnn_fast", "-"),
        ("fcnn_fast", "spread"),
    ]
    assert all(float(r[4]) > 0 for r in rows)
