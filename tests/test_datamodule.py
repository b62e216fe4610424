"""The training data: folds, patches, targets, jitter only in training, determinism, errors."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from conftest import make_dataset

from nriqa.core.ssim import ssim_map
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.folds import FoldError
from nriqa.data.jitter import jitter_pair
from nriqa.data.patches import EpochSampler, cut, item_generator
from nriqa.data.targets import compute_target
from nriqa.io.manifest import ManifestError, read_manifest, write_manifest


@pytest.fixture(scope="module")
def dm(synthetic_dataset) -> NRIQADataModule:
    """The default fold (beta held out), loaded once for the read-only tests."""
    return make_dm(synthetic_dataset)


def make_dm(root, **kw) -> NRIQADataModule:
    args = dict(val_scene="beta", patch_size=32, target="ssim_map", batch_size=4, batches_per_epoch=2, val_patches=8)
    args.update(kw)
    dm = NRIQADataModule(root, **args)
    dm.setup("fit")
    return dm


def test_fold_holds_the_scene_out(synthetic_dataset, dm):
    assert {p.record.scene for p in dm.train_pairs} == {"alpha", "gamma"}
    assert {p.record.scene for p in dm.val_pairs} == {"beta"}
    assert all(p.record.role in ("test", "twin") for p in dm.train_pairs + dm.val_pairs)
    # each noisy image is paired with its own reference
    for p in dm.train_pairs:
        assert Path(p.record.reference) == synthetic_dataset / p.record.scene / "reference.exr"


def test_several_roots_train_together(synthetic_dataset, tmp_path):
    # a second dataset with other images (another size, a longer ladder, only two of the scenes)
    other = make_dataset(tmp_path / "longer", size=64, scenes=("alpha", "beta"), spps=(64, 256))
    one, both = make_dm(synthetic_dataset), make_dm([synthetic_dataset, other])
    assert len(both.train_pairs) == len(one.train_pairs) + 4 and len(both.val_pairs) == len(one.val_pairs) + 4
    ids = [p.record.id for p in both.train_pairs + both.val_pairs]
    assert len(set(ids)) == len(ids)
    longer = [p for p in both.train_pairs if p.record.spp == 256]
    assert longer and all(p.noisy.shape == (3, 64, 64) and p.ref.shape == (3, 64, 64) for p in longer)
    x, y = next(iter(both.train_dataloader()))
    assert x.shape == (4, 3, 32, 32) and torch.isfinite(y).all()
    # the held-out scene is checked against every root together
    make_dm([synthetic_dataset, other], val_scene="gamma")
    with pytest.raises(FoldError, match="alpha, beta, gamma"):
        make_dm([synthetic_dataset, other], val_scene="delta")
    with pytest.raises(ManifestError, match="no manifest"):
        make_dm([synthetic_dataset, tmp_path / "missing"])


def test_no_val_scene_trains_on_all(synthetic_dataset):
    dm = make_dm(synthetic_dataset, val_scene=None)
    assert {p.record.scene for p in dm.train_pairs} == {"alpha", "beta", "gamma"}
    assert dm.val_dataloader() == []


def test_scenes_keeps_only_those_families(synthetic_dataset):
    dm = make_dm(synthetic_dataset, val_scene="beta", scenes=["alpha", "beta"])
    assert {p.record.scene for p in dm.train_pairs} == {"alpha"}
    assert {p.record.scene for p in dm.val_pairs} == {"beta"}
    held_back = make_dm(synthetic_dataset, val_scene=None, scenes=["gamma"])
    assert {p.record.scene for p in held_back.train_pairs} == {"gamma"}
    with pytest.raises(
        FoldError, match=r"unknown scenes \['delta'\] in data.scenes; the dataset has: alpha, beta, gamma"
    ):
        make_dm(synthetic_dataset, scenes=["alpha", "delta"])
    with pytest.raises(FoldError, match="unknown val_scene 'gamma'"):  # the held-out scene must be one of them
        make_dm(synthetic_dataset, val_scene="gamma", scenes=["alpha", "beta"])


def test_references_are_loaded_once(dm):
    refs = {id(p.ref) for p in dm.train_pairs}
    assert len(refs) == 2


@pytest.mark.parametrize(("target", "size", "shape"), [("ssim_map", 64, (1, 64, 64)), ("patch_mae", 32, (1,))])
def test_batch_shapes(synthetic_dataset, target, size, shape):
    dm = make_dm(synthetic_dataset, target=target, patch_size=size)
    for loader in (dm.train_dataloader(), dm.val_dataloader()):
        x, y = next(iter(loader))
        assert x.shape == (4, 3, size, size) and y.shape == (4, *shape)
        assert x.min() >= 0 and x.max() <= 1 and torch.isfinite(y).all()
    assert len(dm.train_dataloader()) == 2
    assert len(dm.val_set) == 8


def test_target_is_computed_after_the_jitter(dm):
    ds = dm.train_set
    for k in range(3):
        g = item_generator(ds.seed, k)
        pair = ds.pairs[int(torch.randint(0, len(ds.pairs), (1,), generator=g))]
        noisy, ref = jitter_pair(*cut(pair, g, ds.patch_size), g)
        x, y = ds[k]
        assert torch.equal(x, noisy)
        assert torch.allclose(y, ssim_map(noisy[None], ref[None])[0])


def test_validation_is_never_jittered(synthetic_dataset, dm):
    on = dm
    off = make_dm(synthetic_dataset, jitter={"hsv": False, "geometric": False})
    assert torch.equal(on.val_set.tensors[0], off.val_set.tensors[0])
    # every validation patch is a plain crop of a held-out image, with the target of that crop
    size = on.patch_size
    for i, (x, y) in enumerate(zip(*on.val_set.tensors)):
        pair = on.val_pairs[i % len(on.val_pairs)]
        crops = pair.noisy.unfold(1, size, 1).unfold(2, size, 1)  # (3, nh, nw, P, P)
        hits = (crops == x[:, None, None]).all(dim=(0, 3, 4)).nonzero()
        assert len(hits) >= 1
        r, c = hits[0].tolist()
        expected = compute_target("ssim_map", x[None], pair.ref[None, :, r : r + size, c : c + size])[0]
        assert torch.allclose(y, expected)


def test_jitter_switches(synthetic_dataset):
    plain = make_dm(synthetic_dataset, jitter={"hsv": False, "geometric": False}).train_set
    x, _ = plain[0]
    g = item_generator(plain.seed, 0)
    pair = plain.pairs[int(torch.randint(0, len(plain.pairs), (1,), generator=g))]
    assert torch.equal(x, cut(pair, g, plain.patch_size)[0])
    hsv = make_dm(synthetic_dataset, jitter={"hsv": True, "geometric": False}).train_set
    assert not torch.equal(hsv[0][0], x)


def test_same_seed_same_first_batch(synthetic_dataset):
    a = next(iter(make_dm(synthetic_dataset, seed=7).train_dataloader()))
    b = next(iter(make_dm(synthetic_dataset, seed=7).train_dataloader()))
    c = next(iter(make_dm(synthetic_dataset, seed=8).train_dataloader()))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert not torch.equal(a[0], c[0])


def test_new_patches_every_epoch():
    sampler = EpochSampler(4)
    first = list(sampler)
    sampler.set_epoch(1)
    assert first == [0, 1, 2, 3] and list(sampler) == [4, 5, 6, 7]


def test_unknown_val_scene_lists_the_scenes(synthetic_dataset):
    with pytest.raises(FoldError, match="alpha, beta, gamma"):
        make_dm(synthetic_dataset, val_scene="nope")


def test_missing_manifest(tmp_path):
    with pytest.raises(ManifestError, match="no manifest"):
        make_dm(tmp_path)


def test_dataset_without_noisy_images(synthetic_dataset, tmp_path):
    records, meta = read_manifest(synthetic_dataset)
    refs = [r for r in records if r.role == "reference"]
    write_manifest(tmp_path, refs, meta)
    with pytest.raises(FoldError, match="no noisy"):
        make_dm(tmp_path)


def test_patch_larger_than_images(synthetic_dataset):
    with pytest.raises(ValueError, match="smaller than patch_size"):
        make_dm(synthetic_dataset, patch_size=128)


def test_bad_options(synthetic_dataset):
    with pytest.raises(ValueError, match="unknown target"):
        NRIQADataModule(synthetic_dataset, target="psnr")
    with pytest.raises(ValueError, match="unknown jitter"):
        NRIQADataModule(synthetic_dataset, jitter={"colour": True})
