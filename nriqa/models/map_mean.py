"""The mean of several map models' outputs: one recipe trained with different seeds, averaged.

A single-image model's per-scene offsets move with its training seed (two ``unet_fast`` seeds read
the same external scene up to 0.04 apart: docs/results/evaluation.md); the mean of the members'
maps cancels part of that spread, at the members' summed cost. Members must take the same input
and be read the same way (``in_channels``, ``window``); the receptive field, smallest input and
alignment are the largest / least common multiple of theirs, so tiled maps still equal untiled ones.

    >>> net = create_model("map_mean", members=[{"name": "unet_fast", "window": 64}] * 2)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from torch import Tensor, nn

from nriqa.models import create_model, register_model

__all__ = ["MapMean", "map_mean"]


class MapMean(nn.Module):
    """``(B,C,H,W)`` -> the mean of the members' ``(B,1,H,W)`` maps.

    ``members``: model specs (``{"name": ..., **kwargs}``, what shipped weights store) or built
    networks (e.g. trained checkpoints' nets, for evaluation). ``window``: the side of the pieces
    the Scorer reads the mean in; by default the members' own, on which they must then agree.
    """

    output = "map"

    def __init__(self, members: Sequence[Mapping | nn.Module], window: int | None = None):
        super().__init__()
        if len(members) < 2:
            raise ValueError(f"map_mean averages at least two members, got {len(members)}")
        nets = [m if isinstance(m, nn.Module) else create_model(**dict(m)) for m in members]
        if any(getattr(n, "output", None) != "map" for n in nets):
            raise ValueError("map_mean averages map models only (output 'map')")
        channels = {int(getattr(n, "in_channels", 3)) for n in nets}
        windows = {int(getattr(n, "window", 0) or 0) for n in nets} if window is None else {int(window)}
        if len(channels) > 1 or len(windows) > 1:
            raise ValueError(f"map_mean members must agree on in_channels and window, got {channels} and {windows}")
        self.members = nn.ModuleList(nets)
        self.in_channels, self.window = channels.pop(), windows.pop()
        self.receptive_field = max(int(n.receptive_field) for n in nets)
        self.min_size = max(int(getattr(n, "min_size", n.receptive_field)) for n in nets)
        self.align = math.lcm(*(int(getattr(n, "align", 1)) for n in nets))

    def forward(self, x: Tensor) -> Tensor:
        out = self.members[0](x)
        for member in self.members[1:]:
            out = out + member(x)
        return out / len(self.members)


@register_model
def map_mean(
    members: Sequence[Mapping] = ({"name": "unet_fast"}, {"name": "unet_fast"}), window: int | None = None
) -> MapMean:
    """:class:`MapMean` of the given member specs (default: two ``unet_fast``)."""
    return MapMean(members, window)
