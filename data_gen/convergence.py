"""Does an algorithm converge to the scene's reference? A blockwise bias test with the twin.

For the top rung's test image ``a`` and its independent twin ``b``, ``m = (a + b) / 2`` is an
estimate of the algorithm's expected image and ``(a - b) / 2`` has the same per-pixel variance as
``m``. Over blocks of pixels, the mean difference ``m - reference`` divided by its standard error
(from the twin difference, plus the reference's own noise) is a z-score: about N(0, 1) where the
algorithm converges to the reference, large where it is biased (e.g. particle tracing that never
sees a glass object). The verdict uses robust summaries of |z| so that fireflies do not decide it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

LUMA = np.array([0.2989, 0.587, 0.114], dtype=np.float64)  # thesis eq. 4.1, as nriqa.tonemap.luminance


@dataclasses.dataclass(frozen=True)
class Convergence:
    """Block z-scores summary: median |z|, fraction of blocks with |z| > 4, relative mean bias."""

    median_abs_z: float
    frac_outliers: float
    relative_bias: float

    @property
    def converged(self) -> bool:
        """Median |z| of N(0,1) is 0.67 and |z| > 4 has probability 6e-5.

        Caustics seen at a few spp are heavy-tailed: where both images miss a rare bright path,
        the twin underestimates the variance, so a minority of outlier blocks is tolerated; a
        biased algorithm (a region it cannot render) fails on a larger area.
        """
        return self.median_abs_z < 1.5 and self.frac_outliers < 0.2


def _blocks(x: np.ndarray, block: int) -> np.ndarray:
    h, w = (x.shape[0] // block) * block, (x.shape[1] // block) * block
    return x[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))


def convergence(test: np.ndarray, twin: np.ndarray, reference: np.ndarray, reference_ratio: float, block: int = 4) -> Convergence:
    """Compare ``(H, W, 3)`` linear images; ``reference_ratio`` = reference spp / test spp."""
    a, b, r = (np.asarray(x, dtype=np.float64) @ LUMA for x in (test, twin, reference))
    m = (a + b) / 2
    half_diff_sq = ((a - b) / 2) ** 2
    d = _blocks(m - r, block)
    # var(m) per pixel ~ half_diff_sq; the reference adds var(m) * 2 / reference_ratio.
    var = _blocks(half_diff_sq, block) / block**2 * (1 + 2 / reference_ratio)
    floor = (1e-4 * max(r.mean(), 1e-6)) ** 2
    z = np.abs(d) / np.sqrt(var + floor)
    bias = abs(m.mean() - r.mean()) / max(r.mean(), 1e-6)
    return Convergence(float(np.median(z)), float((z > 4).mean()), float(bias))
