"""Render loops in Mitsuba 3 driven by the Scorer: early stopping and adaptive sampling.

* :func:`render_until` -- progressive rendering: passes of ``spp_per_step`` samples with fresh
  seeds, averaged, until the predicted pooled quality reaches a target or the time runs out.
* :func:`render_adaptive` -- after a uniform first pass, each step renders ``spp_per_step`` more
  samples only in the tiles the predicted map rates worst (film crops), keeping a per-pixel
  sample count so each pixel holds the mean of all its samples.

The caller chooses the Mitsuba variant before calling, e.g. with the renderer's own choice::

    from data_gen.backend import init_worker, select_backend
    init_worker(select_backend("auto"), threads=2)   # llvm_ad_rgb where it works, else scalar_rgb

or :func:`ensure_variant`, which does exactly that when no variant is set. Both loops work in any
RGB variant. Scene dictionaries as built by ``data_gen.render.scene_dict`` (box pixel filter, so a
crop's pixels equal the full frame's; other filters would blur across crop borders).

Timing: ``seconds`` in the logs is render plus scoring time. With ``llvm_ad_rgb`` every distinct
(scene, sensor, spp) is JIT-compiled on its first render (0.3-0.8 s each on a 2-core CPU, and the
adaptive loop has one sensor per tile), so both loops first render each once, untimed and
discarded (``warmup=True``); the compile time is logged as ``setup_seconds`` in every row. The
true score (``true``, when a reference is given) is computed outside the timed region.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np
import torch

from nriqa.scorer import Scorer
from nriqa.ssim import ssim_map
from nriqa.tonemap import tonemap

__all__ = ["render_until", "render_adaptive", "true_ssim", "ensure_variant"]


def ensure_variant(requested: str = "auto", threads: int | None = None) -> str:
    """Set a Mitsuba variant with ``data_gen.backend`` unless one is already set; return the variant."""
    import mitsuba as mi

    if mi.variant() is not None:
        return mi.variant()
    import os

    from data_gen.backend import init_worker, select_backend

    variant = select_backend(requested)
    init_worker(variant, threads or os.cpu_count() or 1)
    return variant


def true_ssim(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean SSIM map of the tone-mapped ``(H, W, 3)`` linear image against the tone-mapped reference."""
    x = tonemap(torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)[None])
    y = tonemap(torch.from_numpy(np.ascontiguousarray(reference, dtype=np.float32)).permute(2, 0, 1)[None])
    return float(ssim_map(x, y).mean())


def _load(scene):
    import mitsuba as mi

    return mi.load_dict(dict(scene)) if isinstance(scene, Mapping) else scene


def _render(scene, spp: int, seed: int, sensor: int = 0) -> np.ndarray:
    import mitsuba as mi

    img = np.array(mi.render(scene, sensor=sensor, spp=spp, seed=seed), dtype=np.float32)[..., :3]
    # A NaN sample from the renderer would poison the running mean forever; count it as 0.
    return np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)


class _Clock:
    """Render and scoring time of a loop, and the row builder of its log."""

    def __init__(self, reference: np.ndarray | None, setup: float):
        self.render = self.score = 0.0
        self.setup = setup
        self.reference = reference
        self.log: list[dict] = []

    def row(self, image: np.ndarray, spp: np.ndarray | float, predicted: float | None) -> dict:
        spp = np.asarray(spp, dtype=np.float64)
        row = {
            "step": len(self.log),
            "seconds": self.render + self.score,
            "render_seconds": self.render,
            "score_seconds": self.score,
            "setup_seconds": self.setup,
            "spp": float(spp.mean()),
            "spp_min": float(spp.min()),
            "spp_max": float(spp.max()),
            "predicted": predicted,
            "true": true_ssim(image, self.reference) if self.reference is not None else None,
        }
        self.log.append(row)
        return row


def _reached(scorer: Scorer, predicted: float, target: float | None) -> bool:
    if target is None:
        return False
    return predicted >= target if scorer.higher_is_better else predicted <= target


def render_until(
    scene,
    scorer: Scorer | None,
    target_score: float | None,
    time_budget_s: float,
    spp_per_step: int = 4,
    reference: np.ndarray | None = None,
    *,
    max_spp: int | None = None,
    seed: int = 0,
    warmup: bool = True,
) -> tuple[np.ndarray, list[dict]]:
    """Progressive rendering until the predicted quality reaches ``target_score`` (early stopping).

    Each step renders ``spp_per_step`` samples per pixel with a new seed and folds them into the
    running mean; then the scorer rates the mean (as linear HDR). The loop stops after the first
    step whose predicted pooled score reaches the target (``>=`` for SSIM, ``<=`` for the patch
    model's MAE), when the time budget (render + scoring seconds) is spent, or at ``max_spp``.

    Args:
        scene: a Mitsuba scene dict (with film and sampler) or a loaded ``mi.Scene``.
        scorer: the :class:`~nriqa.scorer.Scorer`; ``None`` renders uniformly without scoring
            (the baseline: it runs until the time budget or ``max_spp``).
        target_score: predicted pooled score to stop at (``None``: never stop early).
        time_budget_s: wall-clock budget in seconds for rendering plus scoring.
        spp_per_step: samples per pixel per step.
        reference: converged ``(H, W, 3)`` linear image; adds the true mean SSIM to every row.
        max_spp: stop at this many samples per pixel.
        seed: seed of the first step; step ``k`` uses ``seed + k``.
        warmup: render once, untimed and discarded, to JIT-compile the kernel (LLVM variants).

    Returns:
        ``(image, log)``: the ``(H, W, 3)`` float32 linear mean, and one dict per step with
        ``step, seconds, render_seconds, score_seconds, setup_seconds, spp, spp_min, spp_max,
        predicted, true`` (``predicted``/``true`` are ``None`` without scorer/reference) and, in the
        last row, ``stop``: ``"target"``, ``"time"`` or ``"max_spp"``.
    """
    loaded = _load(scene)
    setup = 0.0
    if warmup:
        t0 = time.perf_counter()
        _render(loaded, spp_per_step, seed=2**31 - 1)
        setup = time.perf_counter() - t0
    clock = _Clock(reference, setup)
    mean: np.ndarray | None = None
    spp = 0
    step = 0
    while True:
        t0 = time.perf_counter()
        img = _render(loaded, spp_per_step, seed=seed + step)
        clock.render += time.perf_counter() - t0
        step += 1
        mean = img if mean is None else mean + (img - mean) * (spp_per_step / (spp + spp_per_step))
        spp += spp_per_step
        predicted = None
        if scorer is not None:
            t0 = time.perf_counter()
            predicted = scorer(mean, hdr=True).score
            clock.score += time.perf_counter() - t0
        row = clock.row(mean, spp, predicted)
        if scorer is not None and _reached(scorer, predicted, target_score):
            row["stop"] = "target"
        elif row["seconds"] >= time_budget_s:
            row["stop"] = "time"
        elif max_spp is not None and spp + spp_per_step > max_spp:
            row["stop"] = "max_spp"
        if "stop" in row:
            return mean, clock.log


def _tiles(width: int, height: int, tile: int) -> list[tuple[int, int, int, int]]:
    return [(x, y, min(tile, width - x), min(tile, height - y)) for y in range(0, height, tile) for x in range(0, width, tile)]


def _with_tile_sensors(scene: Mapping, tiles: list[tuple[int, int, int, int]]) -> dict:
    """The scene plus one copy of its sensor per tile, each with its film cropped to the tile.

    One scene with many sensors, not one scene per tile: Dr.Jit then compiles one kernel per
    sensor once, whereas many loaded copies of the scene made every render recompile.
    """
    out = dict(scene)
    sensor = scene["sensor"]
    for i, (x, y, w, h) in enumerate(tiles):
        film = {**sensor["film"], "crop_offset_x": x, "crop_offset_y": y, "crop_width": w, "crop_height": h}
        out[f"nriqa_tile_sensor_{i:05d}"] = {**sensor, "film": film}
    return out


def _sensor_index(loaded) -> dict[tuple[int, int, int, int], int]:
    """``(x, y, w, h)`` of each sensor's film crop -> its index for ``mi.render(sensor=...)``."""
    index = {}
    for i, sensor in enumerate(loaded.sensors()):
        (x, y), (w, h) = sensor.film().crop_offset(), sensor.film().crop_size()
        index.setdefault((int(x), int(y), int(w), int(h)), i)
    return index


def _expected_gain(qmap: np.ndarray, count: np.ndarray, tiles, k: int, higher_is_better: bool) -> np.ndarray:
    """Per tile, the predicted error times the share of noise ``k`` more samples would remove.

    Error is ``1 - SSIM`` (or the MAE); Monte Carlo noise falls as ``1/sqrt(n)``, so going from
    ``n`` to ``n + k`` samples removes the fraction ``1 - sqrt(n / (n + k))`` of it. Ranking by
    this rather than by the error alone keeps the loop from pouring samples into a tile that is
    hard but already well sampled.
    """
    gains = []
    for x, y, w, h in tiles:
        q = float(qmap[y : y + h, x : x + w].mean())
        n = float(count[y : y + h, x : x + w].mean())
        error = 1.0 - q if higher_is_better else q
        gains.append(max(error, 0.0) * (1.0 - np.sqrt(n / (n + k))))
    return np.array(gains)


def render_adaptive(
    scene: Mapping,
    scorer: Scorer,
    total_spp: float | None = None,
    time_budget_s: float | None = None,
    *,
    initial_spp: int = 4,
    spp_per_step: int = 4,
    tile: int = 16,
    fraction: float = 0.25,
    reference: np.ndarray | None = None,
    seed: int = 0,
    warmup: bool = True,
) -> tuple[np.ndarray, list[dict]]:
    """Adaptive sampling: spend samples on the tiles the predicted map rates worst.

    A uniform pass of ``initial_spp`` samples, then per step: score the current mean, split the
    map into ``tile`` x ``tile`` tiles, rank them by expected gain -- mean predicted error
    (``1 - SSIM``, or the patch model's MAE) times ``1 - sqrt(n / (n + k))``, the share of the
    noise ``k = spp_per_step`` more samples remove at ``n`` samples -- and render ``k`` more samples
    in the best ``fraction`` of tiles (at least one), each through a film crop (``crop_offset_x/y``,
    ``crop_width/height``): the scene is loaded once with one extra sensor per tile, a copy of
    ``scene["sensor"]`` with its film cropped, and every render call gets its own seed. Every
    pixel keeps its sample count ``n`` and the mean of its samples:
    ``mean <- mean + (batch_mean - mean) * k / (n + k)`` for a batch of ``k`` samples.

    Stops when the mean samples per pixel reach ``total_spp`` or the render + scoring time reaches
    ``time_budget_s`` (give at least one).

    Args:
        scene: a Mitsuba scene *dict* with ``sensor.film`` (width, height; box filter) and sampler;
            a dict, not a loaded scene, because a cropped sensor per tile is added to it.
        scorer: the :class:`~nriqa.scorer.Scorer` whose map chooses the tiles.
        total_spp: budget in mean samples per pixel.
        time_budget_s: budget in seconds (render + scoring).
        initial_spp: samples per pixel of the uniform first pass.
        spp_per_step: samples per pixel added to each chosen tile per step.
        tile: tile side in pixels (edge tiles may be smaller).
        fraction: share of tiles refined per step, in (0, 1].
        reference: converged ``(H, W, 3)`` image; adds the true mean SSIM to every row.
        seed: base seed; every render call gets a distinct one.
        warmup: render with every sensor once, untimed, to JIT-compile its kernel (LLVM variants).

    Returns:
        ``(image, log)`` as for :func:`render_until` (``spp`` is the mean over pixels); the last
        row's ``stop`` is ``"spp"`` or ``"time"``, and ``spp_map`` in it holds the ``(H, W)`` counts.
    """
    if not isinstance(scene, Mapping):
        raise TypeError("render_adaptive needs the scene as a dict (a cropped sensor per tile is added to it), not a loaded scene")
    if total_spp is None and time_budget_s is None:
        raise ValueError("render_adaptive needs a budget: total_spp, time_budget_s or both")
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    film = scene["sensor"]["film"]
    width, height = int(film["width"]), int(film["height"])
    tiles = _tiles(width, height, tile)
    loaded = _load(_with_tile_sensors(scene, tiles))
    index = _sensor_index(loaded)
    full, crops = index[(0, 0, width, height)], [index[t] for t in tiles]
    setup = 0.0
    if warmup:
        t0 = time.perf_counter()
        _render(loaded, initial_spp, seed=2**31 - 1, sensor=full)
        for c in crops:
            _render(loaded, spp_per_step, seed=2**31 - 1, sensor=c)
        setup = time.perf_counter() - t0
    clock = _Clock(reference, setup)

    t0 = time.perf_counter()
    mean = _render(loaded, initial_spp, seed=seed, sensor=full)
    clock.render += time.perf_counter() - t0
    count = np.full((height, width), float(initial_spp))
    calls = 1
    n_refine = max(1, int(round(fraction * len(tiles))))
    while True:
        t0 = time.perf_counter()
        result = scorer(mean, hdr=True)
        clock.score += time.perf_counter() - t0
        row = clock.row(mean, count, result.score)
        if total_spp is not None and count.mean() >= total_spp:
            row["stop"] = "spp"
        elif time_budget_s is not None and row["seconds"] >= time_budget_s:
            row["stop"] = "time"
        if "stop" in row:
            row["spp_map"] = count
            return mean, clock.log
        order = np.argsort(-_expected_gain(result.map, count, tiles, spp_per_step, scorer.higher_is_better), kind="stable")
        t0 = time.perf_counter()
        for i in order[:n_refine]:
            x, y, w, h = tiles[i]
            img = _render(loaded, spp_per_step, seed=seed + calls, sensor=crops[i])
            calls += 1
            n = count[y : y + h, x : x + w, None]
            mean[y : y + h, x : x + w] += (img - mean[y : y + h, x : x + w]) * (spp_per_step / (n + spp_per_step))
            count[y : y + h, x : x + w] += spp_per_step
        clock.render += time.perf_counter() - t0
