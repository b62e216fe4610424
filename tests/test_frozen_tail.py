"""The frozen batch-norm tail (freeze_bn_from): statistics estimated at an epoch, then fixed to the end."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch
from test_train import compose_cfg
from torch import nn

from nriqa.training.batchnorm import batchnorms
from nriqa.training.fit import train
from nriqa.training.frozen_tail import FrozenBatchNormTail, check_tail


def test_tail_estimates_at_its_epoch_then_keeps_the_statistics(tmp_path, synthetic_dataset):
    # smoke schedule: 2 epochs of 3 batches; the tail starts at epoch 1 with a 4-batch estimate
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "freeze_bn_from=1", "freeze_bn_batches=4")
    _, objects = train(cfg)
    model = objects["model"]
    # estimated over 4 batches (momentum None counts them), then never updated by epoch 1's 3 training steps
    assert all(int(m.num_batches_tracked) == 4 for m in batchnorms(model.net))
    assert model.freeze_bn is True
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert objects["best_ckpt"] == str(last)
    saved = torch.load(last, map_location="cpu", weights_only=True)
    assert saved["hyper_parameters"]["freeze_bn_tail"] == {"from_epoch": 1, "batches": 4}
    net = model.net.state_dict()
    assert all(torch.equal(v, net[k[len("net.") :]]) for k, v in saved["state_dict"].items() if "running" in k)


def test_without_a_tail_training_moves_the_statistics(tmp_path, synthetic_dataset):
    # the control: the same run without the tail counts every training step (2 epochs x 3 batches)
    _, objects = train(compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast"))
    assert all(int(m.num_batches_tracked) == 6 for m in batchnorms(objects["model"].net))
    assert objects["model"].freeze_bn is False


def _tiny_module() -> SimpleNamespace:
    torch.manual_seed(0)
    net = nn.Sequential(nn.Conv2d(3, 4, 3), nn.BatchNorm2d(4)).train()
    return SimpleNamespace(net=net, freeze_bn=False, hparams={})


def test_a_run_resumed_past_the_start_stays_frozen_without_estimating_again():
    module = _tiny_module()
    before = {k: v.clone() for k, v in module.net.state_dict().items()}
    trainer = SimpleNamespace(current_epoch=5, datamodule=None)  # no loader: estimating would fail
    FrozenBatchNormTail(from_epoch=3, batches=2).on_train_epoch_start(trainer, module)
    assert module.freeze_bn is True and not module.net[1].training
    assert all(torch.equal(before[k], v) for k, v in module.net.state_dict().items())
    assert "freeze_bn_tail" not in module.hparams


def test_before_its_start_the_tail_does_nothing():
    module = _tiny_module()
    FrozenBatchNormTail(from_epoch=3, batches=2).on_train_epoch_start(SimpleNamespace(current_epoch=2), module)
    assert module.freeze_bn is False and module.net[1].training


@pytest.mark.parametrize(
    "args, message",
    [
        ((2, 500, 2, False, 0), "0 <= E < 2"),
        ((-1, 500, 2, False, 0), "0 <= E < 2"),
        ((1.5, 500, 2, False, 0), "0 <= E < 2"),
        ((True, 500, 2, False, 0), "0 <= E < 2"),
        ((1, 0, 2, False, 0), "at least 1"),
        ((1, 500, 2, True, 0), "freeze_bn=true"),
        ((1, 500, 2, False, 500), "bn_refresh"),
    ],
)
def test_check_refuses_a_tail_the_run_cannot_have(args, message):
    with pytest.raises(ValueError, match=message):
        check_tail(*args)
    assert check_tail(None, 500, 2, True, 500) is None  # no tail: nothing to check


def test_train_refuses_a_tail_beside_bn_refresh_before_any_work(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "freeze_bn_from=1", "bn_refresh=3")
    with pytest.raises(ValueError, match="bn_refresh"):
        train(cfg)
    assert not (tmp_path / "checkpoints").exists()
