"""The encoder-decoder map model: shapes, receptive field bound, channels, determinism."""

import pytest
import torch

from nriqa.models import create_model
from nriqa.models.unet_fast import UNetFast, receptive_field


def _span(model, size, pixel, channels):
    """Rows/cols of the input the output pixel depends on (positive weights keep every ReLU open)."""
    x = torch.rand(1, channels, size, size, dtype=torch.float64, requires_grad=True)
    model(x)[0, 0, pixel[0], pixel[1]].backward()
    g = x.grad.abs().sum(dim=(0, 1))
    rows, cols = g.any(1).nonzero()[:, 0], g.any(0).nonzero()[:, 0]
    return (int(rows.min()), int(rows.max()) + 1), (int(cols.min()), int(cols.max()) + 1)


@pytest.mark.parametrize("depth", [1, 2])
@pytest.mark.parametrize("pixel", [(128, 128), (127, 129)])
def test_receptive_field_bounds_the_dependency(depth, pixel):
    torch.manual_seed(0)
    model = UNetFast(width=8, depth=depth).double().eval()
    with torch.no_grad():
        for p in model.parameters():
            p.uniform_(0.01, 0.1)
    for lo, hi in _span(model, 256, pixel, 3):
        assert hi - lo <= model.receptive_field == receptive_field(depth)
        assert hi - lo >= model.receptive_field * 0.85  # a bound, but not a loose one
        assert lo <= pixel[0] < hi


@pytest.mark.parametrize("hw", [(32, 32), (37, 45), (130, 96)])
def test_any_size_map_out(hw):
    model = create_model("unet_fast").eval()
    with torch.no_grad():
        y = model(torch.rand(2, 3, *hw))
    assert y.shape == (2, 1, *hw) and (y >= 0).all()


def test_twin_takes_six_channels_and_refuses_three():
    model = create_model("unet_fast_twin").eval()
    with torch.no_grad():
        assert model(torch.rand(1, 6, 40, 40)).shape == (1, 1, 40, 40)
    with pytest.raises(ValueError, match=r"expects \(B,6,H,W\)"):
        model(torch.rand(1, 3, 40, 40))


def test_bad_construction_is_refused():
    with pytest.raises(ValueError):
        UNetFast(depth=0)
    with pytest.raises(ValueError):
        UNetFast(in_channels=4)


def test_eval_is_deterministic():
    model = create_model("unet_fast").eval()
    x = torch.rand(1, 3, 64, 64)
    with torch.inference_mode():
        assert torch.equal(model(x), model(x))


def test_window_is_stated_not_used_by_forward():
    torch.manual_seed(0)
    plain, stated = UNetFast(width=8, depth=1), UNetFast(width=8, depth=1, window=32)
    stated.load_state_dict(plain.state_dict())
    x = torch.rand(1, 3, 80, 80)
    with torch.inference_mode():
        assert torch.equal(plain.eval()(x), stated.eval()(x))
    assert stated.window == 32 and plain.window == 0
    with pytest.raises(ValueError, match="window"):
        UNetFast(window=-1)
