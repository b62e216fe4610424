"""The image a render loop builds: the mean of its samples per pixel, and how many each pixel has.

A film renders samples and folds them into its mean. :class:`ImageFilm` renders whole images with
``mi.render`` (every pixel gets the same count, any variant); :class:`PixelFilm` renders any count
per pixel through :class:`~nriqa.render.pixel_renderer.PixelRenderer` (JIT variants), and
:class:`HalfFilm` also keeps the half buffer of the even samples (for the variance-based peer and
two-buffer scorers); the tile film
of :mod:`nriqa.render.tiles` renders film crops. Every render call of a film gets its own seed,
``seed + k`` for the ``k``-th call. Scene dictionaries are as built by ``data_gen.render.scene_dict``:
a box pixel filter, so that a sample counts for its own pixel only (other filters spread it over its
neighbours). Each film says which filter its images have (``pixel_filter``): films that render with
``mi.render`` the scene's (:func:`scene_pixel_filter`), :class:`PixelFilm` always ``"box"`` (it traces its
own camera rays, a point uniform in each pixel, whatever the scene's filter). A render loop checks that
it is the one its scorer learnt (:func:`check_pixel_filter`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

import numpy as np

from nriqa.render.error_model import running_mean
from nriqa.render.pixel_renderer import PixelRenderer

__all__ = [
    "WARMUP_SEED",
    "Film",
    "HalfFilm",
    "ImageFilm",
    "PixelFilm",
    "check_pixel_filter",
    "load_scene",
    "render_spp",
    "scene_pixel_filter",
    "split_halves",
]

# Seeds of the discarded warm-up renders, apart from any a loop's own renders use.
WARMUP_SEED = 2**31 - 1


class Film(Protocol):
    """What a render loop needs of a film.

    ``image``: ``(H, W, 3)`` float32 linear mean (``None`` before the first pass); ``count``:
    ``(H, W)`` float64 samples per pixel; ``spp``: their mean; ``quantum``: every count it renders
    uniformly is a multiple of it; ``log_counts``: whether a loop's last row carries ``count`` as
    ``spp_map``; ``pixel_filter``: the pixel filter its images have (:func:`scene_pixel_filter`).
    """

    image: np.ndarray | None
    count: np.ndarray
    quantum: int
    log_counts: bool
    pixel_filter: str

    @property
    def spp(self) -> float: ...

    def warm_up(self, spp: int, seed: int = WARMUP_SEED) -> np.ndarray:
        """An image of ``spp`` samples per pixel, left out of the film (compiles its kernel)."""
        ...

    def add_uniform(self, spp: int) -> np.ndarray:
        """Render ``spp`` more samples in every pixel and fold them in; return their own mean image."""
        ...


def load_scene(scene):
    """A loaded scene; a dict's integrator loses ``samples_per_pass``: the loops size their own steps."""
    import mitsuba as mi

    if not isinstance(scene, Mapping):
        return scene
    scene = dict(scene)
    if isinstance(scene.get("integrator"), Mapping):
        scene["integrator"] = {k: v for k, v in scene["integrator"].items() if k != "samples_per_pass"}
    return mi.load_dict(scene)


def scene_pixel_filter(scene) -> str:
    """The pixel filter of the loaded ``scene``'s first film: ``"box"``, ``"gaussian"`` (Mitsuba's default,
    standard deviation 0.5 pixel), or Mitsuba's own description of any other (e.g. ``"TentFilter[radius=1.000000]"``).
    """
    text = str(scene.sensors()[0].film().rfilter()).strip()
    if text.startswith("BoxFilter"):
        return "box"
    if text.startswith("GaussianFilter[stddev=0.50,"):
        return "gaussian"
    return text


_FILTER_NAMES = {"box": "box", "gaussian": "Gaussian of 0.5 pixel (Mitsuba's default)"}


def check_pixel_filter(film_filter: str, scorer_filter: str, *, per_pixel: bool = False) -> None:
    """Raise a one-line ``ValueError`` unless a film's pixel filter is the one the scorer learnt.

    A scorer reads every image as if it had its filter: the box-filter files read a render through
    Mitsuba's default Gaussian, which spreads every sample over neighbouring pixels, far too good (the
    external Cornell boxes through a Gaussian: MAE 0.22, 2 spp read as converged); ``unet_fast_gaussian``
    reads box-filtered renders too low. ``per_pixel``: the film traces its own box-filtered rays
    (:class:`PixelFilm`), whatever the scene's film says.
    """
    if film_filter == scorer_filter:
        return
    if per_pixel:
        raise ValueError(
            f"per-pixel sampling traces box-filtered pixels whatever the scene's film, and the scorer reads "
            f"{scorer_filter}-filtered renders: use a box-filter scorer (unet_fast), or tiles (tile=16)"
        )
    shape = _FILTER_NAMES.get(film_filter, film_filter.split("[")[0])
    spreads = ", which spreads each sample over neighbouring pixels" if film_filter != "box" else ""
    raise ValueError(
        f"the scene's film filters with a {shape}{spreads}, and the scorer reads {scorer_filter}-filtered renders: "
        f"set scene['sensor']['film']['rfilter'] = {{'type': '{scorer_filter}'}} (in a scene file: "
        f'<rfilter type="{scorer_filter}"/>), or use a scorer for the film\'s filter'
    )


def render_spp(scene, spp: int, seed: int, sensor: int = 0) -> np.ndarray:
    """``mi.render`` of a loaded scene at ``spp``: the ``(H, W, 3)`` float32 linear image (non-finite as 0)."""
    import mitsuba as mi

    img = np.array(mi.render(scene, sensor=sensor, spp=spp, seed=seed), dtype=np.float32)[..., :3]
    # A NaN sample from the renderer would poison the running mean forever; count it as 0.
    return np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)


class ImageFilm:
    """The running mean of whole-image renders of a loaded scene's first sensor (``mi.render``).

    ``quantum``: every count rendered is a multiple of it (a loaded scene's ``samples_per_pass``,
    if set, must divide it).
    """

    log_counts = False

    def __init__(self, scene, seed: int = 0, quantum: int = 1):
        self.scene = scene
        self.pixel_filter = scene_pixel_filter(scene)
        self.seed, self.calls = seed, 0
        self.quantum = quantum
        width, height = (int(v) for v in scene.sensors()[0].film().crop_size())
        self.spp = 0
        self.image: np.ndarray | None = None
        self.count = np.zeros((height, width))

    def warm_up(self, spp: int, seed: int = WARMUP_SEED) -> np.ndarray:
        """An image of ``spp`` samples per pixel, left out of the film (compiles its kernel)."""
        return render_spp(self.scene, spp, seed=seed)

    def add_uniform(self, spp: int) -> np.ndarray:
        """Render ``spp`` more samples in every pixel and fold them in; return their own mean image."""
        img = render_spp(self.scene, spp, seed=self.seed + self.calls)
        self.calls += 1
        self.image = running_mean(self.image, img, spp / (self.spp + spp))
        self.spp += spp
        self.count = np.full(self.count.shape, float(self.spp))
        return img


class PixelFilm:
    """Per-pixel sums and counts of the samples a :class:`PixelRenderer` renders, and their mean."""

    log_counts = True
    quantum = 1
    pixel_filter = "box"  # its own camera rays, a point uniform in each pixel

    def __init__(self, renderer: PixelRenderer, seed: int = 0):
        self.renderer = renderer
        self.seed, self.calls = seed, 0
        shape = (renderer.height, renderer.width)
        self.sums = np.zeros((*shape, 3))
        self.count = np.zeros(shape)
        self.image: np.ndarray | None = None

    @property
    def spp(self) -> float:
        """Mean samples per pixel."""
        return float(self.count.mean())

    def warm_up(self, spp: int, seed: int = WARMUP_SEED) -> np.ndarray:
        """An image of ``spp`` samples per pixel, left out of the film (records the frozen kernel)."""
        return (self.renderer(np.full(self.count.shape, spp), seed=seed) / spp).astype(np.float32)

    def add(self, counts: np.ndarray) -> np.ndarray:
        """Render ``counts[y, x]`` more samples in every pixel and fold them in; return their sums."""
        sums = self.renderer(counts, seed=self.seed + self.calls)
        self.calls += 1
        self.sums += sums
        self.count += counts
        self.image = (self.sums / self.count[..., None]).astype(np.float32)
        return sums

    def add_uniform(self, spp: int) -> np.ndarray:
        """Render ``spp`` more samples in every pixel and fold them in; return their own mean image."""
        return (self.add(np.full(self.count.shape, spp)) / spp).astype(np.float32)


def split_halves(
    image: np.ndarray, half: np.ndarray, n: np.ndarray, m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two independent half images behind an image and its half buffer, for a two-buffer scorer.

    ``image`` ``I`` is the mean of a pixel's ``n`` samples, ``half`` ``A`` the mean of ``m`` of them
    (``(H, W, 3)``; ``n``, ``m`` ``(H, W)``). The other ``n - m`` samples have the mean
    ``B = (n I - m A) / (n - m)``, independent of ``A``: ``(A, B)`` is a true pair of independent
    renders, each with about half the samples of ``I``, which is what a two-buffer scorer learnt
    from (an image and an independent twin at the same spp). Its rating of ``A`` is carried to ``I``'s
    ``n`` samples by :func:`nriqa.render.rating.at_full_samples` with ``share = m / n``.

    (No single stand-in image ``T`` for an independent render of ``n`` samples exists: any function
    of ``I`` and ``A`` that gives ``T - I`` the right spread leaves ``T`` correlated with ``I`` in
    the wrong way, and SSIM(I, T) then reads a noisy image as far cleaner than it is.)

    Pixels with a single sample (no second half) get ``B = A`` and ``share = 1``.

    Returns:
        ``(A, B, share)``: ``(H, W, 3)`` float32 twice and ``(H, W)`` float64.
    """
    n = np.asarray(n, dtype=np.float64)
    m = np.asarray(m, dtype=np.float64)
    rest = n - m
    a = np.asarray(half, dtype=np.float64)
    total = np.asarray(image, dtype=np.float64) * n[..., None] - a * m[..., None]
    b = np.where((rest > 0)[..., None], total / np.maximum(rest, 1.0)[..., None], a)
    share = np.where(rest > 0, m / np.maximum(n, 1.0), 1.0)
    return a.astype(np.float32), b.astype(np.float32), share


class HalfFilm(PixelFilm):
    """A :class:`PixelFilm` that also keeps, per pixel, the mean of its even samples: the half buffer.

    A pixel's samples are numbered in the order rendered; those of even index (``0, 2, 4, ...``,
    ``ceil(n / 2)`` of ``n``) make the half buffer ``half`` (``A``), as Cycles' adaptive sampling
    keeps one (:mod:`nriqa.render.half_buffer`). Both come from the same wavefront
    (:meth:`~nriqa.render.pixel_renderer.PixelRenderer.with_half`): no extra render call.
    ``image``, ``count`` and the seeds are those of a :class:`PixelFilm` fed the same counts.
    """

    def __init__(self, renderer: PixelRenderer, seed: int = 0):
        super().__init__(renderer, seed)
        self.even_sums = np.zeros_like(self.sums)
        self.half: np.ndarray | None = None

    @staticmethod
    def even_count(count: np.ndarray) -> np.ndarray:
        """Samples of even index among ``count``: ``ceil(count / 2)``."""
        return np.ceil(np.asarray(count, dtype=np.float64) / 2.0)

    def add(self, counts: np.ndarray) -> np.ndarray:
        """Render ``counts[y, x]`` more samples in every pixel and fold them in; return their sums."""
        done = self.count.copy()
        sums, even = self.renderer.with_half(counts, seed=self.seed + self.calls, done=done)
        self.calls += 1
        self.sums += sums
        self.even_sums += even
        self.count += counts
        self.image = (self.sums / self.count[..., None]).astype(np.float32)
        half = self.even_sums / np.maximum(self.even_count(self.count), 1.0)[..., None]
        self.half = half.astype(np.float32)
        return sums

    def halves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The image's two independent halves and the first one's share of the samples: :func:`split_halves`."""
        if self.image is None:
            raise ValueError("the film has no samples yet: no halves")
        return split_halves(self.image, self.half, self.count, self.even_count(self.count))
