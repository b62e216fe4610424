"""Classical no-reference baselines that a learned scorer is compared with (evaluation, thesis ch. 5).

Every baseline is a :class:`Predictor`: ``predict(item) -> Prediction(score, map)``, where an
:class:`Item` is one tone-mapped noisy image (and its independent twin, where the dataset has one).
Nothing is downloaded: the two fitted baselines are fitted here, on our own renders.

=========================  =====  ============  ==============================================
name                       scale  fitted on     score
=========================  =====  ============  ==============================================
``wavelet_sigma``          raw    --            noise sigma, wavelet MAD (lower = better)
``laplacian``              raw    --            mean squared Laplacian (lower = better); map
``niqe``                   raw    references    NIQE distance to our references' MVG (lower = better)
``brisque``                ssim   noisy images  ridge regression of the 36 BRISQUE features to SSIM
``dual_buffer``            ssim   --            mean SSIM of the image against its twin; map
``dual_buffer_corrected``  ssim   --            the same, bias-corrected per pixel, 2S/(1+S); map
=========================  =====  ============  ==============================================

"raw" scores are not on the SSIM scale: evaluation correlates them with the sign that makes
higher mean better, and maps them to SSIM with :mod:`nriqa.eval.baselines.mapping`, fitted on the
training scenes, for the MAE.
"""

from __future__ import annotations

import abc
import dataclasses
import math

from torch import Tensor

from nriqa.io.manifest import Record
from nriqa.registry import Registry


@dataclasses.dataclass(frozen=True)
class Item:
    """One noisy image to score.

    Attributes:
        record: its manifest record (``record.scene`` is the fold unit).
        ldr: tone-mapped LDR ``(3, H, W)`` in [0, 1].
        twin: the tone-mapped independent twin ``(3, H, W)`` (same algorithm and spp, another seed), or None.
        true: the true score, mean SSIM map against the reference (NaN where unknown).
        albedo: the scene variant's albedo pass ``(3, H, W)`` in [0, 1] where the dataset has one, or None.
    """

    record: Record
    ldr: Tensor
    twin: Tensor | None = None
    true: float = math.nan
    albedo: Tensor | None = None


@dataclasses.dataclass(frozen=True)
class Prediction:
    """A predicted pooled ``score`` and, for map predictors, the ``(H, W)`` quality ``map``."""

    score: float
    map: Tensor | None = None


class Predictor(abc.ABC):
    """Interface of everything evaluation compares: the baselines and the learned scorers.

    Attributes:
        name: the row label of the comparison table.
        scale: ``"ssim"`` (the score estimates mean SSIM) or ``"raw"`` (any monotone quality score).
        higher_is_better: the score's sign: True when a higher score means a better image.
        fitted: True when :meth:`fit` must see the training scenes before :meth:`predict`.
    """

    name = "predictor"
    scale = "raw"
    higher_is_better = True
    fitted = False

    def fit(self, items: list[Item], references: list[Tensor]) -> None:
        """Fit on the training scenes: their noisy ``items`` (with true scores) and reference LDRs ``(3, H, W)``.

        Most predictors need no fitting: the default does nothing.
        """

    @abc.abstractmethod
    def predict(self, item: Item) -> Prediction:
        """Score one image (NaN when the predictor cannot, e.g. no twin)."""


def _load_baselines() -> None:
    from nriqa.eval.baselines.brisque import Brisque
    from nriqa.eval.baselines.dual_buffer import DualBuffer, DualBufferCorrected
    from nriqa.eval.baselines.laplacian import LaplacianEnergy
    from nriqa.eval.baselines.niqe import Niqe
    from nriqa.eval.baselines.wavelet_sigma import WaveletSigma

    for cls in (WaveletSigma, LaplacianEnergy, Niqe, Brisque, DualBuffer, DualBufferCorrected):
        BASELINES.register(cls, name=cls.name)


# In table order; the classes are imported on first use, so importing the package stays light.
BASELINES: Registry[type[Predictor]] = Registry("baseline", loader=_load_baselines, sort=False)


def baseline_names() -> list[str]:
    """Names of the shipped baselines, in table order."""
    return BASELINES.names()


def create_baseline(name: str, **kwargs) -> Predictor:
    """Build the baseline ``name``; ``kwargs`` go to its class.

    Raises:
        nriqa.errors.NriqaError: unknown name (the message lists the valid ones).
    """
    return BASELINES.create(name, **kwargs)
