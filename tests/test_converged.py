"""Converged patches (data.converged_p): the input is the reference itself and its target 1 everywhere; the other
draws stay as they were; anchored sets learn them at their target; bad settings are one line."""

from __future__ import annotations

import pytest
import torch
from test_batched_patches import MIX, draws_but, make_dm

from nriqa.data.converged import sample_converged
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import item_generator


def test_no_converged_patches_draw_nothing_and_bad_settings_are_one_line(synthetic_dataset):
    g = item_generator(1, 2)
    state = g.get_state()
    assert sample_converged(g, 0.0) is False and torch.equal(g.get_state(), state)
    assert sample_converged(item_generator(1, 2), 1.0) is True
    with pytest.raises(ValueError, match=r"data.converged_p=1.5 is not a probability"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", converged_p=1.5)
    with pytest.raises(ValueError, match=r"data.converged_p needs a single-image model"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", converged_p=0.2, twins=True)


@pytest.mark.parametrize("extra", [{}, {"display": MIX, "albedo_p": 0.5, "pixel_filter_p": 0.5}])
def test_converged_items_show_the_reference_at_target_one_and_leave_the_other_draws(synthetic_dataset, extra):
    plain = make_dm(synthetic_dataset, **extra).train_set
    mixed = make_dm(synthetic_dataset, converged_p=0.5, **extra).train_set
    ks = list(range(48))
    before, after = plain.__getitems__(ks), mixed.__getitems__(ks)
    seen = 0
    for k, (x0, y0), (x1, y1) in zip(ks, before, after):
        a, b = plain.draw(k), mixed.draw(k)
        assert draws_but(a, "converged") == draws_but(b, "converged")
        assert not a.converged
        if b.converged:
            seen += 1
            assert torch.allclose(y1, torch.ones_like(y1), atol=1e-5), "SSIM of an image with itself"
            assert float(y0.mean()) < 0.999, "the noisy patch of the same draw is not converged"
        else:
            assert torch.equal(x0, x1) and torch.equal(y0, y1)
    assert 12 < seen < 36  # about half


def test_anchored_sets_learn_their_converged_items_at_the_target(synthetic_dataset):
    ds = make_dm(synthetic_dataset, anchor_scenes=["alpha"], converged_p=0.5).train_set
    ks = list(range(48))
    for k, (_, _, flag) in zip(ks, ds.__getitems__(ks)):
        d = ds.draw(k)
        assert bool(flag) == (d.pair.record.scene == "alpha" and not d.converged)


def test_every_image_anchored_is_allowed_when_converged_patches_are_the_lesson(synthetic_dataset):
    with pytest.raises(ValueError, match=r"to learn from its target \(or set data.converged_p\)"):
        make_dm(synthetic_dataset, anchor_scenes=["alpha", "gamma"])
    ds = make_dm(synthetic_dataset, anchor_scenes=["alpha", "gamma"], converged_p=0.25).train_set
    flags = [bool(f) for _, _, f in ds.__getitems__(list(range(32)))]
    assert any(flags) and not all(flags)
