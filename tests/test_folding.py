"""Batch norm folded into the convolutions: same outputs, fewer layers, the original untouched."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from nriqa.inference.folding import fold_batchnorm
from nriqa.inference.scorer import Scorer
from nriqa.models import create_model, list_models


def _randomise_batchnorm(net: nn.Module, seed: int = 0) -> None:
    """Running statistics and affine parameters far from their defaults, so folding is not an identity."""
    g = torch.Generator().manual_seed(seed)
    for m in net.modules():
        if isinstance(m, nn.BatchNorm2d):
            n = m.num_features
            m.running_mean.copy_(torch.randn(n, generator=g))
            m.running_var.copy_(torch.rand(n, generator=g) * 3 + 0.05)
            m.weight.data.copy_(torch.randn(n, generator=g))
            m.bias.data.copy_(torch.randn(n, generator=g))


def _count(net: nn.Module, kind: type) -> int:
    return sum(isinstance(m, kind) for m in net.modules())


@pytest.mark.parametrize("name", sorted(set(list_models()) - {"map_mean"}) + ["map_mean"])
def test_folded_model_gives_the_same_output(name):
    torch.manual_seed(0)
    net = create_model(name).eval()
    _randomise_batchnorm(net)
    before = {k: v.clone() for k, v in net.state_dict().items()}
    folded = fold_batchnorm(net)
    assert _count(net, nn.BatchNorm2d) > 0
    assert _count(folded, nn.BatchNorm2d) == 0
    assert _count(folded, nn.Conv2d) == _count(net, nn.Conv2d)
    side = 32 if name == "patch_cnn" else max(64, int(getattr(net, "min_size", net.receptive_field)))
    x = torch.rand(2, int(getattr(net, "in_channels", 3)), side, side)
    with torch.inference_mode():
        want, got = net(x), folded(x)
    assert torch.allclose(got, want, rtol=1e-4, atol=1e-4 * float(want.abs().max()))
    # the original is left as it was: weights, batch norms, attributes
    assert all(torch.equal(before[k], v) for k, v in net.state_dict().items())
    for attr in ("output", "receptive_field", "window", "align", "min_size", "in_channels"):
        assert getattr(folded, attr, None) == getattr(net, attr, None)


def test_only_a_batchnorm_right_after_a_convolution_is_folded():
    net = nn.Sequential(nn.Conv2d(3, 4, 3), nn.ReLU(), nn.BatchNorm2d(4), nn.Conv2d(4, 4, 1), nn.BatchNorm2d(4))
    folded = fold_batchnorm(net)
    assert [type(m) for m in folded] == [nn.Conv2d, nn.ReLU, nn.BatchNorm2d, nn.Conv2d, nn.Identity]
    assert net[4].__class__ is nn.BatchNorm2d and net[2].__class__ is nn.BatchNorm2d


def test_scorer_runs_a_folded_copy_and_leaves_the_net_alone():
    torch.manual_seed(1)
    net = create_model("unet_fast")
    _randomise_batchnorm(net, seed=1)
    net.train()
    scorer = Scorer(net, exact_flat=False)
    assert net.training and _count(net, nn.BatchNorm2d) > 0  # the user's net: mode and layers unchanged
    assert _count(scorer.net, nn.BatchNorm2d) == 0 and not scorer.net.training
    image = torch.rand(3, 64, 64)
    with torch.inference_mode():
        want = net.eval()(image[None])[0, 0].clamp(0, 1)
    got = scorer(image, hdr=False).map
    assert torch.allclose(got, want, atol=1e-5)
