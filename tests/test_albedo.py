"""Albedo textures for training: drawn from a seed, multiplied into noisy image and reference alike."""

from __future__ import annotations

import pytest
import torch
from test_batched_patches import MIX, make_dm

from nriqa.data.albedo import LINE_DUTY, LINE_PERIOD, LOW_RANGE, check_albedo_p, grille, sample_albedo, texture
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


def test_a_grille_is_a_function_of_its_seed_thin_dark_lines_on_a_bright_ground():
    a = grille(3, 32)
    assert torch.equal(a, grille(3, 32)) and a.dtype == torch.float32 and a.shape == (3, 32, 32)
    assert not torch.equal(a, grille(4, 32))
    greys = 0
    for seed in range(40):
        t = grille(seed, 48)
        assert bool(torch.isfinite(t).all())
        assert float(t.min()) >= LOW_RANGE[0] * 0.7 - 1e-6 and float(t.max()) <= 1.0
        assert float(t.std()) > 0.0
        c = t[0]
        share = (c - c.min()) / (c.max() - c.min())  # 0 on a line, 1 on the ground
        assert float(share.mean()) > (1.0 - LINE_DUTY[1]) ** 2 - 0.1  # at most two sets of lines of at most 40 %
        # lines every 3-12 pixels: any 12-pixel run of a row or a column crosses one, unless it runs along them
        rows = share.unfold(1, 12, 12).amin(-1).mean()
        cols = share.unfold(0, 12, 12).amin(-1).mean()
        assert min(float(rows), float(cols)) < 0.9
        greys += len(torch.unique(c)) > 2  # box-filtered: a line's edge shows as grey
    assert greys > 30


def test_texture_draws_grilles_in_the_share_asked():
    assert all(torch.equal(texture(s, 24, lines=1.0), grille(s, 24)) for s in range(20))
    assert not any(torch.equal(texture(s, 24), grille(s, 24)) for s in range(20))
    half = sum(torch.equal(texture(s, 24, lines=0.5), grille(s, 24)) for s in range(60))
    assert 15 < half < 45
    assert grille(1, 1).shape == (3, 1, 1) and bool(torch.isfinite(grille(1, 1)).all())
    assert bool(torch.isfinite(grille(2, 512)).all())


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


@pytest.mark.parametrize("lines", [-0.1, 1.5, float("nan")])
def test_a_share_of_grilles_outside_zero_one_is_one_line(lines, synthetic_dataset):
    with pytest.raises(ValueError, match=r"data.albedo_lines=.* is not a probability.*switches the grilles off\)$"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", albedo_p=0.5, albedo_lines=lines)


def test_grilles_are_multiplied_into_noisy_and_reference_alike(synthetic_dataset):
    kw = dict(jitter={"hsv": False, "geometric": False})
    bare = make_dm(synthetic_dataset, **kw).train_set
    noise = make_dm(synthetic_dataset, albedo_p=1.0, **kw).train_set
    lined = make_dm(synthetic_dataset, albedo_p=1.0, albedo_lines=1.0, **kw).train_set
    for k in range(8):
        a, d = noise.draw(k), lined.draw(k)
        assert (a.pair.record, a.y, a.x, a.display, a.albedo) == (d.pair.record, d.y, d.x, d.display, d.albedo)
        t = grille(d.albedo, 32)  # the same draws: only the texture's kind changes
        (x0, _), (x1, y1) = bare[k], lined[k]
        assert torch.allclose(x1, x0 * t, atol=1e-6)
        ref = d.pair.ref[:, d.y : d.y + 32, d.x : d.x + 32] * t
        assert torch.allclose(y1, compute_target("ssim_map", x1[None], ref[None])[0], atol=1e-6)


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


def test_grilles_are_drawn_at_the_spacing_asked(synthetic_dataset):
    assert all(torch.equal(grille(s, 24, LINE_PERIOD), grille(s, 24)) for s in range(10)), "the default as before"
    fine = [grille(s, 64, (1.2, 2.0))[0] for s in range(20)]
    coarse = [grille(s, 64, (8.0, 12.0))[0] for s in range(20)]

    def high_share(t):  # the share of the texture's variance above half the Nyquist frequency
        f = torch.fft.fftshift(torch.fft.fft2(t - t.mean()).abs() ** 2)
        r = torch.hypot(*torch.meshgrid(torch.arange(-32, 32.0), torch.arange(-32, 32.0), indexing="ij"))
        return float(f[r > 16].sum() / f.sum().clamp_min(1e-12))

    assert min(map(high_share, fine)) > max(map(high_share, coarse)), "finer lines: more of the variance up high"
    assert all(bool(torch.isfinite(t).all()) and float(t.std()) > 0 for t in fine)
    kw = dict(jitter={"hsv": False, "geometric": False}, albedo_p=1.0, albedo_lines=1.0)
    bare = make_dm(synthetic_dataset, jitter=kw["jitter"]).train_set
    lined = make_dm(synthetic_dataset, albedo_line_period=[1.2, 2.0], **kw).train_set
    for k in range(4):
        (x0, _), (x1, _) = bare[k], lined[k]
        assert torch.allclose(x1, x0 * grille(lined.draw(k).albedo, 32, (1.2, 2.0)), atol=1e-6), "items use it"
    for bad in ([0.5, 2.0], [4.0, 3.0], 3, [1.5, 2.0, 3.0]):
        with pytest.raises(
            ValueError, match=r"^data.albedo_line_period=.*: give \[low, high\] with 1 <= low <= high pixels"
        ):
            NRIQADataModule(synthetic_dataset, val_scene="beta", albedo_line_period=bad)


def test_albedo_min_spp_keeps_textures_off_the_noisier_images(synthetic_dataset):
    everywhere = make_dm(synthetic_dataset, albedo_p=1.0).train_set
    gated = make_dm(synthetic_dataset, albedo_p=1.0, albedo_min_spp=16).train_set
    spps = set()
    for k in range(64):
        a, b = everywhere.draw(k), gated.draw(k)
        assert (a.pair.record, a.y, a.x, a.display, a.jitter) == (b.pair.record, b.y, b.x, b.display, b.jitter)
        spp = b.pair.record.spp
        spps.add(spp)
        assert b.albedo == (a.albedo if spp >= 16 else None), f"spp {spp}"
    assert spps == {1, 4, 16, 64}, "both sides of the gate were drawn"
    x_plain = make_dm(synthetic_dataset).train_set
    low = next(k for k in range(64) if gated.draw(k).pair.record.spp < 16)
    assert torch.equal(gated[low][0], x_plain[low][0]), "a gated-out image's item is the untextured one"
    for bad in (-1, 2.5, "many", float("nan")):
        with pytest.raises(ValueError, match=r"data.albedo_min_spp=.*give a whole number of samples per pixel >= 0"):
            NRIQADataModule(synthetic_dataset, val_scene="beta", albedo_min_spp=bad)
