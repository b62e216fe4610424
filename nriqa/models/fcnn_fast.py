"""A fast FCNN for CPU inference: the experiment II task (thesis ch. 5) at a fraction of the cost.

Design (chosen by measuring candidates on a 2-core CPU; see ``benchmarks/model_throughput.py``):

* PixelUnshuffle(2): each 2x2 block of RGB pixels becomes one 12-channel pixel. Lossless, so every
  input value is still seen, but the convolutions run on a quarter of the positions.
* 3 x [Conv3x3(64)-BN-ReLU] at half resolution, 2 x [Conv1x1(64)-BN-ReLU], Conv1x1(4),
  PixelShuffle(2): each output pixel of a block has its own head weights, so the map is full
  resolution and not an upsampled one.
* Final ReLU: scores in [0, inf), like ``fcnn``.

Three 3x3 layers over 2x2 blocks span 7 blocks = 14 pixels: every output pixel sees a 14x14
window that always contains its centred 13x13 window, more than the 11x11 SSIM window the
target is computed with (``fcnn``: 9x9). Odd sizes are zero-padded to even on the bottom/right
and cropped back. 90,052 parameters; about 1.2 % of the multiply-adds of ``fcnn`` per pixel.
Tiles must start at even offsets (``align = 2``) for tiled == untiled. Dense 3x3 convolutions at
64 channels and the channels-last (NHWC) layout were chosen by measuring the alternatives
(depthwise-separable convolutions, NCHW) with ``benchmarks/model_throughput.py``.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from nriqa.models import init_keras_, register_model
from nriqa.models.fcnn import block_trunk, check_image_batch

__all__ = ["FCNNFast", "fcnn_fast"]


class FCNNFast(nn.Module):
    """Fast FCNN (experiment II task, thesis ch. 5): ``(B,3,H,W)`` -> ``(B,1,H,W)`` >= 0, any H, W.

    ``n3x3`` Conv3x3(``width``)-BN-ReLU blocks and ``n1x1`` Conv1x1(``width``)-BN-ReLU blocks run on
    2x2 pixel blocks (PixelUnshuffle / PixelShuffle). Receptive field ``4 * n3x3 + 2`` pixels.
    """

    output = "map"
    align = 2

    def __init__(self, width: int = 64, n3x3: int = 3, n1x1: int = 2):
        super().__init__()
        if n3x3 < 1:
            raise ValueError(f"FCNNFast needs at least one 3x3 block, got n3x3={n3x3}")
        s = self.align
        self.net = nn.Sequential(
            nn.PixelUnshuffle(s),
            *block_trunk(3 * s * s, width, n3x3, n1x1),
            nn.Conv2d(width, s * s, 1),
            nn.PixelShuffle(s),
            nn.ReLU(),
        )
        self.receptive_field = s * (2 * n3x3 + 1)
        init_keras_(self)
        # oneDNN's CPU convolutions run faster on NHWC than NCHW at these widths.
        self.memory_format = torch.channels_last
        self.to(memory_format=self.memory_format)

    def forward(self, x: Tensor) -> Tensor:
        """``x``: ``(B,3,H,W)``; returns ``(B,1,H,W)``."""
        check_image_batch(x, "fcnn_fast")
        h, w = x.shape[-2:]
        s = self.align
        ph, pw = -h % s, -w % s
        if ph or pw:
            x = F.pad(x, (0, pw, 0, ph))
        y = self.net(x.contiguous(memory_format=self.memory_format))
        return y[..., :h, :w].contiguous()


@register_model
def fcnn_fast(**kwargs) -> FCNNFast:
    """Fast FCNN: 14x14 receptive field on 2x2 blocks, 90,052 parameters; see :class:`FCNNFast`."""
    return FCNNFast(**kwargs)
