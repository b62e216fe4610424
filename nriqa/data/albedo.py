"""Training augmentation: a random albedo texture multiplied into the noisy patch and its reference alike.

A held-out scene family with a kind of detail of its own (photographic textures, fine geometry) is read
as noise by a network that learnt from a few families: it has not seen enough textures that mask noise.
This draws a new texture per patch, unlike anything rendered (random-phase noise with a power spectrum
``1 / f ** beta``, smooth or cut into two tones; or, with ``lines``, a grille of thin parallel lines, the
sharp thin structure of fine geometry and its shadows), and multiplies it into the linear radiance of the
noisy image, its twin and its reference alike, as a surface's albedo multiplies the light it reflects, so
its noise. The target is computed afterwards from the textured pair. Training only.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from nriqa.data.options import check_range, check_share, check_whole

BETA_RANGE = (1.0, 3.0)  # spectral slope: 1 fine grain ... 3 large smooth blobs
LOW_RANGE = (0.05, 0.7)  # the texture's darkest albedo (its brightest is 1): strong to mild contrast
TWO_TONE_P = 0.5  # share of textures cut into two tones (sharp edges, like tiles or thin geometry)
TINT = 0.3  # each tone's channels vary by up to this factor (coloured textures)
LINE_PERIOD = (3.0, 12.0)  # a grille's spacing between lines, in pixels (the default of data.albedo_line_period)
LINE_DUTY = (0.1, 0.4)  # the share of that spacing a line covers: hairlines ... bars
CROSSED_P = 0.5  # share of grilles with a second set of lines across the first (a mesh)
SUPERSAMPLE = 4  # a grille is box-filtered from this many samples a pixel side, as a renderer's pixel


def texture(seed: int, size: int, lines: float = 0.0, period: tuple[float, float] = LINE_PERIOD) -> Tensor:
    """A ``(3, size, size)`` albedo in ``[low, 1]`` drawn from ``seed`` alone (float32, CPU).

    With probability ``lines`` it is a grille of thin lines (:func:`grille`, its spacing uniform in ``period``
    pixels), else a noise texture; with ``lines`` 0 (the default) no choice is drawn, so a seed gives the texture
    it gave before grilles existed.

    Examples:
        >>> t = texture(7, 16)
        >>> t.shape, bool(t.min() > 0), bool(t.max() <= 1)
        (torch.Size([3, 16, 16]), True, True)
    """
    g = torch.Generator().manual_seed(int(seed))
    if lines > 0.0 and float(torch.rand(1, generator=g, dtype=torch.float64)) < lines:
        return _grille(g, size, period)
    u = torch.rand(4, generator=g, dtype=torch.float64).tolist()
    beta = BETA_RANGE[0] + (BETA_RANGE[1] - BETA_RANGE[0]) * u[0]
    low = LOW_RANGE[0] + (LOW_RANGE[1] - LOW_RANGE[0]) * u[1]
    two_tone = u[2] < TWO_TONE_P
    noise = torch.randn(size, size, generator=g, dtype=torch.float64)
    tints = 1.0 - TINT * torch.rand(2, 3, generator=g, dtype=torch.float64)
    fy = torch.fft.fftfreq(size, dtype=torch.float64).view(-1, 1)
    fx = torch.fft.rfftfreq(size, dtype=torch.float64).view(1, -1)
    f = torch.sqrt(fx * fx + fy * fy)
    amplitude = torch.where(f > 0, f.clamp_min(1.0 / size) ** (-beta / 2.0), torch.zeros_like(f))
    field = torch.fft.irfft2(torch.fft.rfft2(noise) * amplitude, s=(size, size))
    field = (field - field.mean()) / field.std(correction=0).clamp_min(1e-12)
    t = (field > 0).to(field) if two_tone else 0.5 * (1.0 + torch.erf(field / math.sqrt(2.0)))
    return _tones(t, low, tints)


def grille(seed: int, size: int, period: tuple[float, float] = LINE_PERIOD) -> Tensor:
    """A ``(3, size, size)`` albedo of thin dark lines on a bright ground: ``texture(seed, size, lines=1)``.

    One set of parallel lines at a random angle, spacing (uniform in ``period`` pixels; at the pixel grid's limit,
    2 pixels and below, a mesh shows as a moire, as a fine shadow lattice does), width (:data:`LINE_DUTY`)
    and phase, or two sets crossed (:data:`CROSSED_P`); box-filtered from :data:`SUPERSAMPLE` ² samples a
    pixel, so lines narrower than a pixel come out grey, as a rendered pixel shows them.

    Examples:
        >>> t = grille(7, 16)
        >>> t.shape, bool(t.min() > 0), bool(t.max() <= 1)
        (torch.Size([3, 16, 16]), True, True)
    """
    g = torch.Generator().manual_seed(int(seed))
    torch.rand(1, generator=g, dtype=torch.float64)  # the choice of kind that texture() draws first
    return _grille(g, size, period)


def check_min_spp(spp) -> int:
    """``spp`` as an int if it is a whole number >= 0; else a one-line ``ValueError`` naming ``data.albedo_min_spp``."""
    return check_whole(spp, "data.albedo_min_spp", 0, "samples per pixel", " (0: every image)")


def check_line_period(period) -> tuple[float, float]:
    """``(lo, hi)`` as floats if ``1 <= lo <= hi``; else a one-line ``ValueError`` naming ``data.albedo_line_period``."""
    return check_range(period, "data.albedo_line_period", "pixels between a grille's lines", 1)


def _grille(g: torch.Generator, size: int, period_range: tuple[float, float] = LINE_PERIOD) -> Tensor:
    u = torch.rand(2, generator=g, dtype=torch.float64).tolist()
    low = LOW_RANGE[0] + (LOW_RANGE[1] - LOW_RANGE[0]) * u[0]
    tints = 1.0 - TINT * torch.rand(2, 3, generator=g, dtype=torch.float64)
    n = size * SUPERSAMPLE
    c = (torch.arange(n, dtype=torch.float64) + 0.5) / SUPERSAMPLE  # sample positions, in pixels
    y, x = c.view(-1, 1), c.view(1, -1)
    covered = torch.zeros(n, n, dtype=torch.bool)
    for _ in range(2 if u[1] < CROSSED_P else 1):
        angle, period, duty, phase = torch.rand(4, generator=g, dtype=torch.float64).tolist()
        angle *= math.pi
        period = period_range[0] + (period_range[1] - period_range[0]) * period
        duty = LINE_DUTY[0] + (LINE_DUTY[1] - LINE_DUTY[0]) * duty
        s = (x * math.cos(angle) + y * math.sin(angle)) / period + phase
        covered |= (s - torch.floor(s)) < duty
    line = torch.nn.functional.avg_pool2d(covered.to(torch.float64)[None, None], SUPERSAMPLE)[0, 0]
    return _tones(1.0 - line, low, tints)


def _tones(t: Tensor, low: float, tints: Tensor) -> Tensor:
    """``(3, H, W)`` float32: the dark tone ``low * tints[0]`` where ``t`` is 0, the bright ``tints[1]`` where 1."""
    dark = low * tints[0].view(3, 1, 1)
    bright = tints[1].view(3, 1, 1)
    return (dark + (bright - dark) * t).to(torch.float32)


def sample_albedo(generator: torch.Generator, p: float) -> int | None:
    """With probability ``p``, the seed of one patch's texture (:func:`texture`); else ``None``.

    Nothing is drawn from ``generator`` when ``p`` is 0, so switching the augmentation off leaves
    every other draw of a training item as it was.
    """
    if p <= 0.0:
        return None
    u, seed = torch.rand(1, generator=generator, dtype=torch.float64), torch.randint(0, 2**31 - 1, (1,), generator=generator)
    return int(seed) if float(u) < p else None


def check_albedo_p(p: float) -> float:
    """``p`` as a float in [0, 1], or a one-line ``ValueError`` naming ``data.albedo_p``."""
    return check_share(p, "data.albedo_p", "the albedo textures")


def check_albedo_lines(p: float) -> float:
    """``p`` as a float in [0, 1], or a one-line ``ValueError`` naming ``data.albedo_lines``."""
    return check_share(p, "data.albedo_lines", "the grilles")
