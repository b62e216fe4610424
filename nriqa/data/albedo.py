"""Training augmentation: a random albedo texture multiplied into the noisy patch and its reference alike.

A held-out scene family with a kind of detail of its own (photographic textures, fine geometry) is read
as noise by a network that learnt from a few families: it has not seen enough textures that mask noise.
This draws a new texture per patch, unlike anything rendered (random-phase noise with a power spectrum
``1 / f ** beta``, smooth or cut into two tones), and multiplies it into the linear radiance of the noisy
image, its twin and its reference alike, as a surface's albedo multiplies the light it reflects, so its
noise. The target is computed afterwards from the textured pair. Training only.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

BETA_RANGE = (1.0, 3.0)  # spectral slope: 1 fine grain ... 3 large smooth blobs
LOW_RANGE = (0.05, 0.7)  # the texture's darkest albedo (its brightest is 1): strong to mild contrast
TWO_TONE_P = 0.5  # share of textures cut into two tones (sharp edges, like tiles or thin geometry)
TINT = 0.3  # each tone's channels vary by up to this factor (coloured textures)


def texture(seed: int, size: int) -> Tensor:
    """A ``(3, size, size)`` albedo in ``[low, 1]`` drawn from ``seed`` alone (float32, CPU).

    Examples:
        >>> t = texture(7, 16)
        >>> t.shape, bool(t.min() > 0), bool(t.max() <= 1)
        (torch.Size([3, 16, 16]), True, True)
    """
    g = torch.Generator().manual_seed(int(seed))
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
    """``p`` as a float in [0, 1], or a one-line ``ValueError``."""
    p = float(p)
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"data.albedo_p={p} is not a probability; use a value in [0, 1] (0 switches the albedo textures off)")
    return p
