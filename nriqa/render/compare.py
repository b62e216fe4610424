"""Render loops compared at equal quality: uniform's error against samples, and where stop rules end.

A loop is measured against uniform rendering of the same scene: its error ratio at equal time, and
the *equal-quality speed-up*, the samples uniform needs to reach the loop's error over the samples
uniform reached in the same time. Uniform's error against samples is measured without a clock
(:func:`uniform_curve`) and interpolated in log-log (:func:`spp_for_error`). A stop is *on target*
when the true SSIM there lies in a window about the target (:data:`WINDOW`). For the variance-based
peer, :func:`threshold_crossings` follows a grid of thresholds in one run, recording where its stop
rule would end the run at each, and :func:`choose_threshold` picks the one on target most often.
Used by ``benchmarks/render_compare.py``; results in ``docs/results/render_compare.md``.
"""

from __future__ import annotations

import numpy as np

from nriqa.render.clock import Schedule
from nriqa.render.film import HalfFilm, load_scene
from nriqa.render.loop import render_loop, render_until
from nriqa.render.peer import Converged, UnconvergedPixels
from nriqa.render.pixel_renderer import PixelRenderer
from nriqa.render.stop import MaxSpp, Progress, StopRule

__all__ = [
    "WINDOW",
    "Crossings",
    "choose_threshold",
    "equal_time_rows",
    "method_summary",
    "on_target",
    "spp_for_error",
    "stop_summary",
    "stop_rows",
    "threshold_crossings",
    "uniform_curve",
    "uniform_reaches",
]

# A stop is on target when its true SSIM lies in [target - 0.005, target + 0.02] (issue 16's criterion).
WINDOW = (-0.005, 0.02)


def uniform_curve(scene, reference: np.ndarray, max_spp: float, seeds, spp_per_step: int = 4):
    """Uniform rendering (``render_until``, no clock) up to ``max_spp``: ``(spp, error)`` arrays, the
    error ``1 - SSIM`` averaged over ``seeds`` at each step (the steps are the same for every seed)."""
    logs = [
        render_until(scene, None, None, 1e9, spp_per_step, reference, max_spp=max_spp, seed=s, warmup=False)[1]
        for s in seeds
    ]
    rows = min(len(log) for log in logs)
    spp = np.array([logs[0][i]["spp"] for i in range(rows)])
    return spp, np.array([np.mean([1.0 - log[i]["true"] for log in logs]) for i in range(rows)])


def spp_for_error(error: float, spp: np.ndarray, curve: np.ndarray) -> tuple[float, str]:
    """Samples per pixel uniform needs for ``error``: log-log interpolation of its best error so far.

    Returns ``(spp, bound)``; ``bound`` is ``">"`` when ``error`` is below the whole curve (``spp``
    is then its last point, a lower bound), ``"<"`` when uniform's first point is already better.
    """
    best = np.minimum.accumulate(np.maximum(curve, 1e-12))
    error = max(error, 1e-12)
    if error < best[-1]:
        return float(spp[-1]), ">"
    i = int(np.argmax(best <= error))
    if i == 0:
        return float(spp[0]), "<" if error > best[0] else ""
    t = np.log(best[i - 1] / error) / np.log(best[i - 1] / best[i])
    return float(np.exp(np.log(spp[i - 1]) + t * np.log(spp[i] / spp[i - 1]))), ""


def uniform_reaches(target: float, spp: np.ndarray, curve: np.ndarray, max_spp: float) -> bool:
    """Whether uniform rendering's SSIM reaches ``target`` within ``max_spp`` on the curve (:func:`uniform_curve`)."""
    needs, bound = spp_for_error(1 - target, spp, curve)
    return bound != ">" and needs <= max_spp


def on_target(true, target: float, window: tuple[float, float] = WINDOW) -> np.ndarray:
    """Whether each true SSIM lies in ``[target + window[0], target + window[1]]``."""
    true = np.asarray(true, dtype=np.float64)
    return (true >= target + window[0]) & (true <= target + window[1])


class Crossings(StopRule):
    """Records, for each threshold of ``grid``, the first row at which :class:`~nriqa.render.peer.Converged`
    would end the run (``first[threshold] = (spp, true)``); ends the run once every one is recorded."""

    name = "grid"

    def __init__(self, grid, min_spp: float):
        self.rules, self.first = [Converged(t, 0.0, min_spp) for t in grid], {}

    def reached(self, progress: Progress) -> bool:
        for rule in self.rules:
            if rule.threshold not in self.first and rule.reached(progress):
                self.first[rule.threshold] = (progress.row["spp"], progress.row["true"])
        return len(self.first) == len(self.rules)


def threshold_crossings(scene, reference, grid, max_spp: float, seed: int, min_spp: float = 16, spp_per_step: int = 4):
    """One peer run through a decreasing ``grid`` of thresholds (its placement lowers the threshold by
    ``grid[1] / grid[0]`` whenever every pixel has converged), no clock: ``{threshold: (spp, true)}``
    where the stop rule at that threshold would have ended it, or the run's end at ``max_spp``.

    An approximation of one run per threshold (the samples placed before a threshold is reached
    differ), made to tune a threshold cheaply; the chosen one is then run as it is."""
    rule = Crossings(grid, min_spp)
    placement = UnconvergedPixels(grid[0], min_spp, grid[1] / grid[0], seed=seed)
    film = HalfFilm(PixelRenderer(load_scene(scene)), seed)
    stops = [rule, MaxSpp(max_spp, spp_per_step)]
    schedule = Schedule(spp_per_step, spp_per_step)
    log = render_loop(film, placement, stops, None, schedule=schedule, reference=reference, warmup=False)[1]
    return {t: rule.first.get(t, (log[-1]["spp"], log[-1]["true"])) for t in grid}


def choose_threshold(runs: list[dict], target: float, window: tuple[float, float] = WINDOW) -> tuple[float, float]:
    """The threshold whose stops (``runs``: :func:`threshold_crossings` results) are on target most often;
    ties: the mean true SSIM nearest the window's middle. Returns ``(threshold, share on target)``."""
    middle = target + sum(window) / 2

    def score(t):
        trues = [run[t][1] for run in runs]
        return float(np.mean(on_target(trues, target, window))), -float(np.mean(np.abs(np.array(trues) - middle)))

    best = max(runs[0], key=score)
    return best, score(best)[0]


def equal_time_rows(records: list[dict], curves: dict) -> list[dict]:
    """Per (scene, method) of equal-time ``records`` (``scene, method, seed, true, spp, seconds``): means,
    the error ratio to ``"uniform"`` (per seed, averaged) and the equal-quality speed-up (``curves[scene]``
    from :func:`uniform_curve`; ``bound`` as from :func:`spp_for_error`)."""
    rows = []
    for scene in dict.fromkeys(r["scene"] for r in records):
        mine = [r for r in records if r["scene"] == scene]
        uniform = {r["seed"]: r for r in mine if r["method"] == "uniform"}
        reached = np.mean([r["spp"] for r in uniform.values()])
        for method in dict.fromkeys(r["method"] for r in mine):
            runs = [r for r in mine if r["method"] == method]
            true = np.array([r["true"] for r in runs])
            needed, bound = spp_for_error(float(np.mean(1 - true)), *curves[scene])
            ratio = np.mean([(1 - r["true"]) / (1 - uniform[r["seed"]]["true"]) for r in runs])
            rows.append(
                {
                    "scene": scene,
                    "method": method,
                    "seconds": np.mean([r["seconds"] for r in runs]),
                    "mean spp": np.mean([r["spp"] for r in runs]),
                    "true SSIM": true.mean(),
                    "SSIM std": true.std(),
                    "error ratio": float(ratio),
                    "bound": bound,
                    "speed-up": needed / reached,
                }
            )
    return rows


def stop_rows(records: list[dict], curves: dict, max_spp: float, window: tuple[float, float] = WINDOW) -> list[dict]:
    """Per (scene, target, method) of early-stopping ``records`` (``scene, target, method, true, spp, stop``):
    the true SSIM and samples at the stop, the samples uniform needs for the target (``reachable``: within
    ``max_spp``), and the runs on target and at or above it."""
    rows = []
    for scene, target in dict.fromkeys((r["scene"], r["target"]) for r in records):
        needs, bound = spp_for_error(1 - target, *curves[scene])
        for method in dict.fromkeys(r["method"] for r in records):
            runs = [r for r in records if (r["scene"], r["target"], r["method"]) == (scene, target, method)]
            if not runs:
                continue
            true = np.array([r["true"] for r in runs])
            rows.append(
                {
                    "scene": scene,
                    "target": target,
                    "method": method,
                    "true SSIM": true.mean(),
                    "SSIM std": true.std(),
                    "spp": np.mean([r["spp"] for r in runs]),
                    "uniform needs": f"{bound}{needs:.0f}",
                    "reachable": uniform_reaches(target, *curves[scene], max_spp),
                    "on target": f"{on_target(true, target, window).sum()}/{len(runs)}",
                    "reached": f"{(true >= target).sum()}/{len(runs)}",
                    "stops": "/".join(sorted({r["stop"] for r in runs})),
                }
            )
    return rows


def method_summary(rows: list[dict], against: str = "peer") -> list[dict]:
    """Per method over :func:`equal_time_rows`: mean error ratio, geometric-mean speed-up, and on how many
    scenes its true SSIM is higher than ``against``'s."""
    other = {r["scene"]: r["true SSIM"] for r in rows if r["method"] == against}
    out = []
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        wins = sum(r["true SSIM"] > other[r["scene"]] for r in mine if r["scene"] in other)
        out.append(
            {
                "method": method,
                "scenes": len(mine),
                "mean error ratio": np.mean([r["error ratio"] for r in mine]),
                "speed-up (geometric mean)": float(np.exp(np.mean([np.log(r["speed-up"]) for r in mine]))),
                f"beats the {against} on": f"{wins}/{len(mine)}",
            }
        )
    return out


def stop_summary(rows: list[dict]) -> list[dict]:
    """Per target and method over the reachable rows of :func:`stop_rows`: runs on target and at or above it,
    mean true SSIM, and the samples spent over those uniform needs (geometric mean)."""
    out = []
    for target, method in dict.fromkeys((r["target"], r["method"]) for r in rows):
        mine = [r for r in rows if (r["target"], r["method"]) == (target, method) and r["reachable"]]
        if not mine:
            continue
        hits, runs = (sum(int(r["on target"].split("/")[k]) for r in mine) for k in (0, 1))
        above = sum(int(r["reached"].split("/")[0]) for r in mine)
        ratio = [r["spp"] / float(r["uniform needs"].lstrip("<>")) for r in mine]
        out.append(
            {
                "target": target,
                "method": method,
                "scenes": len(mine),
                "runs on target": f"{hits}/{runs} ({100 * hits / runs:.0f} %)",
                "runs at or above": f"{above}/{runs} ({100 * above / runs:.0f} %)",
                "true SSIM (mean)": np.mean([r["true SSIM"] for r in mine]),
                "spp / uniform needs (geometric mean)": float(np.exp(np.mean(np.log(ratio)))),
            }
        )
    return out
