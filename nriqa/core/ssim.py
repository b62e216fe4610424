"""The SSIM map: the full-reference target of experiment II and of evaluation (thesis ch. 4-5)."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor

from nriqa.core.tonemap import luminance

WINDOW = 11
SIGMA = 1.5
K1 = 0.01
K2 = 0.03
DATA_RANGE = 1.0
# Neighbours closer than this in every channel are the same colour; flat windows darker than FLAT_FLOOR
# (luminance) are not counted as converged (flat_windows).
FLAT_STEP = 1e-6
FLAT_FLOOR = 0.1
FLAT_ROWS = 6  # every window holds one row in FLAT_ROWS (may_be_flat)


def _gaussian_1d(dtype: torch.dtype, device: torch.device) -> Tensor:
    r = torch.arange(WINDOW, dtype=dtype, device=device) - (WINDOW - 1) / 2
    g = torch.exp(-0.5 * (r / SIGMA) ** 2)
    return g / g.sum()


def _as_gray(x: Tensor, name: str) -> Tensor:
    if not isinstance(x, Tensor):
        raise TypeError(f"ssim_map: {name} must be a torch.Tensor, got {type(x).__name__}")
    if not x.is_floating_point():
        raise TypeError(f"ssim_map: {name} must be floating point, got {x.dtype}")
    if x.ndim != 4 or x.shape[1] not in (1, 3):
        raise ValueError(f"ssim_map: {name} must be (B, 3, H, W) RGB or (B, 1, H, W) gray, got {tuple(x.shape)}")
    return luminance(x) if x.shape[1] == 3 else x


def ssim_map(x: Tensor, y: Tensor) -> Tensor:
    r"""Per-pixel SSIM of ``x`` against ``y`` on luminance (thesis ch. 4, target of experiment II).

    .. math::
        \mathrm{SSIM} = \frac{(2\mu_x\mu_y + C_1)(2\sigma_{xy} + C_2)}
                             {(\mu_x^2 + \mu_y^2 + C_1)(\sigma_x^2 + \sigma_y^2 + C_2)},
        \quad C_1 = (K_1 L)^2,\ C_2 = (K_2 L)^2

    with local statistics from an 11x11 Gaussian window, sigma = 1.5 (separable), K1 = 0.01,
    K2 = 0.03, L = 1, population (not sample) covariance. RGB inputs are reduced to luminance
    L = 0.2989 R + 0.587 G + 0.114 B (eq. 4.1) first. The map is clipped to [0, 1].

    Border handling: the output has the input's size; the image is extended by 5 px of reflect
    padding (mirror without repeating the edge pixel, ``torch.nn.functional.pad(mode="reflect")``)
    before filtering. Pixels at least 5 px from the border are unaffected by the padding and match
    ``skimage.metrics.structural_similarity(..., gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False, data_range=1)``; skimage uses symmetric padding, so the outer
    5 px differ slightly. Images must be at least 6x6.

    Args:
        x: ``(B, 3, H, W)`` RGB or ``(B, 1, H, W)`` gray LDR in [0, 1] (e.g. the tone-mapped render).
        y: the reference, same shape as ``x``.

    Returns:
        ``(B, 1, H, W)`` SSIM map in [0, 1]; symmetric in ``x`` and ``y``; 1 where ``x == y``.

    Examples:
        >>> x = torch.rand(2, 3, 16, 16)
        >>> ssim_map(x, x).shape
        torch.Size([2, 1, 16, 16])
    """
    if isinstance(x, Tensor) and isinstance(y, Tensor) and x.shape != y.shape:
        raise ValueError(f"ssim_map: x and y must have the same shape, got {tuple(x.shape)} and {tuple(y.shape)}")
    gx, gy = _as_gray(x, "x"), _as_gray(y, "y")
    h, w = gx.shape[-2:]
    pad = WINDOW // 2
    if h <= pad or w <= pad:
        raise ValueError(f"ssim_map: images must be at least {pad + 1}x{pad + 1} pixels, got {h}x{w}")

    return ssim_from_moments(*pair_moments(gx, gy))


def pair_moments(gx: Tensor, gy: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    """Local means, variances and covariance ``(mu_x, mu_y, var_x, var_y, cov_xy)`` of two ``(B,1,H,W)`` gray images.

    :func:`ssim_map`'s window, padding and population (co)variances; what :func:`ssim_from_moments` takes.
    """
    # (Co)variances are shift-invariant; taking them about each image pair's mean avoids most of
    # the cancellation in E[x^2] - E[x]^2, which matters in float32.
    shift = 0.5 * (gx.mean(dim=(-2, -1), keepdim=True) + gy.mean(dim=(-2, -1), keepdim=True))
    cx, cy = gx - shift, gy - shift
    stats = _window_means(torch.cat([cx, cy, cx * cx, cy * cy, cx * cy], dim=1))
    mcx, mcy, mxx, myy, mxy = stats.split(1, dim=1)
    return mcx + shift, mcy + shift, mxx - mcx * mcx, myy - mcy * mcy, mxy - mcx * mcy


def _window_means(stats: Tensor) -> Tensor:
    """Gaussian-window means (11x11, sigma 1.5, separable) of each channel of ``stats``, reflect-padded by 5 px."""
    pad = WINDOW // 2
    g = _gaussian_1d(stats.dtype, stats.device)
    n = stats.shape[1]
    stats = F.pad(stats, (pad, pad, pad, pad), mode="reflect")
    stats = F.conv2d(stats, g.view(1, 1, 1, WINDOW).expand(n, 1, 1, WINDOW), groups=n)
    return F.conv2d(stats, g.view(1, 1, WINDOW, 1).expand(n, 1, WINDOW, 1), groups=n)


def ssim_from_moments(mx: Tensor, my: Tensor, vx: Tensor, vy: Tensor, cov: Tensor) -> Tensor:
    """SSIM from local means, variances and covariance (the formula of :func:`ssim_map`), clipped to [0, 1]."""
    c1 = (K1 * DATA_RANGE) ** 2
    c2 = (K2 * DATA_RANGE) ** 2
    num = (2 * mx * my + c1) * (2 * cov + c2)
    den = (mx * mx + my * my + c1) * (vx + vy + c2)
    return (num / den).clamp(0.0, 1.0)


def local_moments(gray: Tensor) -> tuple[Tensor, Tensor]:
    """Local mean and variance of ``(B, 1, H, W)`` ``gray`` in :func:`ssim_map`'s window and padding.

    The variance is the population variance, taken about the image's mean (as :func:`ssim_map` does)
    and floored at 0. Images must be at least 6x6.
    """
    shift = gray.mean(dim=(-2, -1), keepdim=True)
    c = gray - shift
    mc, mcc = _window_means(torch.cat([c, c * c], dim=1)).split(1, dim=1)
    return mc + shift, (mcc - mc * mc).clamp_min(0.0)


def correct_dual_buffer(s_ab: Tensor) -> Tensor:
    """Per-pixel estimate of SSIM(a, reference) from the SSIM map of two independent renders ``a``, ``b``.

    ``2 S / (1 + S)``: their disagreement is twice the noise of one against the reference (derived in
    :mod:`nriqa.eval.baselines.dual_buffer`). ``s_ab`` as :func:`ssim_map` gives it, in [0, 1].
    """
    return 2 * s_ab / (1 + s_ab)


def _box_sums(counts: Tensor, rows: tuple[int, int], cols: tuple[int, int], size: tuple[int, int]) -> Tensor:
    """Sums of ``counts`` ``(B, P, Q)`` over ``[i - rows[0], i + rows[1]] x [j - cols[0], j + cols[1]]``
    (clipped to the array) for every output pixel ``(i, j)`` of ``size``; exact (integer prefix sums)."""
    b, p, q = counts.shape
    prefix = torch.zeros(b, p + 1, q + 1, dtype=torch.int64, device=counts.device)
    prefix[:, 1:, 1:] = counts.to(torch.int64).cumsum(1).cumsum(2)
    i = torch.arange(size[0], device=counts.device)
    j = torch.arange(size[1], device=counts.device)
    r0, r1 = (i - rows[0]).clamp(0, p), (i + rows[1] + 1).clamp(0, p)
    c0, c1 = (j - cols[0]).clamp(0, q), (j + cols[1] + 1).clamp(0, q)
    r0, r1, c0, c1 = r0[:, None], r1[:, None], c0[None, :], c1[None, :]
    return prefix[:, r1, c1] - prefix[:, r0, c1] - prefix[:, r1, c0] + prefix[:, r0, c0]


def may_be_flat(rows: Tensor, floor: float = FLAT_FLOOR) -> bool:
    """Could the image whose rows ``0, FLAT_ROWS, 2 FLAT_ROWS, ...`` are ``rows`` hold a flat window?

    Any window holds at least 6 rows (images are >= 6 px), so one of these: a flat window needs a
    bright pixel there the same colour as its right neighbour. Most renders have none, and the test
    reads a sixth of the image (the Scorer prepares only those rows for it).
    """
    same = (rows[..., :, 1:] - rows[..., :, :-1]).abs().amax(dim=1) <= FLAT_STEP
    # (a window's pixels may drift from its centre by 10 steps, so the level test allows for them)
    bright = (luminance(rows) if rows.shape[1] == 3 else rows)[:, 0, :, :-1] >= floor - 20 * FLAT_STEP
    return bool((same & bright).any())


def flat_windows(x: Tensor, floor: float = FLAT_FLOOR) -> Tensor:
    """Pixels whose whole SSIM window is one colour, of luminance at least ``floor``.

    "One colour": every two neighbouring pixels of the window differ by at most ``FLAT_STEP`` (1e-6) in
    every channel; the window is the 11x11 one :func:`ssim_map` filters with, and at the border only
    its in-image part counts, which is what the reflect padding there sees.

    A Monte Carlo render is that flat only where every sample returned the same radiance -- a light
    or a constant background seen directly, a region clipped white (level 1; a float sRGB curve gives
    1 - 6e-8 there, within the step) -- so its reference is the same there and the SSIM is 1. Black
    is left out on purpose: a black window of a noisy render is most often one no sample has reached
    yet (dark, sparse light; on dataset v2 such pixels have true SSIM near 0), and 8-bit steps at low
    levels move SSIM's luminance term, so ``floor`` (0.1) keeps to levels where one 8-bit step costs
    less than 0.001. On dataset v2 every pixel it covers has true SSIM >= 0.993
    (docs/results/evaluation.md, stop 30).

    Args:
        x: ``(B, C, H, W)`` LDR in [0, 1] (e.g. the tone-mapped render); C = 3 (RGB) or 1.
        floor: the least luminance (eq. 4.1, or the gray value) a flat window must have.

    Returns:
        ``(B, H, W)`` bool.
    """
    h, w = x.shape[-2:]
    pad = WINDOW // 2
    if not may_be_flat(x[..., ::FLAT_ROWS, :], floor):
        return torch.zeros(x.shape[0], h, w, dtype=torch.bool, device=x.device)
    step_x = (x[..., :, 1:] - x[..., :, :-1]).abs().amax(dim=1) > FLAT_STEP  # (B, H, W-1): pixel j vs j+1
    step_y = (x[..., 1:, :] - x[..., :-1, :]).abs().amax(dim=1) > FLAT_STEP  # (B, H-1, W)
    level = (luminance(x) if x.shape[1] == 3 else x)[:, 0] >= floor
    # The window of (i, j) holds the horizontal pairs (r, k), k in [j - 5, j + 4], r in [i - 5, i + 5], and
    # the vertical pairs (k, c), k in [i - 5, i + 4], c in [j - 5, j + 5]: none may be a step.
    steps_x = _box_sums(step_x, (pad, pad), (pad, pad - 1), (h, w))
    steps_y = _box_sums(step_y, (pad, pad - 1), (pad, pad), (h, w))
    return level & (steps_x == 0) & (steps_y == 0)
