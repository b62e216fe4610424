"""``unet_fast`` that predicts SSIM's unknowns, not SSIM: the map is composed from the image's own statistics.

SSIM of a render ``x = s + n`` (signal and zero-mean noise) against its converged reference ``y = s``
needs, in each window, ``x``'s mean and variance -- which the image itself gives exactly -- and two
things only the reference knows: how much of ``x``'s local variance is noise, and how far the mean moved
(the tone map is not linear, so noise shifts the displayed mean; a sparse render is darker or brighter
than its reference). With ``r`` the noise share of the variance and ``d`` the mean's shift,

    mu_y = mu_x + d,  var_y = cov_xy = (1 - r) var_x

(the noise uncorrelated with the signal), and SSIM follows from :func:`nriqa.core.ssim.ssim_from_moments`.
The network (:class:`nriqa.models.unet_fast.UNetFast`, two output maps) predicts ``r`` (a sigmoid) and
``d`` per pixel; how visible a given noise is in a flat or a busy window, and how dark or bright it is
around it, are then arithmetic instead of something each scene family must teach. Its receptive field
and alignment are ``unet_fast``'s (the 11x11 SSIM window lies well inside it).
"""

from __future__ import annotations

from torch import Tensor, nn

from nriqa.core.ssim import local_moments, ssim_from_moments
from nriqa.core.tonemap import luminance
from nriqa.models import init_keras_, register_model
from nriqa.models.unet_fast import UNetFast

__all__ = ["UNetSSIM", "composed_ssim", "ssim_from_unknowns", "unet_fast_ssim"]


class UNetSSIM(UNetFast):
    """``(B,3,H,W)`` LDR image -> ``(B,1,H,W)`` SSIM map in [0, 1] from a predicted noise share and mean shift."""

    def __init__(self, width: int = 32, depth: int = 3, window: int = 0):
        super().__init__(width=width, depth=depth, in_channels=3, window=window)
        # two full-resolution maps: the noise share's logit and the mean's shift
        self.head = nn.Sequential(nn.Conv2d(self.head[0].in_channels, 8, 1), nn.PixelShuffle(2))
        init_keras_(self.head)
        self.to(memory_format=self.memory_format)

    def unknowns(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """The noise share of each window's variance, in (0, 1), and the shift of its mean: two ``(B,1,H,W)`` maps."""
        z = super().forward(x)
        return z[:, :1].sigmoid(), z[:, 1:2]

    def forward(self, x: Tensor) -> Tensor:
        return composed_ssim(x, *self.unknowns(x))


def composed_ssim(x: Tensor, share: Tensor, shift: Tensor) -> Tensor:
    """SSIM map of the LDR image ``x`` ``(B,3,H,W)`` given each window's noise share and mean shift ``(B,1,H,W)``.

    ``mu_y = mu_x + shift`` (floored at 0) and ``var_y = cov_xy = (1 - share) var_x``, ``x``'s own local moments.
    """
    return ssim_from_unknowns(*local_moments(luminance(x)), share, shift)


def ssim_from_unknowns(mean: Tensor, var: Tensor, share: Tensor, shift: Tensor) -> Tensor:
    """:func:`composed_ssim` from the image's local moments (:func:`nriqa.core.ssim.local_moments` of its luminance)."""
    signal = var * (1 - share)
    return ssim_from_moments(mean, (mean + shift).clamp_min(0.0), var, signal, signal)


@register_model
def unet_fast_ssim(**kwargs) -> UNetSSIM:
    """:class:`UNetSSIM`: ``unet_fast``'s network predicting SSIM's unknowns, the map composed from the image."""
    return UNetSSIM(**kwargs)
