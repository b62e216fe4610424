"""A small encoder-decoder for the SSIM-map task: ``fcnn_fast``'s cheap full-resolution head plus context.

``fcnn_fast`` sees a 14x14 window. That is enough to measure local noise, but not to tell a dark,
sparse render (mostly black, a few bright samples: far from converged) from a dark converged one,
nor how bright the surroundings are, which sets how visible the noise is after the tone map.
This model adds a U-Net-style context path (Ronneberger et al. 2015) at 1/4 .. 1/16 resolution,
where it costs little, and keeps ``fcnn_fast``'s design at full resolution:

* PixelUnshuffle(2) (lossless 2x2 blocks), 2 x [Conv3x3(``width``)-BN-ReLU] at 1/2 resolution;
* ``depth`` levels of AvgPool(2) + 2 x [Conv3x3-BN-ReLU], widths ``width * (1, 1.5, 2, ...)``;
* back up by bilinear upsampling (x2), concatenation with the skip, Conv3x3-BN-ReLU, per level;
* Conv1x1(4) + PixelShuffle(2): a full-resolution map; final ReLU.

``in_channels`` may be 6 for the two-buffer scorer (the image and an independent render of it,
stacked). With ``albedo`` the last three channels are the scene's albedo pass (what renderers give
their denoisers; nearly noise-free, it tells texture and geometry from noise): 6 channels for the
image and its albedo, 9 with the twin too. Inputs of any size are zero-padded bottom/right to a
multiple of ``align`` and cropped back. The receptive field is computed from the layers
(:func:`receptive_field`), so tiling halos follow it and tiled maps equal untiled ones.

``window``: the side of the images the weights learnt from (0: not stated). The receptive field
(206 px at depth 3) outgrows a 64x64 training image, so on larger images the context path meets
surroundings it never saw in training; :class:`nriqa.inference.scorer.Scorer` then reads the image
in independent ``window``-side pieces. It changes nothing in ``forward``.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from nriqa.models import init_keras_, register_model
from nriqa.models.fcnn import conv_bn_relu

__all__ = ["UNetFast", "unet_fast", "unet_fast_albedo", "unet_fast_twin", "receptive_field"]


def receptive_field(depth: int) -> int:
    """Side in pixels of the window one output pixel depends on, for ``depth`` pooling levels.

    Counted in 1/2-resolution block units and converted: two 3x3 convs at 1/2 (radius 2); each level
    ``l`` (scale ``2**l`` blocks) adds AvgPool (radius ``2**(l-1)``), two 3x3 convs (radius
    ``2 * 2**l``), the bilinear upsample back (radius ``2**(l-1)``) and the 3x3 conv after the
    concatenation at the finer scale (radius ``2**(l-1)``). The block itself spans 2 pixels.
    """
    radius = 2
    for level in range(1, depth + 1):
        radius += 2 ** (level - 1) * 3 + 2 * 2**level
    return 2 * (2 * radius + 1)


class UNetFast(nn.Module):
    """Encoder-decoder SSIM-map model: ``(B,C,H,W)`` -> ``(B,1,H,W)`` >= 0, any H, W (``C`` = ``in_channels``)."""

    output = "map"

    def __init__(self, width: int = 32, depth: int = 3, in_channels: int = 3, window: int = 0, albedo: bool = False):
        super().__init__()
        if window < 0:
            raise ValueError(f"UNetFast's window is a side in pixels (0: none), got {window}")
        self.window = int(window)
        if depth < 1:
            raise ValueError(f"UNetFast needs depth >= 1, got {depth}")
        if in_channels - 3 * bool(albedo) not in (3, 6):
            takes = "6 (image + albedo) or 9 (+ twin)" if albedo else "3 (image) or 6 (image + twin)"
            raise ValueError(f"UNetFast takes {takes} channels, got {in_channels}")
        self.in_channels = in_channels
        self.albedo = bool(albedo)
        self.align = 2 ** (depth + 1)
        self.receptive_field = receptive_field(depth)
        # Context helps, but is not needed: any image of two coarsest cells a side is worth scoring.
        self.min_size = 2 * self.align
        widths = [int(width * (1 + 0.5 * level)) for level in range(depth + 1)]
        self.stem = nn.Sequential(*conv_bn_relu(4 * in_channels, widths[0], 3), *conv_bn_relu(widths[0], widths[0], 3))
        self.down = nn.ModuleList(
            nn.Sequential(
                nn.AvgPool2d(2),
                *conv_bn_relu(widths[i], widths[i + 1], 3),
                *conv_bn_relu(widths[i + 1], widths[i + 1], 3),
            )
            for i in range(depth)
        )
        self.up = nn.ModuleList(
            nn.Sequential(*conv_bn_relu(widths[i + 1] + widths[i], widths[i], 3)) for i in range(depth)
        )
        self.head = nn.Sequential(nn.Conv2d(widths[0], 4, 1), nn.PixelShuffle(2), nn.ReLU())
        init_keras_(self)
        self.memory_format = torch.channels_last
        self.to(memory_format=self.memory_format)

    def forward(self, x: Tensor) -> Tensor:
        """``x``: ``(B, in_channels, H, W)``; returns ``(B,1,H,W)``."""
        if x.ndim != 4 or x.shape[1] != self.in_channels:
            raise ValueError(f"unet_fast expects (B,{self.in_channels},H,W), got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        ph, pw = -h % self.align, -w % self.align
        if ph or pw:
            x = F.pad(x, (0, pw, 0, ph))
        skips = [self.stem(F.pixel_unshuffle(x, 2).contiguous(memory_format=self.memory_format))]
        for down in self.down:
            skips.append(down(skips[-1]))
        y = skips.pop()
        for up in reversed(self.up):
            skip = skips.pop()
            y = F.interpolate(y, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            y = up(torch.cat([y, skip], dim=1))
        return self.head(y)[..., :h, :w].contiguous()


@register_model
def unet_fast(**kwargs) -> UNetFast:
    """Encoder-decoder with a full-resolution head (:class:`UNetFast`), one image in."""
    return UNetFast(**kwargs)


@register_model
def unet_fast_twin(**kwargs) -> UNetFast:
    """:class:`UNetFast` on the image and an independent render of it at the same spp (6 channels)."""
    return UNetFast(**{"in_channels": 6, **kwargs})


@register_model
def unet_fast_albedo(**kwargs) -> UNetFast:
    """:class:`UNetFast` on the image and its scene's albedo pass (6 channels)."""
    return UNetFast(**{"in_channels": 6, "albedo": True, **kwargs})
