"""Wavelet noise sigma: the classical single-image noise estimate as a quality score.

Donoho & Johnstone's robust estimator, as :func:`skimage.restoration.estimate_sigma` computes it:
``sigma = median(|d|) / Phi^-1(0.75)`` over the nonzero coefficients ``d`` of the finest
diagonal (HH) sub-band of a Daubechies-2 wavelet transform. skimage needs PyWavelets, which is not
a dependency of nriqa, so the one sub-band is computed here (separable db2 high-pass, decimated
by 2, interior coefficients only, no boundary extension); on interior pixels it is the same sub-band.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import correlate1d
from scipy.stats import norm

from nriqa.baselines import Item, Prediction, Predictor
from nriqa.baselines.nss import gray255

# Daubechies-2 decomposition high-pass filter (pywt.Wavelet("db2").dec_hi); unit norm, so white
# noise of variance s^2 keeps variance s^2 in the HH sub-band.
DB2_HIGH = np.array([-0.48296291314469025, 0.836516303737469, -0.22414386804185735, -0.12940952255092145])


def diagonal_detail(gray: np.ndarray) -> np.ndarray:
    """The finest diagonal db2 sub-band of a grey ``(H, W)`` image, ``(~H/2, ~W/2)``, interior only."""
    hh = correlate1d(correlate1d(gray, DB2_HIGH, axis=0, mode="constant"), DB2_HIGH, axis=1, mode="constant")
    k = len(DB2_HIGH)
    return hh[k : gray.shape[0] - k : 2, k : gray.shape[1] - k : 2]


def wavelet_sigma(gray: np.ndarray) -> float:
    """Noise standard deviation of a grey ``(H, W)`` image (same units as the input; 0 for a noise-free flat image)."""
    d = diagonal_detail(np.asarray(gray, dtype=np.float64))
    d = d[d != 0]
    return float(np.median(np.abs(d)) / norm.ppf(0.75)) if d.size else 0.0


class WaveletSigma(Predictor):
    """Score = wavelet noise sigma of the tone-mapped luminance, grey levels 0-255 (lower = better; no map)."""

    name = "wavelet_sigma"
    scale = "raw"
    higher_is_better = False

    def predict(self, item: Item) -> Prediction:
        return Prediction(wavelet_sigma(gray255(item.ldr)))
