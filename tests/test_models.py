"""Models of thesis ch. 5 and their registry: parameter counts, shapes, receptive fields."""

import pytest
import torch
from torch import nn

from nriqa.models import create_model, list_models, register_model

MAP_MODELS = ["fcnn", "fcnn11", "fcnn_fast"]
PARAMS = {
    "dual_fast": 28_036,
    "patch_cnn": 8_553_889,
    "fcnn": 1_896_577,
    "fcnn11": 2_487_169,
    "fcnn_fast": 90_052,
    "map_mean": 2 * 371_700,
    "unet_fast": 371_700,
    "unet_fast_albedo": 375_156,
    "unet_fast_ssim": 371_832,
    "unet_fast_twin": 375_156,
}


def n_trainable(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def test_registry_lists_all_models():
    assert list_models() == sorted(PARAMS)
    assert list_models("fcnn*") == MAP_MODELS


def test_unknown_model_lists_valid_names():
    with pytest.raises(ValueError, match="unknown model 'vgg'.*fcnn.*patch_cnn"):
        create_model("vgg")


def test_duplicate_registration_raises():
    def fcnn():
        return nn.Identity()

    with pytest.raises(ValueError, match="already registered"):
        register_model(fcnn)


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_parameter_count(name):
    assert n_trainable(create_model(name)) == PARAMS[name]


def test_patch_cnn_shape_and_range():
    model = create_model("patch_cnn").eval()
    with torch.inference_mode():
        y = model(torch.rand(5, 3, 32, 32))
    assert model.output == "patch" and y.shape == (5, 1)
    assert torch.isfinite(y).all() and (y >= 0).all()


@pytest.mark.parametrize("shape", [(3, 31, 32), (3, 64, 64), (1, 32, 32), (32, 32)])
def test_patch_cnn_rejects_other_sizes(shape):
    with pytest.raises(ValueError, match="patch_cnn takes"):
        create_model("patch_cnn")(torch.rand(1, *shape))


def test_patch_cnn_trains_in_train_mode():
    model = create_model("patch_cnn").train()
    model(torch.rand(4, 3, 32, 32)).sum().backward()
    assert model.features[2].alpha.grad is not None


@pytest.mark.parametrize("name", MAP_MODELS)
@pytest.mark.parametrize("hw", [(64, 64), (37, 53), (1, 1), (2, 7)])
def test_map_shape_and_range(name, hw):
    model = create_model(name).eval()
    with torch.inference_mode():
        y = model(torch.rand(1, 3, *hw))
    assert model.output == "map" and y.shape == (1, 1, *hw)
    assert torch.isfinite(y).all() and (y >= 0).all()


@pytest.mark.parametrize("name", MAP_MODELS)
def test_map_rejects_non_rgb(name):
    with pytest.raises(ValueError, match="RGB batch"):
        create_model(name)(torch.rand(1, 1, 16, 16))


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_eval_is_deterministic(name):
    torch.manual_seed(0)
    a = create_model(name).eval()
    torch.manual_seed(0)
    b = create_model(name).eval()
    c = getattr(a, "in_channels", 3)
    x = torch.rand(2, 3, 32, 32) if name == "patch_cnn" else torch.rand(2, c, 8, 11)
    with torch.inference_mode():
        y = a(x)
        assert torch.equal(y, a(x))
        assert torch.equal(y, b(x))


def _changed_box(model: nn.Module, pixel: tuple[int, int], size: int = 32) -> tuple[slice, slice]:
    """Rows and columns of the output that change when one input pixel changes."""
    x = torch.rand(1, 3, size, size, dtype=torch.float64)
    x2 = x.clone()
    x2[..., pixel[0], pixel[1]] += 1.0
    with torch.inference_mode():
        changed = (model(x2) != model(x))[0, 0]
    rows, cols = changed.any(1).nonzero()[:, 0], changed.any(0).nonzero()[:, 0]
    return slice(int(rows.min()), int(rows.max()) + 1), slice(int(cols.min()), int(cols.max()) + 1)


@pytest.mark.parametrize("name", MAP_MODELS)
@pytest.mark.parametrize("pixel", [(16, 16), (15, 17)])
def test_receptive_field_is_exact(name, pixel):
    # Positive weights and inputs keep every ReLU open, so every dependency shows in the output.
    torch.manual_seed(1)
    model = create_model(name).double().eval()
    with torch.no_grad():
        for p in model.parameters():
            p.uniform_(0.01, 0.1)
    rows, cols = _changed_box(model, pixel)
    rf = model.receptive_field
    for span, p in ((rows, pixel[0]), (cols, pixel[1])):
        assert span.stop - span.start == rf
        assert span.start <= p < span.stop
        if model.align == 1:
            assert span.start == p - rf // 2
        else:  # the window of a block model covers at least the centred (rf - 1) window
            assert span.start <= p - (rf - 1) // 2 and p + (rf - 1) // 2 < span.stop


@pytest.mark.parametrize("name", MAP_MODELS)
def test_receptive_field_bounds_random_model(name):
    torch.manual_seed(2)
    model = create_model(name).double().eval()
    rows, cols = _changed_box(model, (16, 16))
    for span in (rows, cols):
        assert span.stop - span.start <= model.receptive_field


def test_patch_cnn_output_starts_alive_at_the_target_scale():
    """Glorot-initialised, the last layer starts at +-2 and Adam kills the ReLU output at once."""
    import torch

    from nriqa.models import create_model

    torch.manual_seed(0)
    net = create_model("patch_cnn").eval()
    with torch.no_grad():
        out = net(torch.rand(64, 3, 32, 32))
    assert (out > 0).float().mean() > 0.9
    assert 0.0 < out.mean() < 0.2 and out.std() < 0.1


def test_map_mean_is_the_mean_of_its_members_and_refuses_a_mixed_pair():
    torch.manual_seed(0)
    a, b = (create_model("unet_fast", width=8, depth=1, window=32).eval() for _ in range(2))
    mean = create_model("map_mean", members=[a, b]).eval()
    x = torch.rand(2, 3, 48, 40)
    with torch.inference_mode():
        torch.testing.assert_close(mean(x), (a(x) + b(x)) / 2)
    assert (mean.window, mean.in_channels, mean.align, mean.min_size) == (32, 3, 4, a.min_size)
    from_specs = create_model("map_mean", members=[{"name": "unet_fast", "window": 64}] * 3)
    assert len(from_specs.members) == 3 and from_specs.receptive_field == 206
    with pytest.raises(ValueError, match="at least two"):
        create_model("map_mean", members=[a])
    unstated = create_model("unet_fast", width=8, depth=1)
    with pytest.raises(ValueError, match="agree on in_channels and window"):
        create_model("map_mean", members=[a, unstated])
    assert create_model("map_mean", members=[a, unstated], window=64).window == 64  # stated for the pair
    with pytest.raises(ValueError, match="map models only"):
        create_model("map_mean", members=[a, create_model("patch_cnn")])
