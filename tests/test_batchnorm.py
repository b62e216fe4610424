"""Batch-norm statistics when fine-tuning: estimated over many batches, then held fixed while the weights train."""

from __future__ import annotations

import pytest
import torch
from test_train import compose_cfg
from torch import nn

from nriqa.inference.pretrained import load_pretrained
from nriqa.training.batchnorm import batchnorms, estimate_batchnorm, freeze_batchnorm, repeated
from nriqa.training.fit import train


def _tiny() -> nn.Module:
    torch.manual_seed(0)
    return nn.Sequential(nn.Conv2d(3, 4, 3), nn.BatchNorm2d(4), nn.ReLU(), nn.Conv2d(4, 1, 1), nn.BatchNorm2d(1))


def test_running_statistics_become_the_average_over_batches():
    net = _tiny().eval()
    bn = net[1]
    bn.momentum = 0.3
    weights = {k: v.clone() for k, v in net.state_dict().items() if "running" not in k and "num_batches" not in k}
    g = torch.Generator().manual_seed(1)
    # batches of very different brightness: an exponential average would follow the last ones
    batches = [(torch.rand(2, 3, 8, 8, generator=g) * (1 + 10 * i), None) for i in range(4)]
    assert estimate_batchnorm(net, batches, 4) == 4
    with torch.no_grad():
        feats = [net[0](x) for x, _ in batches]
    mean = torch.stack([f.mean((0, 2, 3)) for f in feats]).mean(0)
    var = torch.stack([f.var((0, 2, 3), unbiased=True) for f in feats]).mean(0)
    torch.testing.assert_close(bn.running_mean, mean)
    torch.testing.assert_close(bn.running_var, var)
    assert int(bn.num_batches_tracked) == 4
    # the weights, the momentum and every module's mode are as they were
    assert all(torch.equal(weights[k], v) for k, v in net.state_dict().items() if k in weights)
    assert bn.momentum == 0.3 and not any(m.training for m in net.modules())


def test_estimate_stops_at_n_and_cycles_a_short_loader():
    net = _tiny()
    loader = [torch.rand(2, 3, 8, 8) for _ in range(2)]
    assert estimate_batchnorm(net, repeated(loader), 5) == 5
    assert int(net[1].num_batches_tracked) == 5
    assert net.training  # a network in train mode stays so
    assert list(repeated([])) == []


@pytest.mark.parametrize(("batches", "n", "message"), [([torch.rand(1, 3, 8, 8)], 0, "n >= 1"), ([], 3, "no batches")])
def test_estimate_refuses_nothing_to_estimate_from(batches, n, message):
    with pytest.raises(ValueError, match=message):
        estimate_batchnorm(_tiny(), batches, n)


def test_freeze_puts_only_batchnorm_in_eval_mode():
    net = freeze_batchnorm(_tiny().train())
    assert [m.training for m in net] == [True, False, True, True, False]
    assert batchnorms(net) == [net[1], net[4]]


def test_frozen_fine_tune_trains_weights_and_keeps_statistics(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "init_from=fcnn_fast", "freeze_bn=true")
    _, objects = train(cfg)
    shipped, trained = load_pretrained("fcnn_fast").state_dict(), objects["model"].net.state_dict()
    stats = [k for k in shipped if "running" in k or "num_batches" in k]
    assert stats and all(torch.equal(shipped[k], trained[k]) for k in stats)
    assert not torch.equal(shipped["net.1.weight"], trained["net.1.weight"])
    assert objects["model"].hparams["freeze_bn"] is True


def test_fine_tune_estimates_statistics_first(tmp_path, synthetic_dataset):
    cfg = compose_cfg(
        tmp_path, synthetic_dataset, "experiment=fcnn_fast", "init_from=fcnn_fast", "bn_estimate=4", "freeze_bn=true"
    )
    _, objects = train(cfg)
    net = objects["model"].net
    assert objects["model"].hparams["bn_estimate"] == 4
    assert all(int(m.num_batches_tracked) == 4 for m in batchnorms(net))  # estimated, then never updated
    shipped = load_pretrained("fcnn_fast").state_dict()
    assert not torch.equal(shipped["net.2.running_mean"], net.state_dict()["net.2.running_mean"])


def test_refresh_after_training_rewrites_last_checkpoint(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "bn_refresh=3")
    _, objects = train(cfg)
    assert objects["model"].hparams["bn_refresh"] == 3
    net = objects["model"].net
    assert all(int(m.num_batches_tracked) == 3 for m in batchnorms(net))  # averaged over 3, not the training steps
    last = torch.load(tmp_path / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)
    saved = {k: v for k, v in last["state_dict"].items() if "running_mean" in k}
    assert saved and all(torch.equal(v, net.state_dict()[k[len("net.") :]]) for k, v in saved.items())
    assert last["hyper_parameters"]["bn_refresh"] == 3
    # no held-out scene here: the checkpoint the run reports is the refreshed one, not the epoch's before it
    assert cfg.data.get("val_scene") is None
    assert objects["best_ckpt"] == str(tmp_path / "checkpoints" / "last.ckpt")


def test_refresh_with_a_held_out_scene_reports_the_refreshed_checkpoint(tmp_path, synthetic_dataset):
    # the epoch checkpoint of lowest val/loss was written before the refresh: nriqa-crossval's fold tables
    # must score the refreshed weights, the file nriqa-evaluate --crossval reads too
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "bn_refresh=3", "data.val_scene=beta")
    _, objects = train(cfg)
    last = tmp_path / "checkpoints" / "last.ckpt"
    assert objects["best_ckpt"] == str(last)
    assert any(p.name != "last.ckpt" for p in (tmp_path / "checkpoints").glob("*.ckpt"))  # an epoch file exists
    saved = torch.load(last, map_location="cpu", weights_only=True)["state_dict"]
    net = objects["model"].net.state_dict()
    assert all(torch.equal(v, net[k[len("net.") :]]) for k, v in saved.items() if "running_var" in k)
