"""Do the shipped scorers give the same numbers on a GPU as on the CPU? One table, printed and written.

    python benchmarks/scorer_devices.py IMAGES_DIR [--device cuda] [--models unet_fast,fcnn_fast,dual_fast]
                                        [--out reports/scorer_devices]

Every ``*.exr`` under ``IMAGES_DIR`` (a render named ``... - SPP - 1.exr`` takes ``... - SPP - 2.exr`` as its
twin for a two-buffer model; images without one are skipped for it) is scored by each model on the CPU and on
``--device``; per model the table gives the images, the largest difference of the mean scores and of the maps,
and the median time per image on each device (the image handed over as numpy, as ``predict`` and the render
loops do; the first call of each shape is a warm-up and not timed). On a machine without ``--device`` it says so
and exits 2.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.machine import machine_line, sync  # noqa: E402
from nriqa.inference.pretrained import load_pretrained  # noqa: E402
from nriqa.inference.scorer import Scorer, device_problem  # noqa: E402
from nriqa.io.atomic import write_text_atomic  # noqa: E402
from nriqa.io.exr import read_exr  # noqa: E402
from nriqa.io.tables import markdown_table  # noqa: E402


def _twin_path(path: Path) -> Path | None:
    stem = path.stem
    if not stem.endswith(" - 1"):
        return None
    twin = path.with_name(stem[: -len("1")] + "2" + path.suffix)
    return twin if twin.is_file() else None


def _scored(scorer: Scorer, image: np.ndarray, twin: np.ndarray | None, device: str) -> tuple[float, np.ndarray, float]:
    """(score, map, seconds) of one call; the accelerator's queue is waited for inside the timing."""
    t0 = time.perf_counter()
    result = scorer(image, hdr=True, twin=twin)
    sync(device)
    return float(result.score), np.asarray(result.map), time.perf_counter() - t0


def compare(images: list[Path], models: list[str], device: str) -> list[list]:
    rows = []
    for name in models:
        scorers = {d: Scorer(load_pretrained(name), device=d) for d in ("cpu", device)}
        needs_twin = scorers["cpu"].needs_twin
        d_score, d_map, times, n = 0.0, 0.0, {"cpu": [], device: []}, 0
        seen: set[tuple] = set()
        for path in images:
            twin_path = _twin_path(path) if needs_twin else None
            if needs_twin and twin_path is None:
                continue
            image = read_exr(path)
            twin = read_exr(twin_path) if twin_path else None
            out = {}
            for d, scorer in scorers.items():
                if (d, image.shape) not in seen:  # warm-up: kernels are picked per shape
                    _scored(scorer, image, twin, d)
                    seen.add((d, image.shape))
                out[d] = _scored(scorer, image, twin, d)
                times[d].append(out[d][2])
            d_score = max(d_score, abs(out["cpu"][0] - out[device][0]))
            d_map = max(d_map, float(np.abs(out["cpu"][1] - out[device][1]).max()))
            n += 1
        if n == 0:
            rows.append([name, 0, "–", "–", "–", "–"])
            continue
        rows.append(
            [
                name,
                n,
                f"{d_score:.1e}",
                f"{d_map:.1e}",
                f"{statistics.median(times['cpu']) * 1e3:.1f}",
                f"{statistics.median(times[device]) * 1e3:.1f}",
            ]
        )
        print(f"  {name}: {n} images, scores differ by at most {d_score:.1e}", file=sys.stderr)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("images", type=Path, help="a folder of HDR renders (*.exr, searched recursively)")
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--models", default="unet_fast,fcnn_fast,dual_fast")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--out", type=Path, default=Path("reports/scorer_devices"))
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    problem = device_problem(args.device)
    if problem:
        print(f"scorer_devices: {problem}", file=sys.stderr)
        return 2
    images = sorted(args.images.rglob("*.exr"))
    if not images:
        print(f"scorer_devices: no *.exr under {args.images}; give a folder of renders", file=sys.stderr)
        return 2
    rows = compare(images, [m for m in args.models.split(",") if m], args.device)
    where = torch.cuda.get_device_name() if torch.device(args.device).type == "cuda" else args.device
    table = markdown_table(
        rows,
        ["model", "images", "largest score difference", "largest map difference", "ms / image, CPU"]
        + [f"ms / image, {args.device}"],
    )
    text = f"# The shipped scorers on the CPU and on {where}\n\n{machine_line()}; images under {args.images}\n\n{table}"
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "scorer_devices.md", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
