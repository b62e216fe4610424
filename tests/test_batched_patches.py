"""Training patches made a batch at a time: the same draws and the same numbers as one by one."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from conftest import load_script

from nriqa.core.display import apply_display
from nriqa.data.albedo import texture
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.jitter import apply_jitter, sample_jitter, shift_hsv
from nriqa.data.patches import TONEMAP, cut_all, item_generator
from nriqa.data.pixel_filter import apply_pixel_filter
from nriqa.data.targets import compute_target

MIX = {"tonemap": 1.0, "srgb": 1.0, "gamma22": 1.0, "stops": 2.0, "quantise_p": 0.5}


def make_dm(root, **kw) -> NRIQADataModule:
    args = dict(val_scene="beta", patch_size=32, target="ssim_map", batch_size=8, batches_per_epoch=2, val_patches=8)
    args.update(kw)
    dm = NRIQADataModule(root, **args)
    dm.setup("fit")
    return dm


def draws_but(draw, *skip: str) -> tuple:
    """A training item's random choices (:class:`nriqa.data.patches.Draw`) but the fields ``skip``, comparable."""
    return tuple(
        draw.pair.record if f.name == "pair" else getattr(draw, f.name)
        for f in dataclasses.fields(draw)
        if f.name not in skip
    )


def one_by_one(ds, k):
    """Item ``k`` from the single-image functions, in the order the draws are made."""
    g = item_generator(ds.seed, k)
    pair = ds.pick(g)
    members = cut_all(pair, g, ds.patch_size, ds.twins)
    if ds.draw(k).converged:  # drawn last, applied first: the input is the reference
        members[0] = members[1]
    display = ds.display.sample(g) if ds.display is not None else TONEMAP
    albedo = ds.draw(k).albedo  # drawn last, applied first (to the linear radiance)
    if albedo is not None:
        members = [m * texture(albedo, ds.patch_size, ds.albedo_lines) for m in members]
    sigma = ds.draw(k).pixel_sigma  # drawn after the albedo, applied after it (to the radiance)
    if sigma is not None:
        members = [apply_pixel_filter(m[None], sigma)[0] for m in members]
    if pair.linear:
        members = [apply_display(m, display, pair.key) for m in members]
    if ds.hsv or ds.geometric:
        params = sample_jitter(g, hsv=ds.hsv, geometric=ds.geometric, value=ds.value)
        members = [apply_jitter(m, params) for m in members]
    target = compute_target(ds.target, members[0][None], members[1][None])[0]
    x = members[0] if not ds.twins else torch.cat([members[0], members[2]])
    return x, target


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"display": MIX, "twins": True},
        {"display": MIX, "jitter": {"hsv": False, "geometric": True}},
        {"jitter": {"hsv": True, "geometric": False}},
        {"jitter": {"hsv": True, "geometric": True, "value": "scale"}},
        {"display": MIX, "jitter": {"hsv": True, "geometric": True, "value": False}},
        {"jitter": {"hsv": False, "geometric": False}},
        {"target": "patch_mae"},
        {"albedo_p": 0.5},
        {"display": MIX, "twins": True, "albedo_p": 0.5},
        {"albedo_p": 0.5, "albedo_lines": 0.5},
        {"pixel_filter_p": 0.5},
        {"display": MIX, "twins": True, "albedo_p": 0.5, "pixel_filter_p": 0.5},
        {"display": MIX, "albedo_p": 0.5, "pixel_filter_p": 0.5, "converged_p": 0.5},
    ],
)
def test_a_batch_equals_its_items_made_one_by_one(synthetic_dataset, kw):
    ds = make_dm(synthetic_dataset, **kw).train_set
    ks = list(range(40, 64))
    batch = ds.__getitems__(ks)
    assert len(batch) == len(ks)
    for k, (x, y) in zip(ks, batch):
        rx, ry = one_by_one(ds, k)
        # the images are bit-identical; a target's mean (patch_mae) may round differently in a batch
        assert torch.equal(x, rx) and torch.allclose(y, ry, rtol=0.0, atol=1e-6), k
        sx, sy = ds[k]
        assert torch.equal(x, sx) and torch.allclose(y, sy, rtol=0.0, atol=1e-6)


def test_weighted_draws_are_batched_alike(synthetic_dataset):
    ds = make_dm(synthetic_dataset, display=MIX).train_set
    weights = torch.zeros(len(ds.pairs))
    weights[1] = 1.0
    ds.set_weights(weights)
    try:
        for k, (x, y) in zip(range(8), ds.__getitems__(list(range(8)))):
            assert ds.draw(k).pair is ds.pairs[1]
            rx, ry = one_by_one(ds, k)
            assert torch.equal(x, rx) and torch.equal(y, ry)
    finally:
        ds.set_weights(None)


def test_the_loader_hands_out_batched_items(synthetic_dataset):
    dm = make_dm(synthetic_dataset, display=MIX)
    x, y = next(iter(dm.train_dataloader()))
    items = [dm.train_set[k] for k in range(dm.batch_size)]
    assert torch.equal(x, torch.stack([i[0] for i in items]))
    assert torch.equal(y, torch.stack([i[1] for i in items]))


def test_patches_made_on_a_device_are_the_same(synthetic_dataset):
    on_cpu = make_dm(synthetic_dataset, display=MIX)
    on_device = make_dm(synthetic_dataset, display=MIX, device="cpu")
    assert on_device.train_set.pairs is not on_device.train_pairs  # moved copies; hard sampling keeps the loaded ones
    a = next(iter(on_cpu.train_dataloader()))
    b = next(iter(on_device.train_dataloader()))
    assert all(torch.equal(u, v) for u, v in zip(a, b))


def test_a_shared_reference_is_moved_once(synthetic_dataset):
    ds = make_dm(synthetic_dataset, device="cpu").train_set
    refs = {id(p.ref) for p in ds.pairs}
    assert len(refs) < len(ds.pairs)


def test_device_with_loader_workers_is_refused(synthetic_dataset):
    with pytest.raises(ValueError, match="num_workers=0"):
        NRIQADataModule(synthetic_dataset, device="cuda", num_workers=2)


def test_shift_hsv_per_image_equals_one_shift_each():
    torch.manual_seed(0)
    img = torch.rand(3, 3, 16, 16)
    shifts = torch.tensor([[0.1, 0.2, -0.1], [0.9, -0.3, 0.3], [0.0, 0.0, 0.05]], dtype=torch.float64).view(3, 3, 1, 1)
    batched = shift_hsv(img, shifts[:, 0], shifts[:, 1].float(), shifts[:, 2].float())
    for i in range(3):
        h, s, v = (float(t) for t in shifts[i, :, 0, 0])
        assert torch.equal(batched[i], shift_hsv(img[i], h, s, v))


def load_train_step():
    return load_script("benchmarks/train_step.py")


def test_train_step_benchmark_prints_its_table(synthetic_dataset, capsys, one_thread):
    module = load_train_step()
    module.main(["--data", str(synthetic_dataset), "--patch", "32", "--batch", "2", "--repeats", "1"])
    out = capsys.readouterr().out
    assert "patches, batched" in out and "unet_fast step" in out


def test_train_step_benchmark_bad_data_is_one_line(tmp_path, one_thread):
    module = load_train_step()
    with pytest.raises(SystemExit, match="train_step: .*manifest"):
        module.main(["--data", str(tmp_path), "--repeats", "1"])


def test_a_batch_mixing_linear_and_tone_mapped_pairs_is_refused(synthetic_dataset):
    import dataclasses

    from nriqa.data.patches import TrainPatches

    linear = make_dm(synthetic_dataset, display=MIX).train_set.pairs
    tone_mapped = make_dm(synthetic_dataset).train_set.pairs
    mixed = [linear[0], dataclasses.replace(tone_mapped[1])]
    ds = TrainPatches(mixed, 32, "ssim_map", 8, seed=1, display=None)
    with pytest.raises(ValueError, match="mix tone-mapped and linear"):
        ds.__getitems__(list(range(8)))
