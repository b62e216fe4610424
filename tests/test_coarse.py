"""Coarse pixels (data.coarse_p): a half-size copy of the item's own cut, each pixel a 2 x 2 block's mean, fills a
half-size square of every member alike; the target is the SSIM map of the result; the other draws stay as they were;
bad settings are one line (anchors: test_cutmix)."""

from __future__ import annotations

import pytest
import torch
from test_batched_patches import MIX, draws_but, make_dm

from nriqa.core.ssim import ssim_map
from nriqa.data.coarse import coarse_batch, coarsen, sample_coarse
from nriqa.data.cutmix import Box
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import item_generator

STILL = {"hsv": False, "geometric": False}  # no jitter: what the cut holds is what the target sees


def test_no_coarse_pixels_draw_nothing_and_squares_lie_inside_the_patch():
    g = item_generator(1, 2)
    state = g.get_state()
    assert sample_coarse(g, 0.0, 32) is None and torch.equal(g.get_state(), state)
    ys, xs = [], []
    for k in range(300):
        b = sample_coarse(item_generator(3, k), 1.0, 32)
        assert (b.h, b.w) == (16, 16) and 0 <= b.y <= 16 and 0 <= b.x <= 16
        ys.append(b.y)
        xs.append(b.x)
    assert (min(ys), max(ys), min(xs), max(xs)) == (0, 16, 0, 16), "every position can be drawn"
    assert sum(sample_coarse(item_generator(4, k), 0.25, 32) is not None for k in range(400)) in range(70, 131)


def test_bad_settings_are_one_line(synthetic_dataset):
    with pytest.raises(ValueError, match=r"data.coarse_p=1.5 is not a probability"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", coarse_p=1.5)
    with pytest.raises(ValueError, match=r"data.coarse_p needs an even data.patch_size of at least 4, got 33"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", patch_size=33, coarse_p=0.5)
    NRIQADataModule(synthetic_dataset, val_scene="beta", patch_size=33)  # off: any patch side, as before


def test_coarsen_is_half_the_resolution_at_four_times_the_samples():
    flat = torch.full((1, 3, 8, 8), 0.7)
    assert torch.equal(coarsen(flat), torch.full((1, 3, 4, 4), 0.7)), "a constant stays itself"
    ramp = torch.arange(16.0).view(1, 1, 4, 4)
    assert torch.equal(coarsen(ramp), torch.tensor([[[[2.5, 4.5], [10.5, 12.5]]]]))
    g = torch.Generator().manual_seed(0)
    noise = torch.randn(1, 1, 512, 512, generator=g, dtype=torch.float64)
    ratio = float(coarsen(noise).var() / noise.var())
    assert 0.23 < ratio < 0.27, f"independent pixel noise averaged by four: variance / 4, got {ratio:.3f}"
    spike = torch.zeros(1, 1, 4, 4)
    spike[0, 0, 1, 1] = 1e6  # a firefly spreads over its block, finite, its energy kept
    assert torch.equal(coarsen(spike)[0, 0], torch.tensor([[2.5e5, 0.0], [0.0, 0.0]]))


def test_coarse_batch_fills_the_square_of_every_member_from_its_own_copy():
    g = torch.Generator().manual_seed(1)
    noisy, ref = torch.rand(2, 3, 8, 8, generator=g), torch.rand(2, 3, 8, 8, generator=g)
    out = coarse_batch({1: Box(2, 4, 4, 4)}, [noisy, ref])
    for got, src in zip(out, (noisy, ref)):
        assert torch.equal(got[0], src[0]), "items without a square as they were"
        assert torch.allclose(got[1, :, 2:6, 4:8], coarsen(src[1:2])[0])
        inside = torch.zeros(8, 8, dtype=torch.bool)
        inside[2:6, 4:8] = True
        assert torch.equal(got[1][:, ~inside], src[1][:, ~inside])
    assert coarse_batch({}, [noisy, ref])[0] is noisy


@pytest.mark.parametrize("extra", [{"jitter": STILL}, {"display": MIX, "cutmix_p": 0.5, "albedo_p": 0.5}])
def test_coarse_items_carry_their_copy_and_the_target_of_the_result(synthetic_dataset, seen_pairs, extra):
    plain = make_dm(synthetic_dataset, **extra).train_set
    coarse = make_dm(synthetic_dataset, coarse_p=0.5, **extra).train_set
    ks = list(range(40))
    batch = coarse.__getitems__(ks)
    seen = 0
    for k in ks:
        a, b = plain.draw(k), coarse.draw(k)
        assert draws_but(a, "coarse", "cutmix") == draws_but(b, "coarse", "cutmix") and a.coarse is None
        x1, y1 = coarse[k]
        noisy1, ref1 = (t[0] for t in seen_pairs[-1])
        assert torch.equal(batch[k][0], x1) and torch.equal(batch[k][1], y1), "a batch is its items"
        assert torch.allclose(y1, ssim_map(noisy1[None], ref1[None])[0]), "the target is the map of what is seen"
        if b.coarse is None:
            continue
        seen += 1
        if "display" in extra:
            continue  # displayed, textured, pasted afterwards: the square's content is checked without them
        size = plain.patch_size
        own = [img[:, b.y : b.y + size, b.x : b.x + size] for img in (b.pair.noisy, b.pair.ref)]
        box = b.coarse
        inside = torch.zeros(size, size, dtype=torch.bool)
        inside[box.y : box.y + box.h, box.x : box.x + box.w] = True
        for got, cut in zip((noisy1, ref1), own):
            assert torch.equal(got[:, ~inside], cut[:, ~inside]), "outside the square: the item's own cut"
            assert torch.allclose(got[:, inside].view(3, box.h, box.w), coarsen(cut[None])[0])
        assert torch.equal(x1, noisy1), "the network sees the coarse image"
    assert 8 < seen < 32  # about half
