"""Does the score's calibrated interval hold on adaptively sampled renders? Rows of loops on a dataset's scenes.

    python benchmarks/adaptive_interval.py --data data/v2_x64 --out reports/adaptive_interval
        [--scorer unet_fast] [--twin-scorer dual_fast] [--max-spp 1024] [--seeds 2] [--scenes cornell,...]
        [--loops uniform]

The shipped intervals (``ScoreResult.low``/``high``) were calibrated on uniformly sampled renders; ``render_adaptive``
evens the noise out by placing samples where the map expects error, and ``sure=True`` stops on the low end there
too. For every scene variant of ``--data`` (a dataset with its references, e.g. a fresh ``nriqa-data`` set none of
the scorers learnt or was calibrated on), rendered by the scene's reference algorithm at the dataset's resolution,
this runs uniform progressive rendering (``render_until``) and per-pixel adaptive sampling (``render_adaptive``) to
``--max-spp``, each scored at every step on the image itself (``map_spp=None``), and compares every row's score and
low end with the true mean SSIM against the dataset's reference: the low end's coverage (share of rows with true >=
low; 0.95 by design), the score's bias and mean absolute error, overall and per family, for each scorer (with
``--twin-scorer``, the two-buffer scorer on the loop's halves too). No clock: the samples are the measure.

Writes ``<out>/adaptive_interval.md`` (printed), ``rows.csv`` (one row per loop step) and ``summary.csv``.
Needs ``llvm_ad_rgb`` (per-pixel sampling).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from nriqa.inference import DEFAULT_WEIGHTS  # noqa: E402
from nriqa.io.atomic import write_text_atomic  # noqa: E402
from nriqa.io.tables import markdown_table, write_csv  # noqa: E402

LOOPS = ("uniform", "adaptive")
SEED_SPACING = 10_000  # a loop's k-th render call uses seed + k: runs lie this far apart
BANDS = ((0.0, 0.9), (0.9, 0.95), (0.95, 1.0))  # true SSIM bands of the summary (sure stops happen high)
SUMMARY = ("rows", "true >= low", "bias", "MAE", "low reach")  # the measures of summarise()


def fail(message: str) -> None:
    print(f"adaptive_interval: {message}", file=sys.stderr)
    raise SystemExit(2)


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="a dataset root (manifest.json, references)")
    ap.add_argument("--out", type=Path, default=Path("reports/adaptive_interval"))
    ap.add_argument("--scorer", default=DEFAULT_WEIGHTS, help="single-image scorer: shipped name or .pt/.ckpt")
    ap.add_argument("--twin-scorer", help="a two-buffer scorer (rated on the loop's halves), e.g. dual_fast")
    ap.add_argument("--scenes", help="comma-separated families (default: every family of --data)")
    ap.add_argument("--max-spp", type=int, default=1024)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--spp-per-step", type=int, default=4)
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument(
        "--loops", default=",".join(LOOPS), help=f"comma-separated loop kinds to run (default: {','.join(LOOPS)})"
    )
    args = ap.parse_args(argv)
    args.loops = [k.strip() for k in args.loops.split(",") if k.strip()]
    unknown = sorted(set(args.loops) - set(LOOPS)) or ([] if args.loops else ["(none)"])
    if unknown:
        fail(f"--loops {', '.join(unknown)}: not a loop kind; give some of {', '.join(LOOPS)}")
    if not (args.data / "manifest.json").is_file():
        fail(f"{args.data}: no manifest.json; give a dataset rendered by nriqa-data (it keeps its references)")
    if args.seeds < 1 or args.max_spp < 2 * args.spp_per_step or args.spp_per_step < 1:
        fail("--seeds must be >= 1, --spp-per-step >= 1 and --max-spp at least two steps")
    return args


def load_scorer(option: str, spec: str, twin: bool):
    """A Scorer with a calibrated interval; anything else is one line."""
    from nriqa.inference.scorer import Scorer

    path = Path(spec)
    try:
        scorer = Scorer.from_checkpoint(path) if path.is_file() else Scorer.from_pretrained(spec)
    except (ValueError, OSError, KeyError) as exc:
        fail(f"{option} {spec}: {exc}")
    if bool(getattr(scorer, "needs_twin", False)) != twin:
        other = "--scorer" if twin else "--twin-scorer"
        fail(f"{option} {spec}: {'no' if twin else 'a'} two-buffer scorer; pass it as {other}")
    if scorer.interval is None:
        fail(f"{option} {spec}: no calibrated interval (shipped weights carry one on their card)")
    return scorer


def dataset_scenes(root: Path, only: list[str] | None) -> list[tuple[str, int, dict, np.ndarray]]:
    """``(family, variant, scene dict, reference)`` of every scene variant of the dataset at ``root``: its plan
    rebuilt from the manifest's configuration, the scene's reference algorithm, the reference image it holds."""
    from data_gen.plan import ImageTask, plan_dataset
    from data_gen.render import scene_dict
    from data_gen.scenes import get_scene
    from nriqa.io.exr import read_exr
    from nriqa.io.manifest import read_manifest

    _, meta = read_manifest(root)
    cfg = meta.get("config", {})
    try:
        jobs = plan_dataset(
            list(cfg["scenes"]),
            int(cfg["variants"]),
            int(cfg.get("seed", 0)),
            tuple(cfg["resolution"]) if cfg.get("resolution") else None,
            cfg.get("ladder_top"),
            int(cfg.get("reference_factor", 16)),
            cfg.get("algorithms"),
            int(cfg.get("first_variant", 0)),
        )
    except (KeyError, TypeError) as exc:
        fail(f"{root}/manifest.json: its meta.config cannot rebuild the plan ({exc!r}); render it with nriqa-data")
    unknown = sorted(set(only or ()) - {j.scene for j in jobs})
    if unknown:
        fail(f"--scenes {', '.join(unknown)}: not in {root}")
    out, seen = [], set()
    for job in jobs:
        if job.algorithm != get_scene(job.scene).reference_algorithm or (only and job.scene not in only):
            continue
        if (job.scene, job.variant) in seen:  # the reference and the ladder may be jobs of their own
            continue
        seen.add((job.scene, job.variant))
        ref = job.tasks[0].reference  # the variant's reference, whichever job renders it
        if not (root / ref).is_file():
            fail(f"{root / ref}: missing; finish the dataset first (nriqa-data resumes)")
        scene = scene_dict(job, ImageTask("loop", "test", 4, 1, "loop.exr", ref))
        out.append((job.scene, job.variant, scene, read_exr(root / ref)[..., :3]))
    return out


def loop_rows(scene, reference, scorer, loop: str, seed: int, args) -> list[dict]:
    """Every step of one loop to ``--max-spp``, scored on the image (or its halves) each time: spp, score, low, true."""
    from nriqa.render import render_adaptive, render_until

    common = dict(reference=reference, max_overhead=None, map_spp=None, seed=seed, warmup=False)
    if loop == "uniform":
        _, log = render_until(scene, scorer, None, 1e9, args.spp_per_step, max_spp=args.max_spp, **common)
    else:
        _, log = render_adaptive(
            scene, scorer, args.max_spp, initial_spp=args.spp_per_step, spp_per_step=args.spp_per_step, **common
        )
    return [
        {"spp": r["spp"], "score": r["predicted"], "low": r["low"], "true": r["true"]}
        for r in log
        if r["scored"] and r["low"] is not None
    ]


def summarise(rows: list[dict], keys: tuple[str, ...]) -> list[dict]:
    """Per group of ``keys``: rows, the low end's coverage (true >= low), the score's bias and MAE."""
    out = []
    for group in dict.fromkeys(tuple(r[k] for k in keys) for r in rows):
        mine = [r for r in rows if tuple(r[k] for k in keys) == group]
        true, score, low = (np.array([r[k] for r in mine]) for k in ("true", "score", "low"))
        out.append(
            {
                **dict(zip(keys, group, strict=True)),
                "rows": len(mine),
                "true >= low": float(np.mean(true >= low)),
                "bias": float(np.mean(score - true)),
                "MAE": float(np.mean(np.abs(score - true))),
                "low reach": float(np.mean(score - low)),
            }
        )
    return out


def band(true: float) -> str:
    lo, hi = next(b for b in BANDS if true < b[1] or b[1] == 1.0)
    return f"[{lo:g}, {hi:g})" if hi < 1.0 else f"[{lo:g}, 1]"


def main(argv: list[str] | None = None) -> None:
    args = parse(argv)
    import torch

    from nriqa.render import ensure_variant, is_jit_variant

    torch.set_num_threads(args.threads)
    scorers = {"single": load_scorer("--scorer", args.scorer, twin=False)}
    if args.twin_scorer:
        scorers["two-buffer"] = load_scorer("--twin-scorer", args.twin_scorer, twin=True)
    variant = ensure_variant("auto")
    if not is_jit_variant():
        fail(f"per-pixel adaptive sampling needs llvm_ad_rgb; this machine runs {variant} (set DRJIT_LIBLLVM_PATH)")
    t0 = time.time()
    scenes = dataset_scenes(args.data, args.scenes.split(",") if args.scenes else None)
    rows = []
    for family, v, scene, reference in scenes:
        for kind, scorer in scorers.items():
            for loop in args.loops:
                for k in range(args.seeds):
                    for r in loop_rows(scene, reference, scorer, loop, SEED_SPACING * (k + 1), args):
                        rows.append({"scorer": kind, "loop": loop, "family": family, "variant": v, "seed": k, **r})
        print(f"  {family} v{v}: done", file=sys.stderr)
    for r in rows:
        r["band"] = band(r["true"])
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(args.out / "rows.csv", rows, list(rows[0]))
    overall = [{**r, "band": "all"} for r in summarise(rows, ("scorer", "loop"))]
    bands = sorted(summarise(rows, ("scorer", "loop", "band")), key=lambda r: (r["scorer"], r["band"], r["loop"]))
    families = sorted(summarise(rows, ("scorer", "family", "loop")), key=lambda r: (r["scorer"], r["family"]))
    write_csv(args.out / "summary.csv", overall + bands, ["scorer", "loop", "band", *SUMMARY])
    names = f"single: {args.scorer}" + (
        f"; two-buffer: {args.twin_scorer} (on the loop's halves)" if args.twin_scorer else ""
    )
    text = "\n".join(
        [
            "# The calibrated interval on uniformly and adaptively sampled renders\n",
            f"`python benchmarks/adaptive_interval.py {' '.join(sys.argv[1:] if argv is None else argv)}`\n",
            f"{len(scenes)} scene variants of {args.data} (reference algorithm, its references), scorers {names}; "
            f"{args.seeds} seed(s) per loop, steps of {args.spp_per_step} spp growing to 25 % of those done, up to "
            f"{args.max_spp} spp, every step scored on the image itself; Mitsuba {variant}; {os.cpu_count()} cores; "
            f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(t0))}, {(time.time() - t0) / 60:.0f} min. "
            "'true >= low': share of rows whose true mean SSIM is at or above the interval's low end (0.95 by "
            "design); 'low reach': the mean of score - low.\n",
            markdown_table(overall, ["scorer", "loop", *SUMMARY]),
            "By the true SSIM of the row:\n",
            markdown_table(bands, ["scorer", "band", "loop", *SUMMARY]),
            "By family:\n",
            markdown_table(families, ["scorer", "family", "loop", *SUMMARY]),
        ]
    )
    write_text_atomic(args.out / "adaptive_interval.md", text)
    print(text)


if __name__ == "__main__":
    main()
