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


def test_body_only_loads_all_but_the_head():
    # unet_fast_ssim is unet_fast's body with a head of two maps: its body starts from the shipped default
    net = create_model("unet_fast_ssim", window=64)
    head = {k: v.clone() for k, v in net.state_dict().items() if k.startswith("head.")}
    with pytest.raises(WarmStartError, match="do not fit the model being trained"):
        warm_start(net, "unet_fast")  # the heads differ: nothing loads without body_only
    assert warm_start(net, "unet_fast", body_only=True) is net
    shipped = load_pretrained("unet_fast").state_dict()
    state = net.state_dict()
    body = [k for k in state if not k.startswith("head.")]
    assert body and all(torch.equal(state[k], shipped[k]) for k in body)
    assert head and all(torch.equal(state[k], v) for k, v in head.items())  # the head keeps its start


def test_body_only_needs_a_head_and_a_matching_body():
    with pytest.raises(WarmStartError, match="has no 'head' module"):
        warm_start(create_model("fcnn_fast"), "fcnn_fast", body_only=True)
    net = create_model("unet_fast_ssim", window=64, width=16)
    with pytest.raises(WarmStartError, match="of another shape"):
        warm_start(net, "unet_fast", body_only=True)


def test_body_only_is_refused_without_a_source_or_with_anchors(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "init_body_only=true")
    with pytest.raises(ValueError, match="init_body_only=true loads the body of init_from's network"):
        train(cfg)
    cfg = compose_cfg(
        tmp_path,
        synthetic_dataset,
        "experiment=fcnn_fast",
        "init_from=patch_cnn",
        "init_body_only=true",
        "data.anchor_scenes=[alpha]",
    )
    with pytest.raises(ValueError, match="init_body_only=true starts with an untrained head"):
        train(cfg)


def test_training_starts_from_the_shipped_body(tmp_path, synthetic_dataset):
    cfg = compose_cfg(
        tmp_path,
        synthetic_dataset,
        "experiment=unet_fast",
        "model.net.name=unet_fast_ssim",
        "data.patch_size=64",
        "debug=fdr",
        "init_from=unet_fast",
        "init_body_only=true",
        "model.optimizer.lr=0",
    )
    _, objects = train(cfg)
    shipped = dict(load_pretrained("unet_fast").named_parameters())
    trained = dict(objects["model"].net.named_parameters())
    body = [k for k in trained if not k.startswith("head.")]
    assert body and all(torch.equal(trained[k], shipped[k]) for k in body)
    assert objects["model"].hparams["init_body_only"] is True
