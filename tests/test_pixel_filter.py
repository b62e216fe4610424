"""The pixel-filter augmentation: Mitsuba's Gaussian emulated on box-filtered renders, noisy and reference alike."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest
import torch
from test_batched_patches import MIX, draws_but, make_dm

from nriqa.data.albedo import texture
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import item_generator
from nriqa.data.pixel_filter import apply_pixel_filter, gaussian_weight, kernel_1d, sample_pixel_filter
from nriqa.data.targets import compute_target
from nriqa.io.manifest import read_manifest, write_manifest


@pytest.mark.parametrize("sigma", [0.1, 0.3, 0.5, 0.8, 2.0])
def test_a_kernel_is_symmetric_sums_to_one_and_reaches_four_sigma(sigma):
    k = kernel_1d(sigma)
    assert torch.allclose(k, k.flip(0)) and float(k.sum()) == pytest.approx(1.0)
    assert bool((k > 0).all()) and int(k.argmax()) == (len(k) - 1) // 2
    assert (len(k) - 1) // 2 == max(0, int(np.ceil(4 * sigma - 0.5)))  # taps touching the filter's support


def test_the_weight_is_mitsubas_gaussian_cut_at_four_sigma():
    x = torch.tensor([0.0, 0.5, 1.0, 2.0, 2.5], dtype=torch.float64)
    w = gaussian_weight(x, 0.5)
    expected = np.clip(np.exp(-(x.numpy() ** 2) / 0.5) - np.exp(-8.0), 0, None)
    assert np.allclose(w.numpy(), expected) and float(w[-1]) == 0.0


def test_filtering_keeps_constants_and_the_mean_and_correlates_white_noise():
    flat = torch.full((2, 3, 16, 16), 0.7)
    assert torch.allclose(apply_pixel_filter(flat, 0.5), flat)
    noise = torch.randn(1, 1, 256, 256, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    out = apply_pixel_filter(noise, 0.5)
    k = kernel_1d(0.5)
    lag1 = float((k[:-1] * k[1:]).sum() / (k * k).sum())  # white noise through the taps: 0.42
    a, b = out[0, 0, :, :-1].flatten(), out[0, 0, :, 1:].flatten()
    assert float(torch.corrcoef(torch.stack([a, b]))[0, 1]) == pytest.approx(lag1, abs=0.03)
    assert float(out.std()) < 0.6 * float(noise.std())
    assert bool(torch.isfinite(apply_pixel_filter(torch.full((1, 3, 8, 8), 1e6), 0.8)).all())
    assert apply_pixel_filter(torch.rand(1, 3, 3, 3), 0.5).shape == (1, 3, 3, 3)  # smaller than the kernel


def test_no_pixel_filter_draws_nothing_and_bad_settings_are_one_line(synthetic_dataset):
    g = item_generator(1, 2)
    state = g.get_state()
    assert sample_pixel_filter(g, 0.0) is None and torch.equal(g.get_state(), state)
    assert 0.3 <= sample_pixel_filter(item_generator(1, 2), 1.0) <= 0.8
    with pytest.raises(ValueError, match=r"data.pixel_filter_p=1.5 is not a probability"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", pixel_filter_p=1.5)
    with pytest.raises(
        ValueError, match=r"^data.pixel_filter_sigma=\[0.8, 0.3\]: give \[low, high\] with 0 < low <= high <= 4 pixels"
    ):
        NRIQADataModule(synthetic_dataset, val_scene="beta", pixel_filter_p=0.5, pixel_filter_sigma=[0.8, 0.3])


@pytest.mark.parametrize("display", [None, MIX])
def test_the_filter_leaves_every_other_draw_as_it_was(synthetic_dataset, display):
    plain = make_dm(synthetic_dataset, display=display, albedo_p=0.5).train_set
    filtered = make_dm(synthetic_dataset, display=display, albedo_p=0.5, pixel_filter_p=0.5).train_set
    seen = 0
    for k in range(64):
        a, b = plain.draw(k), filtered.draw(k)
        assert draws_but(a, "pixel_sigma") == draws_but(b, "pixel_sigma")
        assert a.pixel_sigma is None
        seen += b.pixel_sigma is not None
    assert 16 < seen < 48  # about half the patches


def test_the_target_is_computed_from_the_filtered_pair(synthetic_dataset):
    kw = dict(jitter={"hsv": False, "geometric": False})
    plain = make_dm(synthetic_dataset, **kw).train_set
    filtered = make_dm(synthetic_dataset, pixel_filter_p=1.0, **kw).train_set
    rose = 0
    for k in range(16):
        d = filtered.draw(k)
        (x0, y0), (x1, y1) = plain[k], filtered[k]
        assert torch.allclose(x1, apply_pixel_filter(x0[None], d.pixel_sigma)[0], atol=1e-6)
        ref = apply_pixel_filter(d.pair.ref[None, :, d.y : d.y + 32, d.x : d.x + 32], d.pixel_sigma)
        assert torch.allclose(y1, compute_target("ssim_map", x1[None], ref)[0], atol=1e-6)
        rose += float(y1.mean()) > float(y0.mean())  # the filter takes noise away: the target rises
    assert rose >= 12


def test_mitsubas_gaussian_filter_lies_inside_the_family_the_augmentation_draws():
    """The same scene through Mitsuba's Gaussian film (stddev 0.5) spreads its noise between what the emulation
    makes of the box-filtered render at the ends of SIGMA_RANGE: neighbour correlation and noise level."""
    mi = pytest.importorskip("mitsuba")
    from data_gen.plan import ImageTask, Job
    from data_gen.render import scene_dict
    from nriqa.data.pixel_filter import SIGMA_RANGE
    from nriqa.render.backend import SCALAR_VARIANT, init_worker

    previous = mi.variant()
    init_worker(SCALAR_VARIANT, 1)
    try:
        images = {}
        for name in ("box", "gaussian"):
            job = Job("cornell", 0, 7, "path_independent", (48, 48), 6, (), name)
            scene = mi.load_dict(scene_dict(job, ImageTask("t", "test", 16, 1, "t.exr", "r.exr")))
            noisy = np.array(mi.render(scene, spp=16, seed=3), dtype=np.float64)[..., :3]
            ref = np.array(mi.render(scene, spp=1024, seed=4), dtype=np.float64)[..., :3]
            images[name] = [torch.from_numpy(x).permute(2, 0, 1)[None] for x in (noisy, ref)]
    finally:
        if previous is not None:
            mi.set_variant(previous)

    def noise_stats(noisy, ref):
        n = (noisy - ref).mean(dim=1)[0, 4:-4, 4:-4]  # grey noise, away from the borders
        lag1 = torch.corrcoef(torch.stack([n[:, :-1].flatten(), n[:, 1:].flatten()]))[0, 1]
        return float(lag1), float(n.std())

    box = images["box"]
    narrow, wide = (noise_stats(*(apply_pixel_filter(x, s) for x in box)) for s in SIGMA_RANGE)
    real, plain = noise_stats(*images["gaussian"]), noise_stats(*box)
    assert abs(plain[0]) < 0.1 < narrow[0] < real[0] < wide[0], (narrow, real, wide, plain)
    assert wide[1] < real[1] < narrow[1] < plain[1], (narrow, real, wide, plain)


def through_gaussian(dataset, root, scenes=None):
    """A copy of ``dataset`` whose manifest says ``scenes`` (all: ``None``) were rendered through Mitsuba's Gaussian."""
    shutil.copytree(dataset, root)
    records, meta = read_manifest(root)
    marked = [
        dataclasses.replace(r, pixel_filter="gaussian") if scenes is None or r.scene in scenes else r for r in records
    ]
    write_manifest(root, marked, meta)
    return root


def test_renders_already_through_a_filter_are_not_filtered_again(synthetic_dataset, tmp_path):
    mixed = make_dm(through_gaussian(synthetic_dataset, tmp_path / "mixed", {"alpha"}), pixel_filter_p=1.0).train_set
    plain = make_dm(synthetic_dataset, pixel_filter_p=1.0).train_set
    kinds = set()
    for k in range(48):
        a, b = plain.draw(k), mixed.draw(k)
        assert (a.pair.record.id, a.y, a.x, a.jitter) == (b.pair.record.id, b.y, b.x, b.jitter)
        native = b.pair.record.scene == "alpha"
        assert (b.pixel_sigma is None) == native and a.pixel_sigma is not None
        if native:
            assert torch.equal(mixed[k][0], make_dm(synthetic_dataset).train_set[k][0])  # as the render gave it
        kinds.add(native)
    assert kinds == {True, False}


def test_a_texture_laid_on_a_gaussian_render_goes_through_its_filter(synthetic_dataset, tmp_path):
    root = through_gaussian(synthetic_dataset, tmp_path / "gaussian")
    kw = dict(jitter={"hsv": False, "geometric": False})
    textured = make_dm(root, albedo_p=1.0, pixel_filter_p=1.0, **kw).train_set
    plain = make_dm(root, **kw).train_set
    for k in range(8):
        d = textured.draw(k)
        assert d.pixel_sigma is None and d.albedo is not None
        smooth = apply_pixel_filter(texture(d.albedo, 32)[None], 0.5)[0]
        assert torch.allclose(textured[k][0], plain[k][0] * smooth, atol=1e-6)
        assert not torch.allclose(smooth, texture(d.albedo, 32), atol=1e-3)
