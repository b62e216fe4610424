"""Adaptive sampling per tile, through film crops: the placement that works in every variant (``scalar_rgb``).

The image is cut into square tiles; each step refines the tiles where the predicted map expects
the most gain, each through a film crop (one extra sensor per tile). Every ``mi.render`` call has a
fixed cost whatever its size, so small tiles lose to uniform rendering at equal time; per-pixel
sampling (:class:`~nriqa.render.placement.PixelAllocation`) avoids that where a JIT variant runs.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from nriqa.render.clock import Schedule
from nriqa.render.error_model import ErrorModel, error_of
from nriqa.render.film import WARMUP_SEED, load_scene, render_spp, scene_pixel_filter

__all__ = ["TileFilm", "TileRefinement", "expected_gain", "tile_grid"]

Tile = tuple[int, int, int, int]  # x, y, width, height in pixels


def tile_grid(width: int, height: int, tile: int) -> list[Tile]:
    """Tiles of ``tile`` x ``tile`` pixels covering the image, row by row (edge tiles may be smaller)."""
    return [
        (x, y, min(tile, width - x), min(tile, height - y))
        for y in range(0, height, tile)
        for x in range(0, width, tile)
    ]


def _with_tile_sensors(scene: Mapping, tiles: list[Tile]) -> dict:
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


def _sensor_index(loaded) -> dict[Tile, int]:
    """``(x, y, w, h)`` of each sensor's film crop -> its index for ``mi.render(sensor=...)``."""
    index = {}
    for i, sensor in enumerate(loaded.sensors()):
        (x, y), (w, h) = sensor.film().crop_offset(), sensor.film().crop_size()
        index.setdefault((int(x), int(y), int(w), int(h)), i)
    return index


def expected_gain(qmap: np.ndarray, count: np.ndarray, tiles, k: int, higher_is_better: bool) -> np.ndarray:
    """Per tile, the predicted error times the share of noise ``k`` more samples would remove.

    Error is ``1 - SSIM`` (or the MAE); Monte Carlo noise falls as ``1/sqrt(n)``, so going from
    ``n`` to ``n + k`` samples removes the fraction ``1 - sqrt(n / (n + k))`` of it. Ranking by
    this rather than by the error alone keeps the loop from pouring samples into a tile that is
    hard but already well sampled.
    """
    error = error_of(qmap, higher_is_better)
    gains = []
    for x, y, w, h in tiles:
        e = float(error[y : y + h, x : x + w].mean())
        n = float(count[y : y + h, x : x + w].mean())
        gains.append(e * (1.0 - np.sqrt(n / (n + k))))
    return np.array(gains)


class TileFilm:
    """The running mean per pixel of whole-image and tile renders of a scene dict (a film crop per tile)."""

    log_counts = True
    quantum = 1

    def __init__(self, scene: Mapping, tile: int, seed: int = 0):
        if not isinstance(scene, Mapping):
            raise TypeError(
                "render_adaptive with tiles needs the scene as a dict (a cropped sensor per tile is "
                "added to it), not a loaded scene"
            )
        film = scene["sensor"]["film"]
        width, height = int(film["width"]), int(film["height"])
        self.tiles = tile_grid(width, height, tile)
        self.scene = load_scene(_with_tile_sensors(scene, self.tiles))
        self.pixel_filter = scene_pixel_filter(self.scene)
        index = _sensor_index(self.scene)
        self.full, self.crops = index[(0, 0, width, height)], [index[t] for t in self.tiles]
        self.seed, self.calls = seed, 0
        self.image: np.ndarray | None = None
        self.count = np.zeros((height, width))

    @property
    def spp(self) -> float:
        """Mean samples per pixel."""
        return float(self.count.mean())

    def _render(self, spp: int, sensor: int) -> np.ndarray:
        img = render_spp(self.scene, spp, seed=self.seed + self.calls, sensor=sensor)
        self.calls += 1
        return img

    def warm_up(self, spp: int, seed: int = WARMUP_SEED, tile: int | None = None) -> np.ndarray:
        """An image of the whole film or of tile ``tile`` at ``spp``, left out of the film (compiles its kernel)."""
        return render_spp(self.scene, spp, seed=seed, sensor=self.full if tile is None else self.crops[tile])

    def add_uniform(self, spp: int) -> np.ndarray:
        """Render ``spp`` more samples in every pixel and fold them in; return their own mean image."""
        img = self._render(spp, self.full)
        if self.image is None:
            self.image = img.copy()
        else:
            self.image += (img - self.image) * (spp / (self.count + spp))[..., None]
        self.count += spp
        return img

    def add_tile(self, i: int, spp: int) -> None:
        """Render ``spp`` more samples in every pixel of tile ``i`` and fold them in."""
        x, y, w, h = self.tiles[i]
        img = self._render(spp, self.crops[i])
        n = self.count[y : y + h, x : x + w, None]
        self.image[y : y + h, x : x + w] += (img - self.image[y : y + h, x : x + w]) * (spp / (n + spp))
        self.count[y : y + h, x : x + w] += spp


class TileRefinement:
    """Per step, the ``fraction`` of tiles with the most :func:`expected_gain` get ``k`` samples each.

    ``k`` is a uniform step's samples (``spp_per_step`` per pixel) spread over the chosen tiles;
    steps are neither grown nor cut below that.

    Args:
        film: the :class:`TileFilm` it refines.
        fraction: the share of tiles refined per step, in (0, 1].
        spp_per_step: mean samples per pixel of a step.
    """

    needs_map = True

    def __init__(self, film: TileFilm, fraction: float = 0.25, spp_per_step: float = 4):
        if not 0 < fraction <= 1:
            raise ValueError(f"fraction must be in (0, 1], got {fraction}")
        self.n_refine = max(1, int(round(fraction * len(film.tiles))))
        self.k = max(1, round(spp_per_step * len(film.tiles) / self.n_refine))

    def warm_up(self, film: TileFilm, schedule: Schedule) -> None:
        for i in range(len(film.tiles)):
            film.warm_up(self.k, tile=i)

    def step(self, film: TileFilm, spp: float, model: ErrorModel) -> None:
        gain = expected_gain(model.last_map, film.count, film.tiles, self.k, model.higher_is_better)
        for i in np.argsort(-gain, kind="stable")[: self.n_refine]:
            film.add_tile(int(i), self.k)
