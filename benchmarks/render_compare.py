"""Render loops against the variance-based peer (Cycles' half-buffer adaptive sampling), at equal time.

    python benchmarks/render_compare.py --out reports/render_compare [--budget 1 --seeds 5 --stop-seeds 3]
        [--scenes caustic,...,cbox_glass] [--scene-dir ../shared/external/scenes]
        [--scorer NAME|CKPT] [--overlap] [--twin-scorer NAME|CKPT] [--map-spp 64|none] [--sure]
        [--targets 0.9,0.95,0.98 --stop-max-spp 512 --stop-margins 0,0.005,0.01,0.015]
        [--stop-methods peer,learned,two-buffer,sure,sure-twin,adaptive-sure,adaptive-sure-twin]
        [--skip equal_time,stop,half_cost] [--quick]

Scenes: the eight data_gen families (``loop_scene``; the training scenes), the families of data_gen's ``heldout``
preset (``loop_scene``; no shipped scorer learnt them, nothing is tuned on them) and the three Cornell boxes of
``--scene-dir`` (``cbox/*.xml`` loaded with ``mi.load_file(path, res=...)``, max depth 8 / 12 / 12). References:
for the boxes ``--renders-dir``'s 16384-spp ``reference.exr`` where its size matches, else ``--reference-spp``
renders (cached under ``<out>/references``). Sections, written to ``<out>/render_compare.md`` (+ CSVs, a PNG,
``runs.json``) and printed:

1. **equal_time** -- ``uniform`` (``mi.render``), ``uniform (per pixel)``, ``peer`` (``render_peer``, its
   threshold tuned at this budget on the families), ``adaptive`` (``--scorer``, default the shipped
   ``unet_fast``), ``adaptive (overlap)`` (``--overlap``: the same map read in blended, overlapping windows),
   ``adaptive (two-buffer)`` (``--twin-scorer``) and ``oracle map``, each ``--budget`` seconds,
   methods interleaved per seed: error ratio to uniform and equal-quality speed-up (:mod:`nriqa.render.compare`).
2. **stop** -- per target SSIM, no clock: the true SSIM and samples where ``render_until`` with the scorer
   (``learned``, ``two-buffer``; at target + a margin of ``--stop-margins`` tuned on the families), with
   ``--sure`` the scorers stopping on their calibrated interval's low end (``sure (low end)``, nothing tuned),
   and ``render_peer`` (threshold per target tuned on the families) stop; ``--stop-methods`` picks among these
   and the same sure stop in ``render_adaptive`` (``adaptive-sure``, ``adaptive-sure-twin``: samples placed by
   the scorer's map). ``--skip equal_time``: this alone.
3. **half_cost** -- a ``PixelRenderer`` call, the same with the even sums, two calls of half the samples.

The guide: ``docs/render_compare.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from render_compare_stop import (  # noqa: E402
    ADAPTIVE_SURE,
    ADAPTIVE_SURE_TWIN,
    FAMILIES,
    STOP_GRID,
    STOP_MARGINS,
    STOP_METHODS,
    SURE,
    SURE_TWIN,
    half_cost,
    stop_section,
)

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from nriqa.inference import DEFAULT_WEIGHTS  # noqa: E402
from nriqa.io.atomic import save_figure, write_text_atomic  # noqa: E402
from nriqa.io.tables import markdown_table, write_csv  # noqa: E402

CBOX = {
    "cbox_official": ("cbox-rgb.xml", 8),
    "cbox_indirect": ("cbox-indirect.xml", 12),
    "cbox_glass": ("cbox-glass.xml", 12),
}
# A loop's k-th render call uses seed + k: runs' seeds lie this far apart so that no two runs share samples.
SEED_SPACING = 10_000
PEER_GRID = (0.2, 0.1, 0.05, 0.025, 0.0125)  # equal time: thresholds tried on the families
DEFAULT_STOP_METHODS = ("peer", "learned", "two-buffer")  # two-buffer: only with --twin-scorer
LOOP_DEFAULT = "loop"  # --map-spp left out: render_until's own default, read from its signature in main


def fail(message: str) -> None:
    print(f"render_compare: {message}", file=sys.stderr)
    raise SystemExit(2)


def load_scenes(args) -> dict[str, tuple[object, np.ndarray, str]]:
    """Each scene (a dict or a loaded scene), its reference and where the reference came from."""
    import mitsuba as mi

    from data_gen.render import loop_scene
    from nriqa.io.exr import read_exr, write_exr
    from nriqa.render.film import render_spp

    out = {}
    for name in args.scenes:
        if name in CBOX:
            path = args.scene_dir / "cbox" / CBOX[name][0]
            if not path.is_file():
                fail(f"{path} not found: pass --scene-dir DIR (with cbox/) or leave {name} out of --scenes")
            scene = mi.load_file(str(path), res=args.resolution, max_depth=CBOX[name][1], spp=args.spp_per_step)
        else:
            scene = loop_scene(name, (args.resolution, args.resolution), spp=args.spp_per_step)
        shared = args.renders_dir / name / "reference.exr"
        if name in CBOX and shared.is_file() and read_exr(shared).shape[:2] == (args.resolution,) * 2:
            out[name] = (scene, read_exr(shared)[..., :3], f"{shared} (16384 spp)")
            continue
        cache = args.out / "references" / f"{name}_{args.resolution}_{args.reference_spp}.exr"
        if not cache.is_file():
            loaded = mi.load_dict(scene) if isinstance(scene, dict) else scene
            write_exr(cache, render_spp(loaded, args.reference_spp, seed=987654))
        out[name] = (scene, read_exr(cache)[..., :3], f"{args.reference_spp} spp, seed 987654")
    return out


def map_spp_option(value: str) -> float | str | None:
    """``--map-spp``: a number, ``none`` (always the image) or ``loop`` (argparse passes the default through)."""
    if value == "none":
        return None
    return value if value == LOOP_DEFAULT else float(value)


def load_scorer(option: str, spec: str):
    """The Scorer of a shipped name or a checkpoint path; a bad one is one line."""
    from nriqa.inference.scorer import Scorer

    path = Path(spec)
    try:
        return Scorer.from_checkpoint(path) if path.is_file() else Scorer.from_pretrained(spec)
    except (ValueError, OSError, KeyError) as exc:
        fail(f"{option} {spec}: {exc}")


def load_scorers(args) -> dict[str, object]:
    """``adaptive``: ``--scorer`` (the shipped default); ``adaptive (overlap)``: the same read in blended
    windows (``--overlap``); ``adaptive (two-buffer)``: ``--twin-scorer``."""
    from nriqa.eval.predictors import blended

    single = load_scorer("--scorer", args.scorer)
    if getattr(single, "needs_twin", False):
        fail(f"--scorer {args.scorer} needs a twin: pass it as --twin-scorer")
    sure = {STOP_METHODS[k][1]: k for k in args.stop_methods if "sure" in k}  # scorer key -> a sure method
    if "adaptive" in sure and getattr(single, "interval", None) is None:
        fail(f"{sure['adaptive']}: --scorer {args.scorer} has no calibrated interval (shipped weights carry one)")
    scorers = {"adaptive": single}
    if args.overlap:
        if not single.window:
            fail(f"--overlap: --scorer {args.scorer} is not read in windows")
        scorers["adaptive (overlap)"] = blended(single)  # the same network, not loaded again
    if args.twin_scorer:
        twin = load_scorer("--twin-scorer", args.twin_scorer)
        if not getattr(twin, "needs_twin", False):
            fail(f"--twin-scorer {args.twin_scorer} is no two-buffer scorer (needs_twin is false)")
        if "adaptive (two-buffer)" in sure and getattr(twin, "interval", None) is None:
            fail(f"{sure['adaptive (two-buffer)']}: --twin-scorer {args.twin_scorer} has no calibrated interval")
        scorers["adaptive (two-buffer)"] = twin
    return scorers


def methods(scene, reference, scorers, args, threshold: float) -> dict:
    """The equal-time methods of one scene: name -> ``fn(seed) -> (image, log)``."""
    from nriqa.render import ReferenceScorer, render_adaptive, render_peer, render_until

    common = {
        "time_budget_s": args.budget,
        "reference": reference,
        "initial_spp": args.spp_per_step,
        "spp_per_step": args.spp_per_step,
    }
    scored = {**scorers, "oracle map": ReferenceScorer(reference)}
    out = {
        "uniform": lambda s: render_until(scene, None, None, args.budget, args.spp_per_step, reference, seed=s),
        "uniform (per pixel)": lambda s: render_adaptive(scene, None, seed=s, **common),
        "peer": lambda s: render_peer(scene, threshold, stop_fraction=None, min_spp=args.min_spp, seed=s, **common),
    }
    for name, scorer in scored.items():
        out[name] = lambda s, by=scorer: render_adaptive(scene, by, seed=s, max_overhead=args.max_overhead, **common)
    return out


def tune_equal_time(scenes, args) -> tuple[float, list[dict]]:
    """The peer's threshold at equal time: the one of ``--peer-grid`` with the least geometric-mean error
    ratio to uniform over the families, on tuning seeds (not the report's)."""
    from nriqa.render import render_peer, render_until

    logs = {t: [] for t in args.peer_grid}
    for name in [n for n in scenes if n in FAMILIES]:
        scene, reference, _ = scenes[name]
        for seed in args.tuning_seeds:
            uniform = render_until(scene, None, None, args.budget, args.spp_per_step, reference, seed=seed)[1]
            for t in args.peer_grid:
                log = render_peer(
                    scene,
                    t,
                    args.budget,
                    stop_fraction=None,
                    min_spp=args.min_spp,
                    initial_spp=args.spp_per_step,
                    spp_per_step=args.spp_per_step,
                    reference=reference,
                    seed=seed,
                )[1]
                logs[t].append(np.log((1 - log[-1]["true"]) / (1 - uniform[-1]["true"])))
    rows = [{"threshold": t, "error ratio (geometric mean)": float(np.exp(np.mean(v)))} for t, v in logs.items() if v]
    if not rows:
        return args.peer_grid[0], []
    return min(rows, key=lambda r: r["error ratio (geometric mean)"])["threshold"], rows


def run_equal_time(scenes, scorers, args, threshold: float) -> tuple[list[dict], dict]:
    """Every method on every scene and seed (methods interleaved per seed), and uniform's curve per scene."""
    records, curves = [], {}
    for name, (scene, reference, _) in scenes.items():
        fns = methods(scene, reference, scorers, args, threshold)
        for seed in args.seeds:  # interleaved: a change in machine load hits every method alike
            for method, fn in fns.items():
                end = fn(seed)[1][-1]
                records.append(
                    {
                        "scene": name,
                        "method": method,
                        "seed": seed,
                        "true": end["true"],
                        "spp": end["spp"],
                        "seconds": end["seconds"],
                        "score_seconds": end["score_seconds"],
                        "stop": end["stop"],
                    }
                )
                print(f"  {name} {method} {seed}: SSIM {end['true']:.4f}, {end['spp']:.0f} spp", file=sys.stderr)
        reached = max(r["spp"] for r in records if r["scene"] == name and r["method"] == "uniform")
        curves[name] = curve(scene, reference, max(3 * reached, args.stop_max_spp), args)
    return records, curves


def curve(scene, reference, max_spp: float, args):
    """Uniform rendering's error-vs-spp curve of a scene up to ``max_spp`` (``--curve-seeds`` seeds of its own)."""
    from nriqa.render.compare import uniform_curve

    seeds = [SEED_SPACING * (500 + k) for k in range(args.curve_seeds)]
    return uniform_curve(scene, reference, max_spp, seeds, args.spp_per_step)


def plot(et_rows, stop_rows, args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from nriqa.render.compare import WINDOW

    fig, axes = plt.subplots(1, 2, figsize=(14, 4.5))
    scenes = list(dict.fromkeys(r["scene"] for r in et_rows))
    shown = [m for m in dict.fromkeys(r["method"] for r in et_rows) if m != "uniform"]
    width = 0.8 / max(len(shown), 1)
    for k, method in enumerate(shown):
        ratio = {r["scene"]: r["error ratio"] for r in et_rows if r["method"] == method}
        x = np.arange(len(scenes)) + (k - len(shown) / 2 + 0.5) * width
        axes[0].bar(x, [ratio.get(s, np.nan) for s in scenes], width, label=method)
    axes[0].axhline(1.0, color="k", lw=0.8)
    axes[0].set(ylabel="(1 - SSIM) / uniform's", title=f"equal time, {args.budget:g} s per image")
    names = list(dict.fromkeys(r["scene"] for r in stop_rows))
    axes[1].axhspan(*WINDOW, color="0.9", zorder=0)
    markers = {"learned": "o", "two-buffer": "s", "peer": "^", SURE: "v", SURE_TWIN: "D"}
    markers |= {ADAPTIVE_SURE: "P", ADAPTIVE_SURE_TWIN: "X"}
    for r in stop_rows:
        k = args.targets.index(r["target"])
        axes[1].scatter(
            names.index(r["scene"]) + 0.25 * (k - 1),
            r["true SSIM"] - r["target"],
            s=20,
            zorder=2,
            marker=markers[r["method"]],
            color=f"C{k}",
            label=f"{r['method']}, {r['target']:g}",
        )
    axes[1].set(ylabel="true SSIM at the stop - target", title="early stopping (grey: on target)")
    for ax, ticks in ((axes[0], scenes), (axes[1], names)):
        ax.set_xticks(range(len(ticks)))
        ax.set_xticklabels(ticks, rotation=45, ha="right")
        handles, labels = ax.get_legend_handles_labels()
        if labels:
            unique = dict(zip(labels, handles, strict=True))
            ax.legend(unique.values(), unique.keys(), fontsize=6, ncol=2)
    fig.tight_layout()
    save_figure(fig, args.out / "render_compare.png", dpi=100)


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    floats = lambda v: [float(x) for x in v.split(",")]  # noqa: E731
    ap.add_argument("--out", type=Path, default=Path("reports/render_compare"))
    ap.add_argument("--scenes", default=",".join((*FAMILIES, *CBOX)))
    ap.add_argument("--scene-dir", type=Path, default=REPO.parent / "shared" / "external" / "scenes")
    ap.add_argument("--renders-dir", type=Path, default=REPO.parent / "shared" / "external" / "renders")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--budget", type=float, default=1.0, help="seconds (render + scoring) per image at equal time")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--stop-seeds", type=int, help="seeds of the early-stopping runs (default: --seeds)")
    ap.add_argument("--curve-seeds", type=int, default=2, help="seeds of uniform's error-vs-spp curve")
    ap.add_argument("--tuning-seeds", type=int, default=1, help="seeds of the peer's tuning")
    ap.add_argument("--spp-per-step", type=int, default=4)
    ap.add_argument("--max-overhead", type=float, default=0.05)
    ap.add_argument("--min-spp", type=float, default=16, help="peer: pixels with fewer samples stay unconverged")
    ap.add_argument("--peer-threshold", type=float, help="peer at equal time: this threshold instead of tuning one")
    ap.add_argument("--targets", type=floats, default=[0.9, 0.95, 0.98])
    ap.add_argument("--stop-max-spp", type=int, default=512)
    ap.add_argument(
        "--stop-margins",
        type=floats,
        default=list(STOP_MARGINS),
        help="learned stop rules stop at target + margin; the margin is tuned on the families from these",
    )
    ap.add_argument(
        "--scorer",
        default=DEFAULT_WEIGHTS,
        help=f"the single-image scorer: shipped name or checkpoint path (default {DEFAULT_WEIGHTS})",
    )
    ap.add_argument(
        "--map-spp",
        type=map_spp_option,
        default=LOOP_DEFAULT,
        help="stop: past this many spp a single-image scorer rates a probe ('none': always the image; "
        "default: render_until's own)",
    )
    ap.add_argument(
        "--overlap",
        action="store_true",
        help="equal time: also adaptive sampling with --scorer's map read in blended, overlapping windows",
    )
    ap.add_argument("--twin-scorer", help="a two-buffer scorer: shipped name or checkpoint path (skipped without)")
    ap.add_argument(
        "--sure",
        action="store_true",
        help="stop: also --scorer (and --twin-scorer) stopping when the calibrated interval's low end reaches the "
        "target (sure=True); the same as adding sure,sure-twin to --stop-methods",
    )
    ap.add_argument(
        "--stop-methods",
        help=f"stop: the methods to run, comma-separated, of {','.join(STOP_METHODS)} (default: "
        f"{','.join(DEFAULT_STOP_METHODS)}; the two-buffer ones need --twin-scorer; adaptive-*: render_adaptive)",
    )
    ap.add_argument("--skip", default="", help="comma-separated: equal_time,stop,half_cost")
    ap.add_argument("--half-repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--quick", action="store_true", help="2 scenes, 2 seeds, 32x32, 0.3 s: a smoke run")
    args = ap.parse_args(argv)
    if args.quick:
        cbox = (args.scene_dir / "cbox" / CBOX["cbox_official"][0]).is_file()
        args.scenes = "cornell,cbox_official" if cbox else "cornell,caustic"
        args.seeds, args.curve_seeds, args.resolution, args.budget = 2, 1, 32, 0.3
        args.reference_spp, args.stop_max_spp, args.half_repeats = 256, 64, 2
    args.scenes = args.scenes.split(",")
    from data_gen.scenes import list_scenes  # any family: the peer's eight, those learnt later, the held-back ones

    known = (*list_scenes(), *CBOX)
    unknown = [s for s in args.scenes if s not in known]
    if unknown:
        fail(f"unknown scene(s) {', '.join(unknown)}; choose from {', '.join(known)}")
    if min(args.seeds, args.stop_seeds or 1, args.curve_seeds, args.tuning_seeds) < 1:
        fail("--seeds, --stop-seeds, --curve-seeds and --tuning-seeds must be >= 1")
    if args.budget <= 0 or args.resolution < 16 or args.stop_max_spp < 2 * args.spp_per_step:
        fail("--budget must be > 0, --resolution >= 16 and --stop-max-spp at least two steps")
    if not all(0 < t < 1 for t in args.targets):
        fail(f"--targets must lie in (0, 1), got {args.targets}")
    args.stop_seeds = [SEED_SPACING * k for k in range(1, (args.stop_seeds or args.seeds) + 1)]
    args.seeds = [SEED_SPACING * k for k in range(1, args.seeds + 1)]
    args.tuning_seeds = [SEED_SPACING * k for k in range(100, 100 + args.tuning_seeds)]
    grid = PEER_GRID[1::2] if args.quick else PEER_GRID
    args.peer_grid = [args.peer_threshold] if args.peer_threshold else list(grid)
    args.stop_grid = list(STOP_GRID[::2] if args.quick else STOP_GRID)
    if args.quick:
        args.stop_margins = args.stop_margins[::2]
    if not args.stop_margins or not all(0 <= m < 0.1 for m in args.stop_margins):
        fail(f"--stop-margins must lie in [0, 0.1), got {args.stop_margins}")
    args.stop_methods = stop_methods(args)
    if args.map_spp not in (None, LOOP_DEFAULT) and not args.map_spp >= 0:
        fail(f"--map-spp must be >= 0 or 'none', got {args.map_spp}")
    return args


def stop_methods(args) -> list[str]:
    """``--stop-methods`` (with ``--sure``'s two), checked: keys of ``STOP_METHODS``, in the order given."""
    keys = args.stop_methods.split(",") if args.stop_methods else list(DEFAULT_STOP_METHODS)
    if args.sure:
        keys += ["sure", "sure-twin"]
    unknown = [k for k in keys if k not in STOP_METHODS]
    if unknown:
        fail(f"--stop-methods: unknown method(s) {', '.join(unknown)}; choose from {', '.join(STOP_METHODS)}")
    twin = [k for k in keys if STOP_METHODS[k][1] == "adaptive (two-buffer)"]
    if args.stop_methods and twin and not args.twin_scorer:
        fail(f"--stop-methods {', '.join(twin)} need(s) a two-buffer scorer: give --twin-scorer dual_fast")
    return list(dict.fromkeys(keys))


def equal_time_section(scenes, scorers, args) -> tuple[str, list[dict], dict, dict]:
    from nriqa.render.compare import equal_time_rows, method_summary

    threshold, tuning = (args.peer_grid[0], []) if len(args.peer_grid) == 1 else tune_equal_time(scenes, args)
    records, curves = run_equal_time(scenes, scorers, args, threshold)
    rows = equal_time_rows(records, curves)
    write_csv(args.out / "render_compare.csv", rows, list(rows[0]))
    how = "tuned on the families, seeds " + ", ".join(map(str, args.tuning_seeds)) if tuning else "given"
    text = "\n".join(
        [
            f"## Equal time ({args.budget:g} s per image)\n",
            f"Peer threshold {threshold:g} ({how}).\n",
            markdown_table(tuning, ["threshold", "error ratio (geometric mean)"]) if tuning else "",
            markdown_table(
                rows,
                ["scene", "method", "seconds", "mean spp", "true SSIM", "SSIM std", "error ratio", "bound", "speed-up"],
            ),
            "Mean over the scenes (speed-up: geometric mean; 'beats the peer': "
            "a higher mean true SSIM than the peer's):\n",
            markdown_table(
                method_summary(rows),
                ["method", "scenes", "mean error ratio", "speed-up (geometric mean)", "beats the peer on"],
            ),
        ]
    )
    return text, rows, curves, {"equal_time": records, "peer_threshold": threshold, "peer_tuning": tuning}


def header(args, argv, scenes, scorers, variant, load_start, t_start) -> str:
    cpuinfo = Path("/proc/cpuinfo")
    cpu = (
        next(
            (
                line.split(":", 1)[1].strip()
                for line in cpuinfo.read_text().splitlines()
                if line.startswith("model name")
            ),
            "unknown CPU",
        )
        if cpuinfo.is_file()
        else "unknown CPU"
    )
    train = ", ".join(s for s in args.scenes if s in FAMILIES) or "none"
    held = ", ".join(s for s in args.scenes if s not in FAMILIES) or "none"
    return (
        f"# Render loops against the variance-based peer\n\n`python benchmarks/render_compare.py "
        f"{' '.join(sys.argv[1:] if argv is None else argv)}`\n\n"
        f"{cpu}, {os.cpu_count()} cores, load average {load_start:.1f} at the start, {os.getloadavg()[0]:.1f} at "
        f"the end; Mitsuba {variant}, {args.threads} torch thread(s); "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(t_start))}, {(time.time() - t_start) / 60:.0f} min. "
        f"{args.resolution}x{args.resolution}; seeds {args.seeds} (early stopping {args.stop_seeds}, tuning "
        f"{args.tuning_seeds}, uniform's curve {args.curve_seeds} seeds of its own); steps of {args.spp_per_step} "
        f"spp growing to 25 % of those done; peer min spp {args.min_spp:g}. Training scenes (the shipped scorer "
        f"learnt them; the peer's thresholds are tuned on them): {train}. The others (nothing tuned on them): {held}."
        f"{'' if 'adaptive (two-buffer)' in scorers else ' No --twin-scorer: no two-buffer rows.'}\n\n"
        "References: " + "; ".join(f"{k}: {v[2]}" for k, v in scenes.items()) + "\n"
    )


def main(argv: list[str] | None = None) -> None:
    args = parse(argv)
    import torch
    from render_loops import defaults_of

    from nriqa.render import ensure_variant, is_jit_variant, render_until

    if args.map_spp == LOOP_DEFAULT:  # the loop's default, so the report cannot drift from it
        args.map_spp = defaults_of(render_until)["map_spp"]
    torch.set_num_threads(args.threads)
    scorers = load_scorers(args)
    variant = ensure_variant("auto")
    if not is_jit_variant():
        fail(f"the per-pixel loops need llvm_ad_rgb; this machine runs {variant} (set DRJIT_LIBLLVM_PATH to LLVM 19)")
    skip = set(filter(None, args.skip.split(",")))
    load_start, t_start = os.getloadavg()[0], time.time()
    scenes = load_scenes(args)
    parts, results, et_rows, stop_rows, curves = [], {"args": {k: str(v) for k, v in vars(args).items()}}, [], [], {}
    if "equal_time" not in skip:
        text, et_rows, curves, raw = equal_time_section(scenes, scorers, args)
        parts.append(text)
        results.update(raw)
    if "stop" not in skip:
        if not curves:  # no equal-time runs: uniform's curves (for 'uniform needs') to twice the stop's spp
            curves = {name: curve(scene, ref, 2 * args.stop_max_spp, args) for name, (scene, ref, _) in scenes.items()}
        text, stop_rows, raw = stop_section(scenes, scorers, curves, args)
        parts.append(text)
        results.update(raw)
    if "half_cost" not in skip:
        rows = half_cost(scenes, args)
        parts.append("## Keeping the half buffer\n\n" + markdown_table(rows, list(rows[0])))
    if et_rows or stop_rows:
        plot(et_rows, stop_rows, args)
    results["curves"] = {k: {"spp": v[0].tolist(), "error": v[1].tolist()} for k, v in curves.items()}
    text = "\n".join([header(args, argv, scenes, scorers, variant, load_start, t_start), *parts])
    write_text_atomic(args.out / "render_compare.md", text)
    write_text_atomic(args.out / "runs.json", json.dumps(results, indent=1, default=float))
    print(text)


if __name__ == "__main__":
    main()
