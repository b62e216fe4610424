r"""Dual-buffer estimate: SSIM of an image against its independent twin (the single-image scorer's target).

A Monte Carlo renderer can write two images ``a`` and ``b`` of the same scene with independent
seeds (two half buffers). Neither is the reference, but their disagreement is pure noise, so

    SSIM(tonemap(a), tonemap(b))  predicts  SSIM(tonemap(a), reference).

Derivation (one SSIM window, noise small enough that the tone map is locally linear): write
``a = r + n_a``, ``b = r + n_b`` with ``n_a``, ``n_b`` independent, zero mean, local variance
``s^2`` each, and local reference variance ``v``. Means agree (``mu_a ~ mu_b ~ mu_r``), so the
luminance factor is ~1 in both cases and the structure factors are

    SSIM(a, r) ~ (2v + C2) / (2v +   s^2 + C2)
    SSIM(a, b) ~ (2v + C2) / (2v + 2 s^2 + C2)

Hence SSIM(a, b) <= SSIM(a, r), both fall monotonically as ``s^2`` grows, and SSIM(a, b) equals
SSIM(a, r) at twice the noise variance, i.e. the true SSIM of an image with **half** the samples
(variance ~ 1/spp). It is therefore a rank-preserving, slightly pessimistic estimate of the true
score, computed by exactly the same :func:`nriqa.core.ssim.ssim_map` as the target. It needs a second
render, which is what a learned single-image scorer is meant to avoid: it is the bar to approach.

The bias can be undone pixel by pixel under the same assumptions: with ``X = 2v + C2`` and
``y = s^2``, ``S_ab = X / (X + 2y)`` gives ``y / X = (1 / S_ab - 1) / 2`` and so

    S_ar = X / (X + y) = 2 S_ab / (1 + S_ab)

(:func:`correct_dual_buffer`; ``dual_buffer_corrected``). It is exact only where the luminance
factor is 1 and the noise is zero-mean with equal variance in both buffers; where the tone map's
nonlinearity or clipping at 0 break that, it is an approximation.
"""

from __future__ import annotations

import math

from torch import Tensor

from nriqa.core.ssim import correct_dual_buffer, ssim_map
from nriqa.eval.baselines import Item, Prediction, Predictor


def dual_buffer_map(a: Tensor, b: Tensor) -> Tensor:
    """SSIM map of two tone-mapped independent renders ``(3, H, W)`` of the same image: ``(H, W)``."""
    return ssim_map(a[None], b[None])[0, 0]


class DualBuffer(Predictor):
    """Score = mean SSIM of the image vs its twin (SSIM scale, lower-biased); map = that SSIM map.

    Returns NaN for images without a twin (e.g. an external folder of single renders).
    """

    name = "dual_buffer"
    scale = "ssim"
    higher_is_better = True

    def predict(self, item: Item) -> Prediction:
        if item.twin is None:
            return Prediction(math.nan)
        m = dual_buffer_map(item.ldr, item.twin)
        return Prediction(float(m.mean()), m)


class DualBufferCorrected(DualBuffer):
    """Score = mean of :func:`correct_dual_buffer` of the twin SSIM map (SSIM scale, bias removed); map = that map."""

    name = "dual_buffer_corrected"

    def predict(self, item: Item) -> Prediction:
        if item.twin is None:
            return Prediction(math.nan)
        m = correct_dual_buffer(dual_buffer_map(item.ldr, item.twin))
        return Prediction(float(m.mean()), m)
