"""The composed-SSIM map model: its map is SSIM of the image's own moments under the predicted unknowns."""

import pytest
import torch

from nriqa.core.ssim import local_moments, ssim_from_moments, ssim_map
from nriqa.core.tonemap import luminance
from nriqa.models import create_model
from nriqa.models.unet_ssim import UNetSSIM


def test_moments_match_the_ssim_map():
    """ssim_map built from local_moments of each image and of their product equals ssim_map itself."""
    torch.manual_seed(0)
    x, y = torch.rand(2, 1, 30, 27, dtype=torch.float64), torch.rand(2, 1, 30, 27, dtype=torch.float64)
    mx, vx = local_moments(x)
    my, vy = local_moments(y)
    mxy, _ = local_moments(x * y)
    torch.testing.assert_close(ssim_from_moments(mx, my, vx, vy, mxy - mx * my), ssim_map(x, y))


def test_moments_of_a_constant_image_are_exact():
    mean, var = local_moments(torch.full((1, 1, 16, 16), 0.3))
    torch.testing.assert_close(mean, torch.full_like(mean, 0.3))
    assert (var == 0).all()


def _fixed(share: float, shift: float) -> UNetSSIM:
    """A model whose network says ``share`` and ``shift`` everywhere (head weights zero, biases set)."""
    model = UNetSSIM(width=8, depth=1).eval()
    with torch.no_grad():
        conv = model.head[0]
        conv.weight.zero_()
        logit = torch.logit(torch.tensor(share))
        conv.bias.copy_(torch.tensor([logit] * 4 + [shift] * 4))
    return model


@pytest.mark.parametrize("share,shift", [(0.5, 0.0), (0.2, 0.05), (0.9, -0.1)])
def test_map_is_ssim_of_the_composed_moments(share, shift):
    torch.manual_seed(1)
    x = torch.rand(2, 3, 40, 40)
    with torch.inference_mode():
        got = _fixed(share, shift)(x)
    mean, var = local_moments(luminance(x))
    want = ssim_from_moments(mean, (mean + shift).clamp_min(0), var, (1 - share) * var, (1 - share) * var)
    torch.testing.assert_close(got, want)


def test_no_noise_no_shift_reads_converged_and_all_noise_reads_low():
    x = torch.rand(1, 3, 48, 48)
    with torch.inference_mode():
        clean = _fixed(1e-6, 0.0)(x)
        noise = _fixed(1 - 1e-6, 0.0)(x)
    assert clean.min() > 0.999
    assert noise.mean() < 0.1  # uniform random pixels: variance 1/12, far above SSIM's C2


def test_flat_images_read_converged_and_the_map_stays_in_range():
    model = create_model("unet_fast_ssim").eval()
    with torch.inference_mode():
        for value in (0.0, 0.5, 1.0):
            y = model(torch.full((1, 3, 32, 32), value))
            assert torch.isfinite(y).all() and (y >= 0).all() and (y <= 1).all()
        y = model(torch.rand(2, 3, 37, 45))
    assert y.shape == (2, 1, 37, 45) and (y >= 0).all() and (y <= 1).all()
    assert model.receptive_field == create_model("unet_fast").receptive_field
    with pytest.raises(TypeError):
        create_model("unet_fast_ssim", in_channels=6)


def test_trains_toward_a_target():
    """A few Adam steps lower the error to a target map: the gradient reaches the network through the formula."""
    torch.manual_seed(2)
    model = UNetSSIM(width=8, depth=1)
    x = torch.rand(4, 3, 32, 32)
    target = torch.full((4, 1, 32, 32), 0.7)
    opt = torch.optim.Adam(model.parameters(), lr=1e-2)
    first = None
    for _ in range(30):
        loss = (model(x) - target).abs().mean()
        first = float(loss.detach()) if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float(loss.detach()) < 0.5 * first
