"""Training augmentation: a renderer's pixel (reconstruction) filter, emulated on box-filtered renders.

Every rendered dataset here is box-filtered (each sample counts for its own pixel, its noise its own), but
renderers spread each sample over neighbouring pixels by default: Mitsuba's film filters with a Gaussian
of standard deviation 0.5 pixel cut at 4 of them. Such noise is correlated between neighbours, smoother,
and a network that learnt only box-filtered noise reads it as converged (measured in stop 56: the external
Cornell boxes through Mitsuba's Gaussian, MAE 0.22, 2 spp read 0.98). This draws, per training patch, a
Gaussian filter of Mitsuba's form with a random standard deviation and applies it to the noisy image, its
twin and its reference alike, before the display and the target: the box pixels convolved with the
filter's weight integrated over each pixel (the weight a renderer gives them on average over where in its
pixel each sample fell). A renderer's own weights vary with where its samples fell, so at the same
standard deviation its pixels are a little noisier and less alike than the emulation's (Mitsuba's 0.5:
neighbour correlation 0.36 against 0.47 in a test render); ``SIGMA_RANGE`` is drawn wide about it, and
the test suite checks that Mitsuba's filter lies inside the family. Training only.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor

from nriqa.data.options import check_range, check_share

SIGMA_RANGE = (0.3, 0.8)  # standard deviations in pixels: Mitsuba's 0.5 inside, narrower and wider about it
TRUNCATE = 4.0  # Mitsuba's gaussian filter ends at 4 standard deviations
_SUBSAMPLES = 64  # points per pixel integrating the filter's weight


def gaussian_weight(x: Tensor, sigma: float) -> Tensor:
    """Mitsuba's ``gaussian`` rfilter: ``max(0, exp(-x^2 / 2 sigma^2) - exp(-r^2 / 2 sigma^2))``, ``r = 4 sigma``."""
    radius = TRUNCATE * sigma
    bias = math.exp(-(radius**2) / (2 * sigma**2))
    return (torch.exp(-(x**2) / (2 * sigma**2)) - bias).clamp_min(0.0)


def kernel_1d(sigma: float) -> Tensor:
    """The separable taps (float64, summing to 1) a box-filtered image is convolved with to give ``sigma``'s filter.

    Tap ``d`` is the filter's weight integrated over the pixel ``d`` away, ``[d - 1/2, d + 1/2]``.

    Examples:
        >>> k = kernel_1d(0.5)
        >>> len(k), round(float(k.sum()), 6), round(float(k[2]), 3)
        (5, 1.0, 0.683)
    """
    if not 0.0 < sigma <= 4.0:
        raise ValueError(f"pixel filter sigma={sigma}: give a standard deviation in (0, 4] pixels")
    reach = math.ceil(TRUNCATE * sigma - 0.5)
    offsets = torch.arange(-reach, reach + 1, dtype=torch.float64)
    within = (torch.arange(_SUBSAMPLES, dtype=torch.float64) + 0.5) / _SUBSAMPLES - 0.5
    taps = gaussian_weight(offsets[:, None] + within[None, :], sigma).mean(dim=1)
    return taps / taps.sum()


def apply_pixel_filter(x: Tensor, sigma: float) -> Tensor:
    """``(B, C, H, W)`` images through ``sigma``'s filter (separable, reflected at the borders)."""
    k = kernel_1d(sigma).to(x)
    reach = (len(k) - 1) // 2
    if reach == 0:
        return x.clone()
    b, c, h, w = x.shape
    flat = x.reshape(b * c, 1, h, w)
    flat = F.conv2d(F.pad(flat, (reach, reach, 0, 0), mode="reflect"), k.view(1, 1, 1, -1))
    flat = F.conv2d(F.pad(flat, (0, 0, reach, reach), mode="reflect"), k.view(1, 1, -1, 1))
    return flat.reshape(b, c, h, w)


# Renders made through a filter already (the manifest's ``pixel_filter``) and the emulated filter of the same
# spread, for what is laid onto them afterwards: Mitsuba's ``gaussian`` defaults to a standard deviation of 0.5.
RENDERED_SIGMA = {"gaussian": 0.5}


def rendered_sigma(pixel_filter: str) -> float | None:
    """The emulated standard deviation standing for a render's own filter; ``None`` for box or one not emulated."""
    return RENDERED_SIGMA.get(pixel_filter)


def sample_pixel_filter(
    generator: torch.Generator, p: float, sigma_range: tuple[float, float] = SIGMA_RANGE
) -> float | None:
    """With probability ``p``, a standard deviation uniform in ``sigma_range``; else ``None``.

    Nothing is drawn from ``generator`` when ``p`` is 0, so switching the augmentation off leaves every
    other draw of a training item as it was.
    """
    if p <= 0.0:
        return None
    u, s = torch.rand(2, generator=generator, dtype=torch.float64).tolist()
    lo, hi = sigma_range
    return lo + (hi - lo) * s if u < p else None


def check_pixel_filter(p: float, sigma_range) -> tuple[float, tuple[float, float]]:
    """``(p, (lo, hi))`` if ``p`` is a share and ``0 < lo <= hi <= 4``; else a one-line ``ValueError``."""
    p = check_share(p, "data.pixel_filter_p", "the pixel filter")
    return p, check_range(sigma_range, "data.pixel_filter_sigma", "pixels (the filter's standard deviation)", 0, 4, True)
