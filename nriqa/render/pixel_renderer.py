"""Any number of samples in each pixel of a scene, in one wavefront: the renderer of per-pixel adaptive sampling.

``mi.render`` renders the same samples per pixel everywhere. :class:`PixelRenderer` traces the
scene's integrator from the camera through Mitsuba's Python API instead, one sample per entry of a
pixel index, so a step can give every pixel its own count. Needs a JIT variant (``llvm_ad_rgb``).
"""

from __future__ import annotations

import logging

import numpy as np

from nriqa.render.backend import is_jit_variant

__all__ = ["PixelRenderer"]

log = logging.getLogger(__name__)


def _camera_samples(scene, index, seed, width: int, offset: tuple[int, int], full: tuple[int, int]):
    """One sample of the scene's first sensor and integrator per entry of ``index`` (a pixel), as RGB.

    A point uniform in the pixel (box filter), a camera ray through it, the integrator's ``sample``,
    weighted by the sensor's importance; a non-finite sample counts as 0. Traced by Dr.Jit: a
    frozen copy of it (:class:`PixelRenderer`) replays the recorded kernel on later calls.
    """
    import drjit as dr
    import mitsuba as mi

    sensor = scene.sensors()[0]
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, dr.width(index))
    pixel = mi.Vector2f(mi.Float(index % width + offset[0]), mi.Float(index // width + offset[1]))
    position = (pixel + sampler.next_2d()) / mi.ScalarVector2f(full)
    time_ = sensor.shutter_open() + sensor.shutter_open_time() * sampler.next_1d()
    ray, weight = sensor.sample_ray(time_, sampler.next_1d(), position, sampler.next_2d())
    spectrum, _, _ = scene.integrator().sample(scene, sampler, ray, sensor.get_medium())
    rgb = spectrum * weight
    return dr.select(dr.isfinite(rgb), rgb, 0.0)


def _aligned(array: np.ndarray, alignment: int = 64) -> np.ndarray:
    """A copy of the non-empty 1-D ``array`` whose data starts on an ``alignment``-byte boundary.

    Dr.Jit maps a numpy array's memory rather than copying it, and a frozen function records anew
    when that memory's alignment differs from the recorded call's: numpy's allocations are aligned
    or not by chance, so without this a frozen renderer re-recorded (and, with a cold kernel cache,
    compiled) at an unpredictable step of a timed loop.
    """
    buffer = np.empty(array.size * array.itemsize + alignment, dtype=np.uint8)
    start = -buffer.ctypes.data % alignment
    out = buffer[start : start + array.size * array.itemsize].view(array.dtype)
    out[:] = array
    return out


class PixelRenderer:
    """Renders any number of samples in each pixel of a loaded scene's first sensor, in one call.

    One wavefront holds every sample asked for: pixel indices repeated by their counts, each
    traced by :func:`_camera_samples` (path or volpath; not the particle tracer, which does not
    trace from the camera). Sums per pixel are taken in numpy (segment sums over the samples,
    which are sorted by pixel: a fixed order, so the same seed and counts give the same sums,
    which float atomics would not promise).
    Needs a JIT variant (``llvm_ad_rgb``). The seed is passed as an opaque value so that a new
    seed or a new wavefront size does not recompile the kernel, and with ``freeze`` (default) the
    sampling code is a Dr.Jit frozen function: it is traced once and later calls replay the
    recorded kernel (the pixel indices go in 64-byte aligned, see :func:`_aligned`: Dr.Jit records
    anew when the alignment of mapped memory changes). Tracing the integrator is a fixed cost per
    call, which ``mi.render`` pays on every call (``benchmarks/pixel_renderer.py`` measures it).
    Frozen and traced calls give the same sums, bit for bit. A scene Dr.Jit cannot record (a variable of
    the scene made before recording and not traversable: in Mitsuba 3.9 the thin-lens camera of the ``dof``
    family and the scenes of ``textured_light``) is traced on every call instead, with one warning: the same
    sums, at the tracing cost per call.
    """

    def __init__(self, scene, freeze: bool = True):
        import drjit as dr
        import mitsuba as mi

        if not is_jit_variant():
            raise RuntimeError(f"PixelRenderer needs a JIT variant such as llvm_ad_rgb, not {mi.variant()}")
        self.scene = scene
        if not isinstance(scene.integrator(), mi.SamplingIntegrator):
            raise ValueError(
                "per-pixel sampling traces from the camera and needs a sampling integrator (path, volpath), "
                f"not {type(scene.integrator()).__name__}; use render_adaptive(..., tile=N)"
            )
        film = scene.sensors()[0].film()
        self.width, self.height = (int(v) for v in film.crop_size())
        self.offset = tuple(int(v) for v in film.crop_offset())
        self.full = tuple(int(v) for v in film.size())
        # One frozen function per renderer: its recordings go with it.
        self._samples = dr.freeze(_camera_samples) if freeze else _camera_samples

    @property
    def frozen(self) -> bool:
        """Whether calls replay a recorded kernel (``False``: traced every call, asked for or fallen back to)."""
        return self._samples is not _camera_samples

    def __call__(self, counts: np.ndarray, seed: int) -> np.ndarray:
        """Sum of ``counts[y, x]`` new samples in every pixel: ``(H, W, 3)`` float64 (non-finite samples count as 0)."""
        flat, values = self._trace(counts, seed)
        return self._segment_sums(flat, values)

    def with_half(self, counts: np.ndarray, seed: int, done: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`__call__`, and the sum of the new samples of even index among each pixel's samples.

        ``done[y, x]``: the samples the pixel already has, so the ``j``-th new sample is the pixel's
        sample ``done + j``; those with an even index make the half buffer of
        :class:`~nriqa.render.film.HalfFilm`. Returns ``(sums, even_sums)``, both ``(H, W, 3)`` float64.
        The same wavefront as :meth:`__call__` (same seed, same sums): the split is numpy over the samples.
        """
        flat, values = self._trace(counts, seed)
        done = np.asarray(done, dtype=np.int64).reshape(-1)
        if done.shape != flat.shape:
            raise ValueError(f"done must be {(self.height, self.width)}, got {np.shape(done)}")
        # Wavefront position k holds sample (k - start) of its pixel, i.e. the pixel's sample done + k - start.
        starts = np.cumsum(flat) - flat
        index = np.arange(values.shape[1], dtype=np.int64) + np.repeat(done - starts, flat)
        return self._segment_sums(flat, values), self._segment_sums(flat, values * (index % 2 == 0))

    def _trace(self, counts: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """The flat counts ``(H*W,)`` int64 and the samples' RGB ``(3, counts.sum())``, sorted by pixel."""
        import drjit as dr
        import mitsuba as mi

        counts = np.asarray(counts)
        if counts.shape != (self.height, self.width):
            raise ValueError(f"counts must be {(self.height, self.width)}, got {counts.shape}")
        flat = counts.reshape(-1).astype(np.int64)
        index = np.repeat(np.arange(flat.size, dtype=np.uint32), flat)
        if index.size == 0:
            return flat, np.zeros((3, 0))
        index_jit = mi.UInt32(_aligned(index))
        seed_jit = dr.opaque(mi.UInt32, seed & 0xFFFFFFFF)
        try:
            rgb = self._samples(self.scene, index_jit, seed_jit, self.width, self.offset, self.full)
        except RuntimeError as exc:
            if not (self.frozen and "record" in str(exc)):
                raise
            log.warning(
                "Dr.Jit cannot record this scene (sensor %s) in a frozen function: every call is traced instead (%s)",
                str(self.scene.sensors()[0]).split("[", 1)[0],  # the plugin's class, e.g. ThinLensCamera
                str(exc).splitlines()[0],
            )
            self._samples = _camera_samples
            rgb = self._samples(self.scene, index_jit, seed_jit, self.width, self.offset, self.full)
        dr.eval(rgb)  # one kernel for all three channels (reading .x, .y, .z lazily would trace three times)
        return flat, np.stack([np.array(rgb.x), np.array(rgb.y), np.array(rgb.z)])

    def _segment_sums(self, flat: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Per-pixel sums ``(H, W, 3)`` of samples sorted by pixel: segment sums, added in order (deterministic)."""
        sums = np.zeros((3, flat.size))
        nonzero = np.flatnonzero(flat)
        if nonzero.size:
            sums[:, nonzero] = np.add.reduceat(values, (np.cumsum(flat) - flat)[nonzero], axis=1)
        return sums.T.reshape(self.height, self.width, 3)
