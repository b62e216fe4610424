import dataclasses
import math

import pytest
import torch

from nriqa.data.jitter import VAL_STOPS, JitterParams, apply_jitter, check_value_mode, jitter_pair, sample_jitter


def _img(h=6, w=9, seed=0, batch=None):
    g = torch.Generator().manual_seed(seed)
    shape = (3, h, w) if batch is None else (batch, 3, h, w)
    return torch.rand(shape, generator=g)


def test_identity():
    x = _img()
    assert torch.equal(apply_jitter(x, JitterParams()), x)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_hsv_round_trip(dtype):
    x = _img().to(dtype)
    # a full turn of hue and a vanishing shift both go through RGB -> HSV -> RGB
    for p in (JitterParams(hue_shift=1.0), JitterParams(sat_shift=1e-12)):
        out = apply_jitter(x, p)
        assert out.dtype == dtype
        torch.testing.assert_close(out, x, atol=1e-5, rtol=0)


def test_hue_shift_turns_red_into_green_and_blue():
    red = torch.zeros(3, 2, 2)
    red[0] = 1.0
    green = apply_jitter(red, JitterParams(hue_shift=1 / 3))
    blue = apply_jitter(red, JitterParams(hue_shift=2 / 3))
    torch.testing.assert_close(green[:, 0, 0], torch.tensor([0.0, 1.0, 0.0]), atol=1e-5, rtol=0)
    torch.testing.assert_close(blue[:, 0, 0], torch.tensor([0.0, 0.0, 1.0]), atol=1e-5, rtol=0)


def test_saturation_and_value_shifts_clip():
    x = torch.tensor([0.8, 0.4, 0.2]).view(3, 1, 1)
    grey = apply_jitter(x, JitterParams(sat_shift=-1.0))
    torch.testing.assert_close(grey.flatten(), torch.full((3,), 0.8), atol=1e-6, rtol=0)
    brighter = apply_jitter(x, JitterParams(val_shift=0.3))
    assert brighter.max().item() == pytest.approx(1.0)
    torch.testing.assert_close(brighter.flatten(), x.flatten() / 0.8, atol=1e-6, rtol=0)


def test_geometry_on_non_square():
    x = torch.arange(2 * 3, dtype=torch.float32).view(1, 2, 3).expand(3, 2, 3).clone() / 10
    flipped = apply_jitter(x, JitterParams(flip=True))
    assert torch.equal(flipped[0], torch.tensor([[0.2, 0.1, 0.0], [0.5, 0.4, 0.3]]))
    rot = apply_jitter(x, JitterParams(rot_k=1))  # counter-clockwise: top-right corner goes top-left
    assert rot.shape == (3, 3, 2)
    assert torch.equal(rot[0], torch.tensor([[0.2, 0.5], [0.1, 0.4], [0.0, 0.3]]))
    assert torch.equal(apply_jitter(x, JitterParams(rot_k=2))[0], x[0].flip(0).flip(1))
    both = apply_jitter(x, JitterParams(flip=True, rot_k=3))
    assert torch.equal(both, torch.rot90(x.flip(-1), 3, dims=(-2, -1)))


def test_batched_same_as_per_image():
    xb = _img(batch=3)
    p = JitterParams(hue_shift=0.4, sat_shift=0.1, val_shift=-0.2, flip=True, rot_k=1)
    out = apply_jitter(xb, p)
    for i in range(3):
        torch.testing.assert_close(out[i], apply_jitter(xb[i], p))


def test_sample_ranges_and_flags():
    g = torch.Generator().manual_seed(3)
    draws = [sample_jitter(g) for _ in range(400)]
    assert all(0 <= d.hue_shift < 1 and abs(d.sat_shift) <= 0.3 and abs(d.val_shift) <= 0.3 for d in draws)
    assert {d.rot_k for d in draws} == {0, 1, 2, 3}
    flips = sum(d.flip for d in draws)
    assert 150 < flips < 250
    assert min(d.sat_shift for d in draws) < -0.25 and max(d.val_shift for d in draws) > 0.25
    off = sample_jitter(torch.Generator().manual_seed(3), hsv=False, geometric=False)
    assert off == JitterParams()
    # switching a part off leaves the other part's draw unchanged
    full = sample_jitter(torch.Generator().manual_seed(4))
    colour = sample_jitter(torch.Generator().manual_seed(4), geometric=False)
    assert (colour.hue_shift, colour.flip, colour.rot_k) == (full.hue_shift, False, 0)
    with pytest.raises(TypeError, match="Generator"):
        sample_jitter(42)


def test_pair_same_draw_range_and_seed():
    x = _img(8, 8)
    ref = _img(8, 8, seed=1)
    for seed in range(10):
        a, b = jitter_pair(x, x.clone(), torch.Generator().manual_seed(seed))
        assert torch.equal(a, b)
        assert a.min() >= 0 and a.max() <= 1
        n1, r1 = jitter_pair(x, ref, torch.Generator().manual_seed(seed))
        n2, r2 = jitter_pair(x, ref, torch.Generator().manual_seed(seed))
        assert torch.equal(n1, n2) and torch.equal(r1, r2)
        p = sample_jitter(torch.Generator().manual_seed(seed))
        assert torch.equal(r1, apply_jitter(ref, p))
    outs = {tuple(jitter_pair(x, ref, torch.Generator().manual_seed(s))[0].flatten()[:4].tolist()) for s in range(5)}
    assert len(outs) == 5  # different seeds, different draws


def test_no_augmentation_is_exact():
    x = _img()
    a, b = jitter_pair(x, x * 0.5, torch.Generator().manual_seed(0), hsv=False, geometric=False)
    assert torch.equal(a, x) and torch.equal(b, x * 0.5)


def test_errors():
    with pytest.raises(ValueError, match="same shape"):
        jitter_pair(_img(8, 8), _img(8, 9), torch.Generator())
    with pytest.raises(ValueError, match="3, H, W"):
        apply_jitter(torch.rand(4, 8, 8), JitterParams())
    with pytest.raises(TypeError):
        apply_jitter(torch.zeros(3, 4, 4, dtype=torch.uint8), JitterParams())


def test_hue_is_modular():
    x = _img()
    twice = apply_jitter(apply_jitter(x, JitterParams(hue_shift=0.5)), JitterParams(hue_shift=0.25))
    torch.testing.assert_close(apply_jitter(x, JitterParams(hue_shift=0.75)), twice, atol=1e-5, rtol=0)


def test_value_switch_drops_only_the_value_shift():
    """value=False: hue, saturation and the geometric draw exactly as with it; the value shift 0."""
    for seed in range(5):
        with_value = sample_jitter(torch.Generator().manual_seed(seed))
        without = sample_jitter(torch.Generator().manual_seed(seed), value=False)
        assert without.val_shift == 0.0 and with_value.val_shift != 0.0
        assert dataclasses.replace(with_value, val_shift=0.0) == without
    # a dark image: the value shift is what moves its black pixels; without it black stays black
    dark = torch.zeros(3, 4, 4)
    p = sample_jitter(torch.Generator().manual_seed(1), value=False)
    assert torch.equal(apply_jitter(dark, dataclasses.replace(p, flip=False, rot_k=0)), dark)


def test_value_scale_multiplies_value_from_the_same_draw():
    """value="scale": the same random numbers as "add", value multiplied by 2^U(-0.7, 0.7) instead of shifted."""
    factors = []
    for seed in range(40):
        add = sample_jitter(torch.Generator().manual_seed(seed))
        scale = sample_jitter(torch.Generator().manual_seed(seed), value="scale")
        assert scale.val_shift == 0.0
        assert dataclasses.replace(add, val_shift=0.0, val_scale=scale.val_scale) == scale
        # the same uniform number: shift / 0.3 == log2(scale) / 0.7
        assert add.val_shift / 0.3 == pytest.approx(math.log2(scale.val_scale) / VAL_STOPS)
        factors.append(scale.val_scale)
    assert 2.0**-VAL_STOPS <= min(factors) < 1.0 < max(factors) <= 2.0**VAL_STOPS
    # a grey pixel's value is multiplied (hue and saturation of a grey stay 0), clipped at 1
    grey = torch.full((3, 2, 2), 0.5)
    out = apply_jitter(grey, JitterParams(val_scale=1.5))
    torch.testing.assert_close(out, torch.full((3, 2, 2), 0.75))
    torch.testing.assert_close(apply_jitter(grey, JitterParams(val_scale=2.5)), torch.ones(3, 2, 2))


def test_value_scale_keeps_a_dark_sparse_render_dark():
    """Black stays black under a scale (the additive shift lifts it to the same grey in both images)."""
    img = torch.zeros(3, 8, 8)
    img[:, 2, 3] = torch.tensor([0.6, 0.3, 0.1])
    for seed in range(10):
        p = dataclasses.replace(sample_jitter(torch.Generator().manual_seed(seed), value="scale"), flip=False, rot_k=0)
        out = apply_jitter(img, p)
        assert torch.equal(out[:, img.sum(0) == 0], img[:, img.sum(0) == 0])
        assert float(out.max()) > 0.0
    lifted = apply_jitter(img, JitterParams(val_shift=0.2))
    assert float(lifted[:, 0, 0].max()) == pytest.approx(0.2)


@pytest.mark.parametrize(
    "value, mode", [(True, "add"), (False, "off"), ("add", "add"), ("scale", "scale"), ("off", "off")]
)
def test_value_modes(value, mode):
    assert check_value_mode(value) == mode


@pytest.mark.parametrize("bad", ["multiply", 1, None, "Scale"])
def test_value_mode_refused_in_one_line(bad):
    with pytest.raises(ValueError) as info:
        check_value_mode(bad)
    assert "data.jitter.value" in str(info.value) and "\n" not in str(info.value)


def test_the_datamodule_takes_the_value_mode_and_refuses_an_unknown_one(synthetic_dataset):
    from nriqa.data.datamodule import NRIQADataModule

    dm = NRIQADataModule(synthetic_dataset, batch_size=4, jitter={"hsv": True, "geometric": True, "value": "scale"})
    dm.setup("fit")
    assert dm.train_set.value == "scale"
    draws = [dm.train_set.draw(k).jitter for k in range(8)]
    assert all(d.val_shift == 0.0 and d.val_scale != 1.0 for d in draws)
    with pytest.raises(ValueError, match="data.jitter.value must be one of add, scale, off"):
        NRIQADataModule(synthetic_dataset, jitter={"value": "multiply"})
