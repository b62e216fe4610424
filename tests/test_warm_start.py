"""Fine-tuning: init_from starts a training from shipped weights or a checkpoint, or says why it cannot."""

from __future__ import annotations

import pytest
import torch
from test_train import compose_cfg

from nriqa.data.folds import FoldError
from nriqa.inference.pretrained import PretrainedError, load_pretrained
from nriqa.models import create_model
from nriqa.training.crossval import fold_scenes
from nriqa.training.fit import train
from nriqa.training.warm_start import WarmStartError, warm_start


def _equal_states(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


@pytest.mark.parametrize("member", [0, 1])
def test_one_member_of_shipped_average(member):
    shipped = load_pretrained("dual_fast")  # the mean of two runs (map_mean)
    net = create_model("dual_fast")
    assert not _equal_states(net, shipped.members[member])
    assert warm_start(net, "dual_fast", member) is net
    assert _equal_states(net, shipped.members[member])
    assert not _equal_states(net, shipped.members[1 - member])  # the two runs differ: the right one was taken


def test_single_network_and_checkpoint(tmp_path, synthetic_dataset):
    net = create_model("fcnn_fast")
    warm_start(net, "fcnn_fast")
    assert _equal_states(net, load_pretrained("fcnn_fast"))

    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "trainer.max_epochs=1", "+model.net.width=8")
    _, objects = train(cfg)
    small = create_model("fcnn_fast", width=8)
    warm_start(small, objects["best_ckpt"])
    assert _equal_states(small, objects["model"].net)


@pytest.mark.parametrize(
    ("source", "member", "message"),
    [
        ("dual_fast", None, r"averages 2 networks; pick the one to start from with init_member=0\.\.1"),
        ("dual_fast", 2, r"init_member=2 is out of range: .* has members 0\.\.1"),
        ("fcnn_fast", 0, "is a single network; leave init_member unset"),
    ],
)
def test_member_choice_errors(source, member, message):
    with pytest.raises(WarmStartError, match=message):
        warm_start(create_model("dual_fast"), source, member)


def test_weights_of_another_model_load_nothing():
    net = create_model("unet_fast", window=64)
    before = {k: v.clone() for k, v in net.state_dict().items()}
    with pytest.raises(WarmStartError, match="do not fit the model being trained") as info:
        warm_start(net, "fcnn_fast")
    assert "\n" not in str(info.value)
    assert all(torch.equal(before[k], v) for k, v in net.state_dict().items())
    with pytest.raises(PretrainedError, match="no shipped weights 'nope'"):
        warm_start(net, "nope")


def test_training_starts_from_the_shipped_weights(tmp_path, synthetic_dataset):
    # with a learning rate of 0 the trained parameters are the shipped ones (batch-norm statistics move)
    cfg = compose_cfg(
        tmp_path, synthetic_dataset, "experiment=fcnn_fast", "debug=fdr", "init_from=fcnn_fast", "model.optimizer.lr=0"
    )
    _, objects = train(cfg)
    shipped = dict(load_pretrained("fcnn_fast").named_parameters())
    trained = dict(objects["model"].net.named_parameters())
    assert trained.keys() == shipped.keys() and all(torch.equal(trained[k], shipped[k]) for k in trained)
    assert objects["model"].hparams["init_from"] == "fcnn_fast"


def test_crossval_refuses_a_warm_start(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "init_from=fcnn_fast")
    with pytest.raises(FoldError, match="must start every fold from random weights"):
        fold_scenes(cfg)
