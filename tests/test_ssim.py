import numpy as np
import pytest
import torch
from skimage.metrics import structural_similarity

from nriqa.core.mae import patch_mae
from nriqa.core.ssim import flat_windows, ssim_map
from nriqa.core.tonemap import luminance


def _skimage_map(a: torch.Tensor, b: torch.Tensor) -> np.ndarray:
    _, full = structural_similarity(
        a.numpy(), b.numpy(), gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1, full=True
    )
    return np.clip(full, 0, 1)


@pytest.fixture
def pair():
    g = torch.Generator().manual_seed(0)
    ref = torch.rand(2, 3, 24, 30, generator=g, dtype=torch.float64)
    ref = torch.nn.functional.avg_pool2d(ref, 3, stride=1, padding=1)  # some structure
    noisy = (ref + 0.15 * torch.randn(ref.shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    return noisy, ref


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_matches_skimage_on_interior(pair, dtype):
    noisy, ref = pair
    ours = ssim_map(noisy.to(dtype), ref.to(dtype))
    assert ours.shape == (2, 1, 24, 30) and ours.dtype == dtype
    for i in range(2):
        expected = _skimage_map(luminance(noisy[i])[0], luminance(ref[i])[0])
        diff = np.abs(ours[i, 0].double().numpy() - expected)[5:-5, 5:-5]
        assert diff.max() < 1e-5
    assert ours.min() < 0.9  # the noise is visible: the comparison is not trivial


def test_gray_input_same_as_rgb_luminance(pair):
    noisy, ref = pair
    torch.testing.assert_close(ssim_map(noisy, ref), ssim_map(luminance(noisy), luminance(ref)))


def test_identical_is_one_and_symmetric(pair):
    noisy, ref = pair
    torch.testing.assert_close(ssim_map(ref, ref), torch.ones(2, 1, 24, 30, dtype=ref.dtype))
    torch.testing.assert_close(ssim_map(noisy, ref), ssim_map(ref, noisy))


def test_range_and_constant_images():
    x = torch.zeros(1, 3, 16, 16)
    y = torch.full((1, 3, 16, 16), 0.5)
    for a, b in ((x, x), (x, y), (y, y)):
        out = ssim_map(a, b)
        assert torch.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
    torch.testing.assert_close(ssim_map(y, y), torch.ones(1, 1, 16, 16))
    assert ssim_map(x, y).max() < 0.1
    anti = torch.rand(1, 1, 16, 16)
    assert ssim_map(anti, 1 - anti).min() >= 0  # negative SSIM is clipped to 0


def test_gradient_flows():
    x = torch.rand(1, 3, 12, 12, requires_grad=True)
    ssim_map(x, torch.rand(1, 3, 12, 12)).mean().backward()
    assert torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0


def test_errors():
    with pytest.raises(ValueError, match="same shape"):
        ssim_map(torch.rand(1, 3, 16, 16), torch.rand(1, 3, 16, 15))
    with pytest.raises(ValueError, match=r"\(B, 3, H, W\)"):
        ssim_map(torch.rand(3, 16, 16), torch.rand(3, 16, 16))
    with pytest.raises(ValueError, match=r"\(B, 3, H, W\)"):
        ssim_map(torch.rand(1, 2, 16, 16), torch.rand(1, 2, 16, 16))
    with pytest.raises(ValueError, match="at least"):
        ssim_map(torch.rand(1, 1, 5, 16), torch.rand(1, 1, 5, 16))
    with pytest.raises(TypeError):
        ssim_map(torch.zeros(1, 1, 8, 8, dtype=torch.uint8), torch.zeros(1, 1, 8, 8, dtype=torch.uint8))


def test_patch_mae():
    x = torch.zeros(2, 3, 4, 4)
    y = torch.zeros(2, 3, 4, 4)
    y[0] = 0.5
    y[1, 0] = 0.3  # one channel of three
    torch.testing.assert_close(patch_mae(x, y), torch.tensor([0.5, 0.1]))
    torch.testing.assert_close(patch_mae(y, x), patch_mae(x, y))
    with pytest.raises(ValueError, match="same shape"):
        patch_mae(x, y[:1])
    with pytest.raises(ValueError, match=r"\(B, C, H, W\)"):
        patch_mae(x[0], y[0])


def _flat_brute_force(x: torch.Tensor, floor: float = 0.1) -> torch.Tensor:
    b, _, h, w = x.shape
    out = torch.zeros(b, h, w, dtype=torch.bool)
    lum = luminance(x)[:, 0]
    for i in range(h):
        for j in range(w):
            win = x[:, :, max(0, i - 5) : i + 6, max(0, j - 5) : j + 6]
            dx = (win[..., :, 1:] - win[..., :, :-1]).abs().amax(dim=(1, 2, 3))
            dy = (win[..., 1:, :] - win[..., :-1, :]).abs().amax(dim=(1, 2, 3))
            out[:, i, j] = (dx <= 1e-6) & (dy <= 1e-6) & (lum[:, i, j] >= floor)
    return out


@pytest.mark.parametrize("h, w", [(30, 37), (6, 6), (7, 40), (25, 11)])
def test_flat_windows_match_their_definition(h, w):
    g = torch.Generator().manual_seed(h * w)
    x = torch.rand(2, 3, h, w, generator=g)
    x[0, :, 1:, 0:20] = 0.5  # flat grey touching three borders
    x[1, :, h // 3 :, w // 3 :] = torch.tensor([0.9, 0.2, 0.1])[:, None, None]  # a flat colour in a corner
    x[1, :, -1, -1] += 5e-7  # within the step tolerance
    assert torch.equal(flat_windows(x), _flat_brute_force(x))


def test_flat_windows_leave_dark_out_and_hold_white():
    assert not flat_windows(torch.zeros(1, 3, 16, 16)).any()  # black: not reached yet, not converged
    assert not flat_windows(torch.full((1, 3, 16, 16), 0.099)).any()
    assert flat_windows(torch.full((1, 3, 16, 16), 0.101)).all()
    x = torch.rand(1, 3, 30, 30, generator=torch.Generator().manual_seed(3))
    x[..., 0:20, 5:25] = 1.0  # clipped white is flat at level 1, a float sRGB curve's white too
    x[0, 0, 19, 24] = 1 - 6e-8
    want = torch.zeros(30, 30, dtype=torch.bool)
    want[0:15, 10:20] = True  # 5 px in from the block's inner edges; the image border does not count
    assert torch.equal(flat_windows(x)[0], want)
    checker = (torch.arange(16)[:, None] + torch.arange(16)[None, :]) % 2
    assert not flat_windows((1 - checker * 2**-16).expand(1, 3, 16, 16)).any()  # 16-bit steps are not flat
    # Where a window is flat and the reference has the same colour there, the SSIM is exactly 1.
    x[..., 20:, :] = 0.4
    ref = x.clone()
    ref[..., 0:4, 25:] = 0.0
    assert torch.all(ssim_map(x, ref)[0, 0][flat_windows(x)[0]] == 1)
