"""Albedo textures for training: drawn from a seed, multiplied into noisy image and reference alike."""

from __future__ import annotations

import pytest
import torch
from test_batched_patches import MIX, make_dm

from nriqa.data.albedo import LOW_RANGE, check_albedo_p, sample_albedo, texture
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import TONEMAP, item_generator
from nriqa.data.targets import compute_target


def test_a_texture_is_a_function_of_its_seed_and_an_albedo():
    a, b = texture(3, 32), texture(3, 32)
    assert torch.equal(a, b) and a.dtype == torch.float32 and a.shape == (3, 32, 32)
    assert not torch.equal(a, texture(4, 32))
    for seed in range(40):
        t = texture(seed, 24)
        assert bool(torch.isfinite(t).all())
        assert float(t.min()) >= LOW_RANGE[0] * 0.7 - 1e-6 and float(t.max()) <= 1.0
        assert float(t.std()) > 0.0  # never flat: a flat albedo would only dim the patch


def test_textures_come_smooth_and_two_toned():
    distinct = [len(torch.unique(texture(seed, 32)[0])) for seed in range(40)]
    assert min(distinct) <= 2  # two tones, sharp edges
    assert max(distinct) > 100  # smooth


def test_texture_of_one_pixel_and_of_a_large_patch():
    assert texture(1, 1).shape == (3, 1, 1)
    assert bool(torch.isfinite(texture(1, 1)).all())
    assert bool(torch.isfinite(texture(2, 512)).all())


def test_no_albedo_draws_nothing():
    g = item_generator(1, 2)
    state = g.get_state()
    assert sample_albedo(g, 0.0) is None
    assert torch.equal(g.get_state(), state)
    g1 = item_generator(1, 2)
    assert isinstance(sample_albedo(g1, 1.0), int)


@pytest.mark.parametrize("p", [-0.1, 1.5, float("nan")])
def test_a_probability_outside_zero_one_is_one_line(p, synthetic_dataset):
    with pytest.raises(ValueError, match="data.albedo_p=.* is not a probability"):
        check_albedo_p(p)
    with pytest.raises(ValueError, match="not a probability"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", albedo_p=p)


@pytest.mark.parametrize("display", [None, MIX])
def test_albedo_leaves_every_other_draw_as_it_was(synthetic_dataset, display):
    plain = make_dm(synthetic_dataset, display=display).train_set
    textured = make_dm(synthetic_dataset, display=display, albedo_p=0.5).train_set
    seen = 0
    for k in range(64):
        a, b = plain.draw(k), textured.draw(k)
        assert (a.pair.record, a.y, a.x, a.display, a.jitter) == (b.pair.record, b.y, b.x, b.display, b.jitter)
        assert a.albedo is None
        seen += b.albedo is not None
    assert 16 < seen < 48  # about half the patches


def test_the_target_is_computed_from_the_textured_pair(synthetic_dataset):
    # no display mix and no jitter: the pair is tone-mapped, the texture multiplies noisy and reference alike
    kw = dict(jitter={"hsv": False, "geometric": False})
    plain = make_dm(synthetic_dataset, **kw).train_set
    textured = make_dm(synthetic_dataset, albedo_p=1.0, **kw).train_set
    changed = 0
    for k in range(16):
        d = textured.draw(k)
        t = texture(d.albedo, 32)
        (x0, y0), (x1, y1) = plain[k], textured[k]
        assert torch.allclose(x1, x0 * t, atol=1e-6)
        ref = d.pair.ref[:, d.y : d.y + 32, d.x : d.x + 32] * t
        assert torch.allclose(y1, compute_target("ssim_map", x1[None], ref[None])[0], atol=1e-6)
        changed += not torch.allclose(y0, y1, atol=1e-3)
        assert d.display == TONEMAP
    assert changed > 8


def test_a_textured_batch_stays_finite_on_extreme_images(synthetic_dataset):
    ds = make_dm(synthetic_dataset, display=MIX, albedo_p=1.0).train_set
    for p in ds.pairs:
        p.noisy[:, :4, :4] = 1e6  # fireflies
        p.noisy[:, -4:, -4:] = 0.0
    for x, y in ds.__getitems__(list(range(16))):
        assert bool(torch.isfinite(x).all()) and bool(torch.isfinite(y).all())
