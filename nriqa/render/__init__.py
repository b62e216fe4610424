"""Render loops in Mitsuba 3 driven by a scorer: early stopping and adaptive sampling.

One driver (:func:`render_loop`) with pluggable parts, one module each:

* ``backend`` -- the Mitsuba variant (``llvm_ad_rgb`` where it works, else ``scalar_rgb``).
* ``film`` -- the image a loop builds (mean and count per pixel); ``tiles`` -- its tile variant.
* ``pixel_renderer`` -- any number of samples per pixel in one wavefront (:class:`PixelRenderer`).
* ``placement`` -- where a step's samples go; ``stop`` -- when a loop ends.
* ``rating`` -- what the scorer rates and when; ``error_model`` -- noise and predicted score.
* ``clock`` -- render and scoring time, step sizes; ``reference`` -- the true SSIM (the oracle).
* ``loop`` -- the driver, and the two loops built on it: :func:`render_until`, :func:`render_adaptive`.
* ``half_buffer`` -- Cycles' per-pixel error from a half buffer; ``peer`` -- the variance-based peer
  built on it (placement, stop rule and :func:`render_peer`), the control that needs no model;
  ``compare`` -- loops against uniform rendering at equal quality, and where stop rules end.

Names are imported lazily: ``import nriqa.render.backend`` (as the renderer's workers do) loads
neither torch nor the scorer.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "render_loop": "loop",
    "render_until": "loop",
    "render_adaptive": "loop",
    "ensure_variant": "backend",
    "is_jit_variant": "backend",
    "select_backend": "backend",
    "init_worker": "backend",
    "ReferenceScorer": "reference",
    "true_ssim": "reference",
    "PixelRenderer": "pixel_renderer",
    "ImageFilm": "film",
    "PixelFilm": "film",
    "HalfFilm": "film",
    "split_halves": "film",
    "render_peer": "peer",
    "UnconvergedPixels": "peer",
    "Converged": "peer",
    "half_buffer_error": "half_buffer",
    "load_scene": "film",
    "render_spp": "film",
    "TileFilm": "tiles",
    "TileRefinement": "tiles",
    "Placement": "placement",
    "UniformSteps": "placement",
    "PixelAllocation": "placement",
    "allocate_samples": "placement",
    "StopRule": "stop",
    "TargetScore": "stop",
    "SureOfTarget": "stop",
    "TimeBudget": "stop",
    "SppBudget": "stop",
    "MaxSpp": "stop",
    "Probes": "rating",
    "Schedule": "clock",
    "ErrorModel": "error_model",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
