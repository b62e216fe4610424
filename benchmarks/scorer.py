"""Scorer benchmark: throughput, peak memory of tiling, accuracy (with weights), render loops.

    python benchmarks/scorer.py --out reports/scorer [--size 512 --patch-size 128 --repeats 3]
                                [--data data/default --val-scene cornell --checkpoint-dir DIR]
                                [--scenes cornell,caustic,door --resolution 128 --budget 2 --render-repeats 3]
                                [--range-spp 16,64,256] [--stop-targets 0.95,0.98 --stop-max-spp 1024]
                                [--skip throughput,memory,accuracy,range,stop,render] [--models fcnn_fast,...]

Sections, each a Markdown table in ``<out>/scorer.md`` (and printed), plots as PNGs beside it:

1. **throughput** -- Mpix/s of :class:`nriqa.inference.scorer.Scorer` (tone map + forward + pooling) for
   every registered model (or ``--models``) on a ``size``-square HDR image, and the patch model at strides 1/4/8/16
   on a ``patch-size`` square (its cost grows with 1/stride^2); a model read in windows (``unet_fast``) side by
   side and with ``overlap`` (blended windows at half-window steps), and single-image map models with ``spread``
   (the eight flips and turns scored too). Time only: untrained weights (``--shipped``:
   the shipped ones; ``--device cuda``: on a GPU, the images already there as tensors). ``--unfolded`` also
   times each map model's network as trained, batch norm not folded
   into its convolutions (:mod:`nriqa.inference.folding`), alternating with the Scorer as it runs.
2. **memory** -- peak resident memory of scoring a 4096x4096 HDR image with ``fcnn_fast``, tiled
   (512) and untiled, each in a fresh subprocess: peak RSS (``resource.getrusage``) and its rise
   over the RSS just before scoring (torch, model and the input already in memory).
3. **accuracy** -- with ``--data`` and weights (the ``*.ckpt`` under ``--checkpoint-dir``, trained
   with ``--val-scene`` held out; without it the shipped weights, which learnt every scene): the
   held-out accuracy of :mod:`nriqa.eval.accuracy` on the test images of ``--val-scene``: image
   SROCC with its 95 % bootstrap interval, each run's paired difference to ``--against`` (a name in
   the table), else to the best run of its quantity, pixel PCC of the map and Mpix/s; the pooled
   scores per image go to ``accuracy_scores.json``, the plot to ``frontier.png``. Without weights it
   prints "no weights".
4. **range**, 5. **stop**, 6. **render** -- the render loops driven by the scorer
   (``benchmarks/render_loops.py`` says what each measures).

Run with ``--threads 1`` on a small shared CPU, so that torch does not compete with Mitsuba's
threads and other processes.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.machine import machine_line, sync  # noqa: E402
from benchmarks.render_loops import early_stop, render, scorer_range  # noqa: E402
from nriqa.eval.accuracy import (  # noqa: E402  # noqa: E402
    AccuracyError,
    choose_bases,
    load_heldout,
    named_runs,
    paired_difference,
    score_run,
    write_scores,
)
from nriqa.eval.dataset import EvaluationError  # noqa: E402
from nriqa.eval.plots import plot_frontier  # noqa: E402
from nriqa.inference.pretrained import load_pretrained  # noqa: E402
from nriqa.inference.scorer import Scorer  # noqa: E402
from nriqa.io.atomic import write_text_atomic  # noqa: E402
from nriqa.io.exr import ImageReadError  # noqa: E402
from nriqa.io.tables import markdown_table  # noqa: E402
from nriqa.models import create_model, list_models  # noqa: E402

ACCURACY_COLUMNS = [
    "weights",
    "predicts",
    "images",
    "image SROCC",
    "95 % interval",
    "to the base (95 %)",
    "pixel PCC (SSIM map)",
    "Mpix/s",
]


def timed(fn, repeats: int, device: str = "cpu") -> float:
    """Median seconds of ``fn()`` after one warm-up call; on an accelerator, waiting for its queue each time."""
    fn()  # warm-up: oneDNN (cuDNN) picks kernels per shape
    sync(device)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        sync(device)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def throughput(args) -> str:
    rng = np.random.default_rng(0)
    rows = []
    for name in args.models.split(",") if args.models else list_models():
        torch.manual_seed(0)
        net = load_pretrained(name) if args.shipped else create_model(name)
        scorer = Scorer(net, stride=8, device=args.device)
        size = args.patch_size if scorer.output == "patch" else args.size
        img = (rng.random((size, size, 3)) * 4).astype(np.float32)
        twin = (rng.random((size, size, 3)) * 4).astype(np.float32) if scorer.needs_twin else None
        if args.device != "cpu":  # images already on the device (a GPU renderer's buffers): no copies timed
            img = torch.from_numpy(img).permute(2, 0, 1).to(args.device)
            twin = None if twin is None else torch.from_numpy(twin).permute(2, 0, 1).to(args.device)
        if args.unfolded and scorer.output == "map":
            rows.append(_against_unfolded(name, scorer, net, img, twin, args.repeats))
            continue
        # the patch model at several strides; a model read in windows side by side and overlapping (blended); a
        # single-image map model with its spread over the eight flips and turns (nriqa.inference.spread)
        strides = (1, 4, 8, 16) if scorer.output == "patch" else ("-", "overlap") if scorer.window else ("-",)
        if scorer.output == "map" and not (scorer.needs_twin or scorer.needs_albedo):
            strides = (*strides, "spread")
        for stride in strides:
            if isinstance(stride, int):
                scorer.stride = stride
            scorer.overlap = stride == "overlap"
            scorer.spread = stride == "spread"
            t = timed(
                lambda s=scorer, x=img, y=twin: s(x, hdr=True, twin=y), args.repeats if stride != 1 else 1, args.device
            )
            rows.append([name, size, stride, f"{t * 1e3:.1f}", f"{size * size / t / 1e6:.3g}"])
            print(f"  throughput {name} stride={stride}: {t:.3f} s", file=sys.stderr)
    return markdown_table(rows, ["model", "side (px)", "stride / windows", "ms / image", "Mpix/s"])


def _against_unfolded(name: str, scorer: Scorer, net: torch.nn.Module, img, twin, repeats: int) -> list:
    """One row: the Scorer as shipped (batch norm folded) and the same Scorer running ``net`` as trained.

    The two alternate within each repeat, so load changes hit both; the ratio is the median of the
    per-repeat ratios (folded / unfolded), and the largest difference of their maps is reported too.
    """
    unfolded = copy.copy(scorer)
    unfolded.net = net.eval()
    score = [lambda s=s: s(img, hdr=True, twin=twin) for s in (scorer, unfolded)]
    diff = float(np.abs(np.asarray(score[0]().map) - np.asarray(score[1]().map)).max())
    times = [[], []]
    for _ in range(repeats):
        for k in (0, 1):
            t0 = time.perf_counter()
            score[k]()
            times[k].append(time.perf_counter() - t0)
    ratio = statistics.median(a / b for a, b in zip(*times))
    folded_s, unfolded_s = (statistics.median(t) for t in times)
    side = img.shape[0]
    print(f"  throughput {name}: folded {folded_s:.3f} s, unfolded {unfolded_s:.3f} s", file=sys.stderr)
    return [
        f"{name} (unfolded: {unfolded_s * 1e3:.1f} ms, {side * side / unfolded_s / 1e6:.3g} Mpix/s; "
        f"folded / unfolded {ratio:.3f}; maps differ by {diff:.1e})",
        side,
        "-",
        f"{folded_s * 1e3:.1f}",
        f"{side * side / folded_s / 1e6:.3g}",
    ]


_MEMORY_CHILD = r"""
import os, resource, sys, time, numpy as np, torch
from nriqa.models import create_model
from nriqa.inference.scorer import Scorer
def rss_mib():  # current resident set, not the peak
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
name, side, tile = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
torch.manual_seed(0)
scorer = Scorer(create_model(name), tile=tile)
img = np.empty((side, side, 3), np.float32)  # filled in place: no temporary copies to inflate the peak
np.random.default_rng(0).random(out=img, dtype=np.float32)
img *= 4
scorer(img[:64, :64], hdr=True)
before = rss_mib()
t0 = time.perf_counter()
res = scorer(img, hdr=True)
seconds = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(before, peak, seconds, res.score)
"""


def memory(args) -> str:
    rows = []
    for name, tile in [("fcnn_fast", 512), ("fcnn_fast", 0), *([("fcnn", 512)] if args.memory_fcnn else [])]:
        proc = subprocess.run(
            [sys.executable, "-c", _MEMORY_CHILD, name, str(args.memory_side), str(tile)],
            cwd=REPO,
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0:
            rows.append([name, tile or "untiled", "failed", (proc.stderr.strip().splitlines() or ["?"])[-1], "", ""])
            continue
        before, after, seconds, score = map(float, proc.stdout.split())
        added = after - before
        rows.append([name, tile or "untiled", f"{after:.0f}", f"{added:.0f}", f"{seconds:.1f}", f"{score:.4f}"])
        print(
            f"  memory {name} tile={tile}: peak {after:.0f} MiB ({added:.0f} for scoring), {seconds:.1f} s",
            file=sys.stderr,
        )
    side = args.memory_side
    note = (
        f"{side}x{side} float32 HDR input ({side * side * 12 / 2**20:.0f} MiB); peak RSS of the process, and the "
        "rise over the RSS just before scoring (input, model and torch already in memory).\n\n"
    )
    columns = ["model", "tile", "peak RSS (MiB)", "added by scoring (MiB)", "seconds", "score"]
    return note + markdown_table(rows, columns)


def find_scorers(args) -> dict[str, Scorer]:
    """The single-image scorers of the accuracy section (two-buffer ones need twins it does not load)."""
    from nriqa.inference.pretrained import list_pretrained

    if not args.checkpoint_dir:
        found = {f"shipped:{n}": Scorer.from_pretrained(n) for n in list_pretrained()}
    else:
        # Only the given checkpoints: the shipped weights learnt every scene, the held-out one too, and
        # would not be compared on equal terms (nor be "the best" the others are measured against).
        found = {
            str(ckpt.relative_to(args.checkpoint_dir)): Scorer.from_checkpoint(ckpt)
            for ckpt in sorted(Path(args.checkpoint_dir).rglob("*.ckpt"))
        }
    return {name: scorer for name, scorer in found.items() if not scorer.needs_twin}


def accuracy(args) -> str:
    """Held-out accuracy of the weights (:mod:`nriqa.eval.accuracy`) as a table, with the scores and a plot."""
    if not args.data:
        return "no data: pass --data DIR --val-scene NAME"
    scorers = find_scorers(args)
    if not scorers:
        return (
            f"no weights: no *.ckpt under {args.checkpoint_dir}"
            if args.checkpoint_dir
            else "no weights: no shipped weights"
        )
    try:
        runs = named_runs(scorers, args.patch_strides, args.against)
        held = load_heldout(args.data, args.val_scene)
    except (AccuracyError, EvaluationError, ImageReadError) as exc:
        return str(exc)
    results = {name: score_run(held, scorer, stride) for name, (scorer, stride) in runs.items()}
    bases = choose_bases(results, args.against)
    rows = []
    for name, r in results.items():
        base = bases[r.quantity]
        paired = "(the base)"
        if base != name:
            diff, low, high = paired_difference(held, results, name, base)
            paired = f"{diff:+.3f} ({low:+.3f} to {high:+.3f})"
        pixel = f"{r.pixel_pcc:.3f}" if np.isfinite(r.pixel_pcc) else "-"
        rows.append(
            [
                name,
                r.quantity,
                len(held.ids),
                f"{r.rho:.3f}",
                f"{r.low:.3f}–{r.high:.3f}",
                paired,
                pixel,
                f"{r.mpix:.3g}",
            ]
        )
    scores_file = args.out / "accuracy_scores.json"
    write_scores(scores_file, args.data, args.val_scene, held, results)
    plot_frontier(
        args.out / "frontier.png", [(n, r.mpix, r.rho, r.low, r.high) for n, r in results.items()], args.val_scene
    )
    return (
        f"scene {args.val_scene}, {len(held.ids)} test images of {args.data}; 95 % intervals: percentile bootstrap "
        "over the images (2000 resamples); 'to the base': the paired difference in image SROCC to "
        f"{args.against or 'the best predictor of the same quantity'}, the same images resampled for both. "
        "Mpix/s: scoring these images (tone-mapped, as LDR) one by one in this run. Pixel PCC: the evaluation's "
        f"fixed pixels of each map. Pooled scores per image: {scores_file.name}. Plot: frontier.png\n\n"
    ) + markdown_table(rows, ACCURACY_COLUMNS)


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("reports/scorer"))
    ap.add_argument(
        "--skip", default="", help="comma-separated sections to skip: throughput,memory,accuracy,range,stop,render"
    )
    ap.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    ap.add_argument(
        "--device", default="cpu", help="throughput: where the Scorer runs (cuda: images already there, as tensors)"
    )
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--models", default="", help="throughput: comma-separated registered models (default all)")
    ap.add_argument(
        "--shipped",
        action="store_true",
        help="throughput: time the shipped weights of these names as users get them (e.g. unet_fast's 64x64 "
        "windows), not untrained registered models",
    )
    ap.add_argument(
        "--unfolded",
        action="store_true",
        help="throughput: also time each map model with its batch norm unfolded (as trained), alternating",
    )
    ap.add_argument("--patch-size", type=int, default=128)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--memory-side", type=int, default=4096)
    ap.add_argument("--memory-fcnn", action="store_true", help="also measure fcnn (slow: ~2M multiply-adds per pixel)")
    ap.add_argument("--data", type=Path)
    ap.add_argument("--val-scene", default="cornell")
    ap.add_argument("--checkpoint-dir", type=Path)
    ap.add_argument(
        "--against",
        help="accuracy: the weights (as named in the table) the others are paired against; default: the best",
    )
    ap.add_argument(
        "--patch-strides",
        type=lambda v: [int(x) for x in v.split(",")],
        default=[16, 8],
        help="accuracy: strides for patch-model weights (the cost grows with 1/stride^2)",
    )
    ap.add_argument("--scenes", default="cornell,caustic,door")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--budget", type=float, default=2.0, help="seconds per render loop")
    ap.add_argument("--render-repeats", type=int, default=3, help="seeds per render loop")
    ap.add_argument(
        "--range-spp",
        type=lambda v: [int(x) for x in v.split(",")],
        default=[16, 64, 256],
        help="range section: mean spp at which the scorer and adaptive sampling are measured",
    )
    ap.add_argument(
        "--stop-targets",
        type=lambda v: [float(x) for x in v.split(",")],
        default=[0.95, 0.98],
        help="stop section: predicted SSIM targets of early stopping",
    )
    ap.add_argument("--stop-max-spp", type=int, default=1024, help="stop section: most spp of a run")
    ap.add_argument("--max-overhead", type=float, default=0.05, help="scorer time allowed, as a share of render time")
    ap.add_argument("--uniform-share", type=float, default=0.5, help="adaptive: share of each step spread evenly")
    ap.add_argument("--spp-per-step", type=int, default=4)
    ap.add_argument("--target", type=float, default=0.9, help="predicted SSIM at which early stopping stops")
    ap.add_argument("--tile", type=int, default=16, help="also run adaptive per tile of this side (0: skip)")
    ap.add_argument("--fraction", type=float, default=0.25)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--render-checkpoint", type=Path)
    return ap


def main(argv: list[str] | None = None) -> None:
    args = _parser().parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    args.out.mkdir(parents=True, exist_ok=True)
    skip = set(filter(None, args.skip.split(",")))
    parts = [f"# Scorer benchmark\n\n{machine_line()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n"]
    sections = {
        "throughput": lambda: throughput(args),
        "memory": lambda: memory(args),
        "accuracy": lambda: accuracy(args),
        "range": lambda: scorer_range(args),
        "stop": lambda: early_stop(args),
        "render": lambda: render(args, args.out),
    }
    for name, fn in sections.items():
        if name in skip:
            continue
        print(f"{name} ...", file=sys.stderr)
        text = f"## {name}\n\n{fn().rstrip()}\n"
        print(text, flush=True)
        parts.append(text)
    write_text_atomic(args.out / "scorer.md", "\n".join(parts))
    print(f"wrote {args.out / 'scorer.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
