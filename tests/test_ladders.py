"""Ladder pairs: training items in pairs of one view at two sample counts, and the loss term on their difference."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from test_train import compose_cfg
from torch import nn

from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.ladders import ladder_key, ladder_partners
from nriqa.io.manifest import Record
from nriqa.losses import create_loss
from nriqa.losses.ladder import ladder_term
from nriqa.training.fit import train
from nriqa.training.module import NRIQAModule


def _rec(spp: int, algorithm: str = "path", role: str = "test", reference: str = "s/reference.exr") -> Record:
    return Record(
        f"{reference}/{algorithm}/{role}/{spp}", "s", 0, algorithm, role, spp, 0, "p", reference, 8, 8, 0.0, "b"
    )


def test_partners_share_reference_algorithm_and_role_within_the_span():
    records = [
        _rec(2),
        _rec(4),
        _rec(8),
        _rec(16),
        _rec(4, role="twin"),
        _rec(8, role="twin"),
        _rec(4, algorithm="bdpt"),
        _rec(4, reference="t/reference.exr"),
    ]
    assert ladder_partners(records, span=1) == [[1], [0, 2], [1, 3], [2], [5], [4], [], []]
    assert ladder_partners(records, span=3) == [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2], [5], [4], [], []]
    assert ladder_key(records[0]) == ladder_key(records[3]) != ladder_key(records[4])
    for span in (0, 1.5, -1):
        with pytest.raises(ValueError, match=r"data.ladder_span=.*: give a whole number of doublings >= 1$"):
            ladder_partners(records, span=span)


def _datamodule(root, **kwargs) -> NRIQADataModule:
    dm = NRIQADataModule(root, patch_size=32, batch_size=4, batches_per_epoch=4, val_patches=4, **kwargs)
    dm.setup("fit")
    return dm


def _choices(draw) -> tuple:
    return (draw.pair.record.id, draw.y, draw.x, draw.display, draw.jitter, draw.albedo, draw.pixel_sigma)


def test_odd_items_are_the_cut_before_them_at_another_rung(synthetic_dataset):
    dm = _datamodule(synthetic_dataset, ladder_pairs=True)
    ds = dm.train_set
    for k in range(0, 16, 2):
        first, second = ds.draw(k), ds.draw(k + 1)
        assert ladder_key(first.pair.record) == ladder_key(second.pair.record)
        assert first.pair.record.spp != second.pair.record.spp  # every synthetic rung has a neighbour within 4x
        assert 0.25 <= second.pair.record.spp / first.pair.record.spp <= 4
        assert _choices(dataclasses.replace(second, pair=first.pair)) == _choices(first)
    # the even items are the draws without pairs; items are pure functions of (seed, k)
    alone = _datamodule(synthetic_dataset).train_set
    assert [_choices(ds.draw(k)) for k in range(0, 16, 2)] == [_choices(alone.draw(k)) for k in range(0, 16, 2)]
    again = _datamodule(synthetic_dataset, ladder_pairs=True).train_set
    a, b = ds.__getitems__(list(range(8))), again.__getitems__(list(range(8)))
    assert all(torch.equal(x, y) for i, j in zip(a, b) for x, y in zip(i, j))
    # the two items of a pair: one view, so their references' patches are the same pixels
    noisy, target = a[0][0], a[0][1]
    assert not torch.equal(noisy, a[1][0]) and not torch.equal(target, a[1][1])


def test_pairs_need_an_even_batch(synthetic_dataset):
    with pytest.raises(ValueError, match="data.batch_size must be even, got 3"):
        NRIQADataModule(synthetic_dataset, batch_size=3, ladder_pairs=True)
    with pytest.raises(ValueError, match=r"data.ladder_span=0: give a whole number of doublings >= 1$"):
        NRIQADataModule(synthetic_dataset, ladder_span=0)


def test_ladder_term_is_the_error_of_the_differences_within_pairs():
    t = torch.tensor([0.2, 0.5, 0.9, 0.8]).view(4, 1, 1, 1).expand(4, 1, 3, 3)
    assert float(ladder_term(t + 0.3, t)) == pytest.approx(1e-3, rel=1e-3)  # a shared bias: Charbonnier's floor
    # the first pair read in the wrong order (0.5 then 0.4 for a true 0.2 -> 0.5): its difference is off by 0.4
    pred = torch.tensor([0.5, 0.4, 0.9, 0.8]).view(4, 1, 1, 1).expand(4, 1, 3, 3)
    expected = (((0.4**2 + 1e-6) ** 0.5) + 1e-3) / 2
    assert float(ladder_term(pred, t)) == pytest.approx(expected, rel=1e-4)
    with pytest.raises(ValueError, match="even batch, got 3"):
        ladder_term(t[:3], t[:3])


def _module(weight: float) -> NRIQAModule:
    net = nn.Sequential(nn.Conv2d(3, 1, 3, padding=1), nn.Sigmoid())
    return NRIQAModule(net, create_loss("charbonnier"), torch.optim.SGD, ladder_weight=weight)


def test_the_module_adds_the_weighted_term_to_the_training_loss_only():
    torch.manual_seed(0)
    x, y = torch.rand(4, 3, 8, 8), torch.rand(4, 1, 8, 8)
    plain, paired = _module(0.0), _module(2.0)
    paired.load_state_dict(plain.state_dict())
    base = plain._step((x, y), "train")
    with torch.no_grad():
        term = ladder_term(plain(x), y)
    loss = {stage: float(paired._step((x, y), stage).detach()) for stage in ("train", "val")}
    assert loss["train"] == pytest.approx(float(base.detach() + 2.0 * term), rel=1e-6)
    assert loss["val"] == pytest.approx(float(plain._step((x, y), "val").detach()), rel=1e-6)
    with pytest.raises(ValueError, match="ladder_weight must be >= 0"):
        _module(-1.0)


def test_training_with_ladder_pairs_draws_pairs_and_records_the_weight(tmp_path, synthetic_dataset):
    common = ("experiment=fcnn_fast", "debug=fdr", "data.val_scene=null")
    _, objects = train(compose_cfg(tmp_path / "a", synthetic_dataset, *common, "ladder_weight=0.5"))
    assert objects["datamodule"].train_set.ladder_pairs and objects["model"].hparams["ladder_weight"] == 0.5
    _, objects = train(compose_cfg(tmp_path / "b", synthetic_dataset, *common))
    assert not objects["datamodule"].train_set.ladder_pairs and objects["model"].hparams["ladder_weight"] == 0.0
    with pytest.raises(ValueError, match="ladder_weight must be >= 0, got -1.0"):
        train(compose_cfg(tmp_path / "c", synthetic_dataset, *common, "ladder_weight=-1"))
