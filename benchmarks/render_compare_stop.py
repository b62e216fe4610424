"""Early stopping and the half buffer's cost for ``benchmarks/render_compare.py`` (its sections 2 and 3).

Kept apart so each file stays one readable size; the command is ``benchmarks/render_compare.py``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from nriqa.io.tables import markdown_table, write_csv

# the training scenes: the eight data_gen families (the peer's threshold is tuned on them)
FAMILIES = ("caustic", "cornell", "door", "envmap", "glossy", "medium", "shadows", "textured")
STOP_GRID = tuple(0.4 * 0.5 ** (k / 2) for k in range(12))  # stop: 0.4 down to 0.009, steps of sqrt(2)
STOP_MARGINS = (0.0, 0.005, 0.01, 0.015)  # the learned stop rules stop at predicted >= target + margin
SURE = "sure (low end)"  # --sure: the single-image scorer, stopping when its interval's low end reaches the target
SURE_TWIN = "sure, two-buffer (low end)"  # --sure with --twin-scorer: the same for the two-buffer scorer's halves
ADAPTIVE_SURE = "adaptive, sure (low end)"  # render_adaptive: samples placed by the map, stopping as SURE does
ADAPTIVE_SURE_TWIN = "adaptive, sure, two-buffer (low end)"  # the same with the two-buffer scorer
# --stop-methods: key -> (method label, scorer key or None); the sure ones stop on the interval, nothing tuned
STOP_METHODS = {
    "peer": ("peer", None),
    "learned": ("learned", "adaptive"),
    "two-buffer": ("two-buffer", "adaptive (two-buffer)"),
    "sure": (SURE, "adaptive"),
    "sure-twin": (SURE_TWIN, "adaptive (two-buffer)"),
    "adaptive-sure": (ADAPTIVE_SURE, "adaptive"),
    "adaptive-sure-twin": (ADAPTIVE_SURE_TWIN, "adaptive (two-buffer)"),
}


def tune_stop(scenes, curves, args) -> tuple[dict[float, float], list[dict]]:
    """Per target, the stop threshold of ``--stop-grid`` on target most often on the families that
    uniform brings to the target within ``--stop-max-spp`` (one progressive run per family and seed)."""
    from nriqa.render.compare import choose_threshold, threshold_crossings, uniform_reaches

    runs = {}
    for name in [n for n in scenes if n in FAMILIES]:
        scene, reference, _ = scenes[name]
        runs[name] = [
            threshold_crossings(
                scene, reference, args.stop_grid, args.stop_max_spp, seed, args.min_spp, args.spp_per_step
            )
            for seed in args.tuning_seeds
        ]
    chosen, rows = {}, []
    for target in args.targets:
        reach = [n for n in runs if uniform_reaches(target, *curves[n], args.stop_max_spp)]
        fit = [run for n in (reach or list(runs)) for run in runs[n]]
        chosen[target], hits = choose_threshold(fit, target)
        rows.append(
            {
                "target": target,
                "threshold": chosen[target],
                "tuning runs": len(fit),
                "on target": hits,
                "mean spp": np.mean([run[chosen[target]][0] for run in fit]),
            }
        )
    return chosen, rows


def learned_stop(scene, reference, scorer, target: float, margin: float, seed: int, args, sure: bool = False) -> dict:
    """The last row of ``render_until`` with ``scorer`` stopping at predicted >= ``target + margin`` (below 1),
    scoring every step; ``sure``: at the first low end of its calibrated interval >= ``target + margin``."""
    from nriqa.render import render_until

    return render_until(
        scene,
        scorer,
        min(target + margin, 0.9999),
        1e9,
        args.spp_per_step,
        reference,
        max_spp=args.stop_max_spp,
        max_overhead=None,
        seed=seed,
        warmup=False,
        map_spp=args.map_spp,
        sure=sure,
    )[1][-1]


def adaptive_sure_stop(scene, reference, scorer, target: float, seed: int, args) -> dict:
    """The last row of ``render_adaptive`` (samples placed by ``scorer``'s map, at most ``--stop-max-spp``) stopping at
    the first low end of ``scorer``'s calibrated interval >= ``target``, scoring every step."""
    from nriqa.render import render_adaptive

    return render_adaptive(
        scene,
        scorer,
        total_spp=args.stop_max_spp,
        initial_spp=args.spp_per_step,
        spp_per_step=args.spp_per_step,
        max_overhead=None,
        reference=reference,
        seed=seed,
        warmup=False,
        target_score=target,
        sure=True,
    )[1][-1]


def tune_margins(scenes, scorers, curves, args) -> tuple[dict[str, float], list[dict]]:
    """Per learned stop rule, the margin of ``--stop-margins`` on target most often (ties: the smaller) over
    the families and targets uniform reaches within ``--stop-max-spp``, on the tuning seeds: the same
    footing as the peer's threshold. A rule that steps onto the target ends where its estimate crosses
    it, so its estimate's bias decides the outcome; the window is lopsided ([-0.005, +0.02])."""
    from nriqa.render.compare import on_target, uniform_reaches

    chosen, rows = {}, []
    tuned = [STOP_METHODS[m] for m in ("learned", "two-buffer") if m in args.stop_methods]
    for method, key in [(m, k) for m, k in tuned if k in scorers]:
        hits = {}
        for margin in args.stop_margins:
            ends = [
                (learned_stop(scene, reference, scorers[key], target, margin, seed, args)["true"], target)
                for name, (scene, reference, _) in scenes.items()
                if name in FAMILIES
                for target in args.targets
                if uniform_reaches(target, *curves[name], args.stop_max_spp)
                for seed in args.tuning_seeds
            ]
            hits[margin] = sum(bool(on_target(true, target)) for true, target in ends)
            rows.append({"method": method, "margin": margin, "tuning runs": len(ends), "on target": hits[margin]})
        chosen[method] = max(args.stop_margins, key=lambda m: (hits[m], -m))
        print(f"  {method}: margin {chosen[method]:g} ({hits})", file=sys.stderr)
    return chosen, rows


def stop_fns(scene, reference, target: float, scorers, thresholds, margins, args) -> dict:
    """The early-stopping methods of ``--stop-methods`` for one scene and target: label -> ``fn(seed) -> last row``."""
    from nriqa.render import render_peer

    fns = {}
    for key in args.stop_methods:
        label, by = STOP_METHODS[key]
        if by is not None and by not in scorers:
            continue  # a two-buffer method without --twin-scorer
        if key == "peer":
            fns[label] = lambda s, t=thresholds[target]: render_peer(
                scene,
                t,
                max_spp=args.stop_max_spp,
                min_spp=args.min_spp,
                initial_spp=args.spp_per_step,
                spp_per_step=args.spp_per_step,
                reference=reference,
                seed=s,
                warmup=False,
            )[1][-1]
        elif key in ("learned", "two-buffer"):
            fns[label] = lambda s, sc=scorers[by], m=margins[label]: learned_stop(
                scene, reference, sc, target, m, s, args
            )
        elif key.startswith("adaptive"):
            fns[label] = lambda s, sc=scorers[by]: adaptive_sure_stop(scene, reference, sc, target, s, args)
        else:
            fns[label] = lambda s, sc=scorers[by]: learned_stop(scene, reference, sc, target, 0.0, s, args, sure=True)
    return fns


def run_stop(scenes, scorers, thresholds, margins, args) -> list[dict]:
    """Early stopping per scene, target and seed: each method of ``--stop-methods`` (:func:`stop_fns`)."""
    records = []
    for name, (scene, reference, _) in scenes.items():
        for target in args.targets:
            fns = stop_fns(scene, reference, target, scorers, thresholds, margins, args)
            for seed in args.stop_seeds:
                for method, fn in fns.items():
                    end = fn(seed)  # the run's last row
                    records.append(
                        {
                            "scene": name,
                            "target": target,
                            "method": method,
                            "seed": seed,
                            "true": end["true"],
                            "spp": end["spp"],
                            "stop": end["stop"],
                        }
                    )
        print(f"  {name}: early stopping done", file=sys.stderr)
    return records


def half_cost(scenes, args) -> list[dict]:
    """Median time of a PixelRenderer call, the same with the even sums, and two calls of half the samples."""
    from nriqa.render import PixelRenderer
    from nriqa.render.film import load_scene

    name = next(iter(scenes))
    renderer = PixelRenderer(load_scene(scenes[name][0]))
    rows = []
    for spp in (4, 16):
        full, half = np.full((args.resolution,) * 2, spp), np.full((args.resolution,) * 2, spp // 2)
        calls = {
            "one call": lambda s, c=full: renderer(c, s),
            "one call + even sums": lambda s, c=full: renderer.with_half(c, s, c),
            "two calls of half the samples": lambda s, c=half: (renderer(c, s), renderer(c, s + 1)),
        }
        times = {k: [] for k in calls}
        for fn in calls.values():
            fn(1)  # records the frozen kernel for this size
        for rep in range(args.half_repeats):
            for k, fn in calls.items():
                t0 = time.perf_counter()
                fn(100 + rep)
                times[k].append(time.perf_counter() - t0)
        base = np.median(times["one call"])
        rows += [
            {"scene": name, "spp": spp, "how": k, "ms (median)": 1e3 * np.median(v), "ratio": np.median(v) / base}
            for k, v in times.items()
        ]
    return rows


SUMMARY_COLUMNS = [
    "target",
    "method",
    "scenes",
    "runs on target",
    "runs at or above",
    "true SSIM (mean)",
    "spp / uniform needs (geometric mean)",
]


def held_out_summary(rows: list[dict], max_spp: int) -> list[str]:
    """The summary again over the scenes that are not training families (none: nothing)."""
    from nriqa.render.compare import stop_summary

    held = [r for r in rows if r["scene"] not in FAMILIES]
    if not held or len(held) == len(rows):
        return []
    names = ", ".join(dict.fromkeys(r["scene"] for r in held))
    return [
        f"Over the held-out scenes alone ({names}; nothing was tuned on them), those uniform brings to the target "
        f"within {max_spp} spp:\n",
        markdown_table(stop_summary(held), SUMMARY_COLUMNS),
    ]


def stop_section(scenes, scorers, curves, args) -> tuple[str, list[dict], dict]:
    from nriqa.render.compare import stop_rows, stop_summary

    thresholds, tuning = tune_stop(scenes, curves, args) if "peer" in args.stop_methods else ({}, [])
    margins, margin_rows = tune_margins(scenes, scorers, curves, args)
    records = run_stop(scenes, scorers, thresholds, margins, args)
    rows = stop_rows(records, curves, args.stop_max_spp)
    write_csv(args.out / "render_compare_stop.csv", rows, list(rows[0]))
    text = "\n".join(
        [
            f"## Early stopping (no clock; at most {args.stop_max_spp} spp)\n",
            f"Methods: {', '.join(args.stop_methods)}.\n",
            "Peer thresholds per target, tuned on the families ('on target': share of the tuning runs):\n"
            if tuning
            else "",
            markdown_table(tuning, list(tuning[0])) if tuning else "",
            "Learned stop rules: stop at the first predicted SSIM >= target + margin, the margin tuned on the "
            "families and the same seeds (runs on target per margin; chosen: "
            + ", ".join(f"{k} {v:g}" for k, v in margins.items())
            + "):\n"
            if margin_rows
            else "",
            markdown_table(margin_rows, ["method", "margin", "tuning runs", "on target"]) if margin_rows else "",
            f"'{SURE}': the single-image scorer stops at the first low end of its calibrated interval at or "
            "above the target (no margin, nothing tuned; it rates the image itself at every count); "
            f"'{SURE_TWIN}': the two-buffer scorer likewise, its halves' interval carried to the whole image; "
            f"'{ADAPTIVE_SURE}', '{ADAPTIVE_SURE_TWIN}': the same stop in render_adaptive, whose steps go where "
            "the scorer's map expects the most error (half of each step spread evenly).\n"
            if any("sure" in key for key in args.stop_methods)
            else "",
            markdown_table(
                rows,
                [
                    "scene",
                    "target",
                    "method",
                    "true SSIM",
                    "SSIM std",
                    "spp",
                    "uniform needs",
                    "on target",
                    "reached",
                    "stops",
                ],
            ),
            f"Over the scenes uniform brings to the target within {args.stop_max_spp} spp:\n",
            markdown_table(stop_summary(rows), SUMMARY_COLUMNS),
            *held_out_summary(rows, args.stop_max_spp),
        ]
    )
    return (
        text,
        rows,
        {
            "stop": records,
            "stop_thresholds": thresholds,
            "stop_tuning": tuning,
            "stop_margins": margins,
            "stop_margin_tuning": margin_rows,
        },
    )
