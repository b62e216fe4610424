"""nriqa.eval.unknowns: a composed-SSIM model's error split into its noise share and its mean shift."""

import pytest
import torch
from torch import nn

from nriqa.core.ssim import pair_moments, ssim_from_moments, ssim_map
from nriqa.core.tonemap import luminance
from nriqa.eval.unknowns import UnknownsError, error_split, main, true_unknowns
from nriqa.models import create_model
from nriqa.models.unet_ssim import composed_ssim


def _pair(seed: int = 0, size: int = 40) -> tuple[torch.Tensor, torch.Tensor]:
    """A smooth reference and a noisy, slightly darker render of it, LDR, ``(1,3,H,W)``."""
    g = torch.Generator().manual_seed(seed)
    ramp = torch.linspace(0.2, 0.8, size)
    ref = (ramp[None, :] * ramp[:, None]).expand(1, 3, size, size).contiguous()
    noisy = (0.9 * ref + 0.1 * torch.randn(1, 3, size, size, generator=g)).clamp(0, 1)
    return noisy, ref


def test_pair_moments_are_the_ssim_maps():
    x, y = _pair()
    torch.testing.assert_close(ssim_from_moments(*pair_moments(luminance(x), luminance(y))), ssim_map(x, y))


def test_an_image_against_itself_has_no_noise_and_no_shift():
    x, _ = _pair()
    share, shift = true_unknowns(x, x)
    assert share.abs().max() < 1e-4 and shift.abs().max() < 1e-6
    torch.testing.assert_close(composed_ssim(x, share, shift), torch.ones_like(share), atol=1e-4, rtol=0)


def test_true_unknowns_give_the_references_mean_and_covariance():
    """Composed with the true unknowns, SSIM is exact but for var_y, which the form takes equal to cov_xy."""
    x, y = _pair(1)
    share, shift = true_unknowns(x, y)
    assert ((share >= 0) & (share <= 1)).all()
    mx, my, vx, _, cov = pair_moments(luminance(x), luminance(y))
    expected = ssim_from_moments(mx, my.clamp_min(0), vx, cov.clamp_min(0), cov.clamp_min(0))
    torch.testing.assert_close(composed_ssim(x, share, shift), expected, atol=1e-5, rtol=1e-4)


def test_flat_render_has_share_zero_not_nan():
    x = torch.full((1, 3, 16, 16), 0.4)
    share, shift = true_unknowns(x, torch.rand(1, 3, 16, 16))
    assert torch.isfinite(share).all() and (share == 0).all() and torch.isfinite(shift).all()


class _Oracle(nn.Module):
    """A composed-SSIM 'network' that reads the true unknowns of a fixed reference."""

    def __init__(self, ref: torch.Tensor):
        super().__init__()
        self.ref = ref

    def unknowns(self, x):
        return true_unknowns(x, self.ref)


def test_a_model_that_knows_both_unknowns_is_off_only_by_its_form():
    x, y = _pair(2)
    split = error_split(_Oracle(y), x, y)
    for reading in ("true_shift", "true_share", "true_both"):
        assert split[reading] == pytest.approx(split["predicted"], abs=1e-6)
    assert split["share"] == pytest.approx(split["share_true"])
    assert abs(split["true_both"] - split["truth"]) < 0.05


def test_a_wrong_share_shows_in_the_share_reading_only():
    """Reading twice the true noise share: the true share fixes it, the true shift does not."""
    x, y = _pair(3)

    class Doubled(_Oracle):
        def unknowns(self, x):
            share, shift = true_unknowns(x, self.ref)
            return (2 * share).clamp(max=1), shift

    split = error_split(Doubled(y), x, y)
    assert split["predicted"] < split["true_share"] - 0.05
    assert split["true_shift"] == pytest.approx(split["predicted"], abs=1e-6)
    assert split["true_share"] == pytest.approx(split["true_both"], abs=1e-6)


def test_a_model_that_predicts_ssim_itself_is_refused():
    x, y = _pair()
    with pytest.raises(UnknownsError, match="composed-SSIM"):
        error_split(create_model("unet_fast", width=8, depth=1), x, y)


def _checkpoint(path, name: str):
    net = create_model(name, width=8, depth=1)
    state = {f"net.{k}": v for k, v in net.state_dict().items()}
    torch.save({"hyper_parameters": {"net": {"name": name, "width": 8, "depth": 1}}, "state_dict": state}, path)
    return path


def test_command_prints_and_writes_the_split(synthetic_dataset, tmp_path, capsys):
    ckpt = _checkpoint(tmp_path / "s.ckpt", "unet_fast_ssim")
    out = tmp_path / "split.md"
    main([str(synthetic_dataset), "--checkpoint", str(ckpt), "--out", str(out)])
    text = capsys.readouterr().out
    assert "| all |" in text and "true_share_mae" in text
    assert out.read_text().splitlines()[2].startswith("| all |")


def test_command_errors_are_one_line(synthetic_dataset, tmp_path):
    with pytest.raises(SystemExit, match="error: .*no folds"):
        main([str(synthetic_dataset), "--crossval", str(tmp_path)])
    ckpt = _checkpoint(tmp_path / "u.ckpt", "unet_fast")
    with pytest.raises(SystemExit, match="error: .*predicts SSIM itself"):
        main([str(synthetic_dataset), "--checkpoint", str(ckpt)])
    with pytest.raises(SystemExit, match="error: .*no test image"):
        main(
            [
                str(synthetic_dataset),
                "--checkpoint",
                str(_checkpoint(tmp_path / "s.ckpt", "unet_fast_ssim")),
                "--scenes",
                "nothing",
            ]
        )
