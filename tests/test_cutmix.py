"""Pasted patches (data.cutmix_p): a rectangle of a partner item, made alike, fills every member; the target is the
SSIM map of the pasted pair; the other draws stay as they were; anchors and ladder pairs; bad settings are one line."""

from __future__ import annotations

import pytest
import torch
from test_batched_patches import MIX, draws_but, make_dm

from nriqa.core.ssim import ssim_map
from nriqa.data.cutmix import Box, partner_generator, paste_batch, sample_box
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import item_generator


def test_no_pasting_draws_nothing_and_boxes_lie_inside_the_patch(synthetic_dataset):
    g = item_generator(1, 2)
    state = g.get_state()
    assert sample_box(g, 0.0, 32) is None and torch.equal(g.get_state(), state)
    sides = []
    for k in range(200):
        b = sample_box(item_generator(3, k), 1.0, 32)
        assert 8 <= b.h <= 24 and 8 <= b.w <= 24
        assert 0 <= b.y <= 32 - b.h and 0 <= b.x <= 32 - b.w
        sides += [b.h, b.w]
    assert min(sides) == 8 and max(sides) == 24  # the whole range is drawn
    a, b = partner_generator(1, 5), item_generator(1, 5)
    assert not torch.equal(torch.rand(4, generator=a), torch.rand(4, generator=b)), "a stream of its own"


def test_bad_settings_are_one_line(synthetic_dataset):
    with pytest.raises(ValueError, match=r"data.cutmix_p=2.0 is not a probability"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", cutmix_p=2.0)
    with pytest.raises(ValueError, match=r"data.cutmix_p and ladder pairs .* do not go together"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", cutmix_p=0.5, ladder_pairs=True)


@pytest.mark.parametrize("extra", [{}, {"display": MIX, "albedo_p": 0.5, "pixel_filter_p": 0.5, "converged_p": 0.3}])
def test_pasted_items_carry_their_partner_and_the_target_of_the_pasted_pair(synthetic_dataset, seen_pairs, extra):

    def made(ds, k, draw=None):
        """Item k's input, target and the displayed (noisy, reference) its target came from."""
        if draw is not None:
            ds.draw = lambda index: draw  # item k made from these choices alone
        (x, y), (noisy, ref) = ds[k], seen_pairs[-1]
        if draw is not None:
            del ds.draw
        return x, y, noisy[0], ref[0]

    plain = make_dm(synthetic_dataset, **extra).train_set
    mixed = make_dm(synthetic_dataset, cutmix_p=0.5, **extra).train_set
    ks = list(range(48))
    batch = mixed.__getitems__(ks)
    seen = 0
    for k in ks:
        a, b = plain.draw(k), mixed.draw(k)
        assert draws_but(a, "cutmix") == draws_but(b, "cutmix") and a.cutmix is None
        x0, y0, noisy0, ref0 = made(plain, k)
        x1, y1, noisy1, ref1 = made(mixed, k)
        assert torch.equal(batch[k][0], x1) and torch.equal(batch[k][1], y1), "a batch is its items"
        if b.cutmix is None:
            assert torch.equal(x0, x1) and torch.equal(y0, y1)
            continue
        seen += 1
        box = b.cutmix
        inside = torch.zeros_like(noisy1, dtype=torch.bool)
        inside[:, box.y : box.y + box.h, box.x : box.x + box.w] = True
        _, _, noisy_p, ref_p = made(mixed, k, mixed.partner(k))
        for got, own, partner in ((noisy1, noisy0, noisy_p), (ref1, ref0, ref_p)):
            assert torch.equal(got[~inside], own[~inside]), "outside the box: the item's own patch"
            assert torch.equal(got[inside], partner[inside]), "inside the box: the partner's patch, made alike"
        assert torch.equal(x1, noisy1), "the network sees the pasted image"
        assert torch.allclose(y1, ssim_map(noisy1[None], ref1[None])[0]), "the target is the pasted pair's map"
    assert 12 < seen < 36  # about half


def test_paste_batch_fills_the_box_of_every_member_from_the_partner():
    g = torch.Generator().manual_seed(0)
    noisy = torch.rand(2, 3, 32, 32, generator=g)
    ref = torch.full((2, 3, 32, 32), 0.5)
    ref[1] = 0.2
    pasted = paste_batch({0: (Box(4, 6, 16, 20), 1)}, [noisy, ref])
    assert torch.equal(pasted[0][0, :, 4:20, 6:26], noisy[1, :, 4:20, 6:26])
    assert torch.equal(pasted[1][0, :, 4:20, 6:26], ref[1, :, 4:20, 6:26])
    assert torch.equal(pasted[0][1], noisy[1]) and torch.equal(noisy[0, :, 0, 0], pasted[0][0, :, 0, 0])
    target = ssim_map(pasted[0][:1], pasted[1][:1])
    assert torch.isfinite(target).all() and target.shape == (1, 1, 32, 32)


@pytest.mark.parametrize("share, field", [("cutmix_p", "cutmix"), ("coarse_p", "coarse")])
def test_pasted_or_coarse_anchored_items_learn_their_target(synthetic_dataset, share, field):
    ds = make_dm(synthetic_dataset, anchor_scenes=["alpha"], **{share: 0.5}).train_set
    ks = list(range(48))
    flags = []
    for k, (_, _, flag) in zip(ks, ds.__getitems__(ks)):
        d = ds.draw(k)
        assert bool(flag) == (d.pair.record.scene == "alpha" and getattr(d, field) is None)
        flags.append(getattr(d, field) is not None and d.pair.record.scene == "alpha")
    assert any(flags), "some anchored image was pasted or coarsened (and learns its target)"
