"""Display transforms: how linear HDR renders become the 8-bit or float images users look at.

Users bring PNGs from other renderers, whose display pipeline is not the package's tone map: a
plain exposure and sRGB curve with clipped highlights, a gamma of 2.2, 8-bit quantisation. To make
the scorer hold on those, training draws one :class:`Display` per example and applies it
*identically* to the noisy image and its reference before the target is computed (issue 15), so
the target is the SSIM a user would measure between the two displayed images.

* ``tonemap`` -- the package tone map (:func:`nriqa.core.tonemap.tonemap`), exposure-free; what EXR
  input goes through at inference.
* ``srgb`` -- exposure, clip to [0, 1], the sRGB transfer function (IEC 61966-2-1, via
  :func:`kornia.color.linear_rgb_to_rgb`).
* ``gamma22`` -- exposure, clip to [0, 1], ``x ** (1 / 2.2)``.

The exposure of ``srgb``/``gamma22`` is ``2 ** stops`` times the *key* exposure of the reference,
the scale that maps its log-average luminance to middle grey 0.18 (Reinhard et al. 2002, eq. 1),
so ``stops`` is relative to a sensible exposure whatever the render's absolute level. ``bits``
quantises the result (``round(x * (2**bits - 1)) / (2**bits - 1)``), as saving a PNG does.
"""

from __future__ import annotations

import dataclasses
import math
import re

import torch
from kornia.color import linear_rgb_to_rgb
from torch import Tensor

from nriqa.core.tonemap import GAMMA, luminance, tonemap

CURVES = ("tonemap", "srgb", "gamma22")
MIDDLE_GREY = 0.18
# Luminance floor of the log-average, so black pixels do not send it to -inf (Reinhard's delta).
_LOG_EPS = 1e-6
# CURVE, then optional signed stops, then optional :BITS -- "srgb", "srgb+2", "gamma22-1.5:8", "tonemap:8".
_SPEC = re.compile(r"^(?P<curve>[a-z0-9]+)(?P<stops>[+-]\d+(?:\.\d+)?)?(?::(?P<bits>\d+))?$")


@dataclasses.dataclass(frozen=True)
class Display:
    """One display pipeline.

    Attributes:
        curve: ``"tonemap"``, ``"srgb"`` or ``"gamma22"``.
        stops: exposure in stops relative to the key exposure (ignored by ``tonemap``).
        bits: quantise to this many bits after the curve (``None``: keep floats).
    """

    curve: str = "tonemap"
    stops: float = 0.0
    bits: int | None = None

    def __post_init__(self) -> None:
        if self.curve not in CURVES:
            raise ValueError(f"unknown display curve {self.curve!r}; choose one of {', '.join(CURVES)}")
        if self.bits is not None and not 1 <= self.bits <= 16:
            raise ValueError(f"display bits must be in 1..16 or None, got {self.bits}")
        if not math.isfinite(self.stops):
            raise ValueError(f"display stops must be finite, got {self.stops}")

    @classmethod
    def parse(cls, spec: str) -> Display:
        """A display from ``CURVE[+-STOPS][:BITS]``: ``srgb``, ``srgb+2``, ``gamma22-1.5:8``, ``tonemap:8``.

        Raises:
            ValueError: one line naming the spec and the form it needs.
        """
        match = _SPEC.match(spec.strip().lower())
        if match is None or match["curve"] not in CURVES:
            raise ValueError(
                f"display {spec!r}: give CURVE[+-STOPS][:BITS] with CURVE one of {', '.join(CURVES)} "
                "(e.g. srgb, srgb+2, gamma22-1:8)"
            )
        stops = float(match["stops"] or 0.0)
        if match["curve"] == "tonemap" and stops:
            raise ValueError(f"display {spec!r}: the tone map has no exposure; drop the stops")
        return cls(match["curve"], stops, int(match["bits"]) if match["bits"] else None)

    def __str__(self) -> str:
        """The spec :meth:`parse` reads back."""
        stops = f"{self.stops:+g}" if self.stops else ""
        return f"{self.curve}{stops}{f':{self.bits}' if self.bits is not None else ''}"


def _clean(hdr: Tensor) -> Tensor:
    """NaN and negative -> 0, +inf -> huge (a pixel with +inf is set white afterwards, as by the tone map)."""
    return torch.nan_to_num(hdr, nan=0.0, posinf=1e30, neginf=0.0).clamp(0.0, 1e30)


def key_exposure(reference: Tensor) -> Tensor:
    """Scale mapping the log-average luminance of ``reference`` to 0.18, per image.

    Args:
        reference: ``(..., 3, H, W)`` linear HDR; bad pixels are cleaned as by the tone map.

    Returns:
        ``(..., 1, 1, 1)`` positive finite scale; 1 for an all-black image.
    """
    lum = luminance(_clean(reference)).clamp(max=1e30)
    log_avg = torch.exp(torch.log(lum + _LOG_EPS).mean(dim=(-3, -2, -1), keepdim=True))
    scale = MIDDLE_GREY / log_avg
    black = lum.amax(dim=(-3, -2, -1), keepdim=True) <= 0
    return torch.where(black | ~torch.isfinite(scale), torch.ones_like(scale), scale)


def quantise(ldr: Tensor, bits: int) -> Tensor:
    """Round LDR in [0, 1] to ``2 ** bits`` levels, as writing an integer image file does."""
    levels = float(2**bits - 1)
    return torch.round(ldr * levels) / levels


def apply_display(hdr: Tensor, display: Display, scale: Tensor | float = 1.0) -> Tensor:
    """Linear HDR ``(..., 3, H, W)`` -> displayed LDR in [0, 1] through ``display``.

    Args:
        hdr: linear RGB, float32 or float64, any range; NaN/Inf handled as by the tone map.
        display: the pipeline.
        scale: the key exposure (:func:`key_exposure` of the reference), broadcastable to ``hdr``;
            pass the *same* scale for a noisy image and its reference.

    Returns:
        LDR of the same shape, dtype and device.
    """
    if display.curve == "tonemap":
        ldr = tonemap(hdr)
    else:
        exposed = (_clean(hdr) * (scale * 2.0**display.stops)).clamp(0.0, 1.0)
        ldr = linear_rgb_to_rgb(exposed) if display.curve == "srgb" else exposed ** (1.0 / GAMMA)
        white = torch.isposinf(hdr).any(dim=-3, keepdim=True)
        ldr = torch.where(white, torch.ones_like(ldr), ldr.clamp(0.0, 1.0))
    return quantise(ldr, display.bits) if display.bits is not None else ldr


def display_pair(noisy: Tensor, reference: Tensor, display: Display) -> tuple[Tensor, Tensor]:
    """Apply one display identically to a noisy render and its reference (exposure keyed on the reference)."""
    scale = key_exposure(reference) if display.curve != "tonemap" else 1.0
    return apply_display(noisy, display, scale), apply_display(reference, display, scale)


@dataclasses.dataclass(frozen=True)
class DisplayMix:
    """How training draws a :class:`Display` per example.

    Attributes:
        tonemap, srgb, gamma22: relative weights of the curves (need not sum to 1).
        stops: exposure drawn uniformly in ``[-stops, stops]`` for ``srgb``/``gamma22``.
        quantise_p: probability of 8-bit quantisation after the curve.
    """

    tonemap: float = 0.5
    srgb: float = 0.25
    gamma22: float = 0.25
    stops: float = 2.0
    quantise_p: float = 0.5

    def __post_init__(self) -> None:
        weights = (self.tonemap, self.srgb, self.gamma22)
        if min(weights) < 0 or sum(weights) <= 0:
            raise ValueError(f"display mix weights must be >= 0 with a positive sum, got {weights}")
        if not 0.0 <= self.quantise_p <= 1.0 or self.stops < 0:
            raise ValueError(f"display mix needs 0 <= quantise_p <= 1 and stops >= 0, got {self}")

    def sample(self, generator: torch.Generator) -> Display:
        """Draw one display; always consumes three uniforms, so the stream stays aligned."""
        u = torch.rand(3, generator=generator, dtype=torch.float64).tolist()
        weights = [self.tonemap, self.srgb, self.gamma22]
        edges = [sum(weights[: i + 1]) / sum(weights) for i in range(3)]
        curve = CURVES[next(i for i, e in enumerate(edges) if u[0] < e or i == 2)]
        stops = 0.0 if curve == "tonemap" else (2.0 * u[1] - 1.0) * self.stops
        return Display(curve, stops, 8 if u[2] < self.quantise_p else None)
