"""Folds trained side by side (nriqa.training.stacked): the same training as one fold at a time, resumable."""

from __future__ import annotations

import copy
import json

import pytest
import torch
from hydra import compose, initialize_config_dir
from torch import nn
from torch.overrides import TorchFunctionMode

from nriqa.configs import CONFIG_DIR
from nriqa.data.folds import FoldError
from nriqa.losses import create_loss
from nriqa.models import create_model
from nriqa.training import stacked
from nriqa.training.checkpoint import load_net_from_checkpoint
from nriqa.training.crossval import RESULT_NAME, crossval
from nriqa.training.stacked import STATE_NAME, BatchNormByOps, StackedNets, parse_max_time

TINY = [
    "schedule=smoke",
    "trainer.max_epochs=2",
    "data.batches_per_epoch=3",
    "data.patch_size=32",
    "trainer.enable_progress_bar=false",
    "trainer.enable_model_summary=false",
    "logger=csv",
    "++trainer.num_sanity_val_steps=0",
    "+model.net.width=8",
]


@pytest.mark.parametrize("name", ["fcnn_fast", "unet_fast"])
def test_stacked_steps_equal_separate_steps(name):
    # In double precision the rounding of the two ways of computing is far below Adam's eps, so the
    # folds must follow their separate runs to the last digits: weights and batch-norm statistics.
    torch.manual_seed(0)
    base = create_model(name, width=8).double()
    folds = 3
    nets = [copy.deepcopy(base) for _ in range(folds)]
    stack = StackedNets(base, folds)
    loss_fn = create_loss("joint", signed=True)
    opt = torch.optim.Adam(stack.params.values(), lr=1e-3)
    opts = [torch.optim.Adam(n.parameters(), lr=1e-3) for n in nets]
    for _ in range(3):
        x = torch.rand(folds, 4, 3, 32, 32, dtype=torch.float64)
        y = torch.rand(folds, 4, 1, 32, 32, dtype=torch.float64)
        opt.zero_grad()
        losses = stack.losses(x, y, loss_fn)
        losses.sum().backward()
        opt.step()
        for f, (net, o) in enumerate(zip(nets, opts)):
            o.zero_grad()
            loss = loss_fn(net(x[f]), y[f])
            loss.backward()
            o.step()
            assert losses[f].item() == pytest.approx(loss.item(), abs=1e-12)
    for f, net in enumerate(nets):
        got = stack.fold_state(f)
        for k, v in net.state_dict().items():
            assert torch.allclose(got[k].double(), v.double(), rtol=0, atol=1e-9), k


@pytest.mark.parametrize("momentum", [0.1, None])
def test_batch_norm_by_ops_is_batch_norm(momentum):
    torch.manual_seed(1)
    ref = nn.BatchNorm2d(5, momentum=momentum, eps=1e-3).double()
    with torch.no_grad():
        ref.weight.uniform_(0.5, 2)
        ref.bias.uniform_(-1, 1)
    ops = copy.deepcopy(ref)
    ops.__class__ = BatchNormByOps
    for _ in range(3):
        x = (torch.randn(4, 5, 6, 7, dtype=torch.float64) * 3 + 2).requires_grad_(True)
        xo = x.detach().clone().requires_grad_(True)
        y, yo = ref(x), ops(xo)
        w = torch.randn_like(y)
        (y * w).sum().backward()
        (yo * w).sum().backward()
        assert torch.allclose(yo, y, atol=1e-12) and torch.allclose(xo.grad, x.grad, atol=1e-12)
    for (k, v), (ko, vo) in zip(ref.state_dict().items(), ops.state_dict().items()):
        assert k == ko and torch.allclose(vo.double(), v.double(), atol=1e-12), k
    assert torch.allclose(ops.weight.grad, ref.weight.grad, atol=1e-12)
    ops.eval()  # outside training it is batch norm itself
    x = torch.randn(2, 5, 3, 3, dtype=torch.float64)
    assert torch.allclose(ops(x), ref.eval()(x), atol=1e-12)
    with pytest.raises(ValueError, match="more than 1 value per channel"):
        ops.train()(torch.randn(1, 5, 1, 1, dtype=torch.float64))


class _BatchNormCalls(TorchFunctionMode):
    def __init__(self):
        super().__init__()
        self.calls = 0

    def __torch_function__(self, func, types, args=(), kwargs=None):
        if func in (torch.batch_norm, torch.nn.functional.batch_norm, torch.native_batch_norm):
            self.calls += 1
        return func(*args, **(kwargs or {}))


@pytest.mark.parametrize("name", ["fcnn_fast", "unet_fast"])
def test_stacked_step_asks_no_batch_norm_kernel(name):
    # torch.batch_norm asks a batched tensor for its memory layout on CUDA, which vmap cannot answer (stop 48's
    # H100): the stacked step must not call it. The separate network does, so the probe is seen to work.
    net = create_model(name, width=8)
    x, y = torch.rand(2, 2, 3, 32, 32), torch.rand(2, 2, 1, 32, 32)
    with _BatchNormCalls() as seen:
        net(x[0])
    assert seen.calls > 0
    with _BatchNormCalls() as seen:
        StackedNets(net, 2).losses(x, y, create_loss("joint", signed=True)).sum().backward()
    assert seen.calls == 0


def _cfg(data, out, *extra):
    overrides = [f"paths.data_dir={data}", f"crossval.out_dir={out}", "experiment=fcnn_fast", *TINY, *extra]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        return compose("crossval", overrides=overrides)


def _weights(out, scene):
    return torch.load(out / "folds" / scene / "checkpoints" / "last.ckpt", weights_only=True)["state_dict"]


def test_crossval_stacked_trains_as_one_by_one(synthetic_dataset, tmp_path):
    one = crossval(_cfg(synthetic_dataset, tmp_path / "one"))
    side = crossval(_cfg(synthetic_dataset, tmp_path / "side", "crossval.stacked=true"))
    assert [r["scene"] for r in side] == ["alpha", "beta", "gamma"]
    assert [r["steps"] for r in side] == [r["steps"] for r in one] == [6, 6, 6]
    assert all(r["stacked_folds"] == 3 and r["image"]["n"] == 8 for r in side)
    assert (tmp_path / "side" / "folds.md").is_file() and (tmp_path / "side" / "images.csv").is_file()
    for scene in ("alpha", "beta", "gamma"):
        a, b = _weights(tmp_path / "one", scene), _weights(tmp_path / "side", scene)
        assert set(a) == set(b)
        # The same patches, initial weights and updates: every weight agrees to float32 rounding. The
        # convolutions' biases are left out (those before batch norm have a zero gradient up to rounding,
        # which Adam scales to steps of the learning rate's size), and the running means that follow them.
        for k in a:
            weight = a.get(k.removesuffix(".bias") + ".weight")
            if (k.endswith(".bias") and weight is not None and weight.ndim == 4) or k.endswith("running_mean"):
                continue
            assert torch.allclose(a[k], b[k], rtol=0, atol=2e-5), (scene, k)
        load_net_from_checkpoint(tmp_path / "side" / "folds" / scene / "checkpoints" / "last.ckpt")
    # done folds are skipped on a rerun, stacked or not
    again = crossval(_cfg(synthetic_dataset, tmp_path / "side", "crossval.stacked=true"))
    assert [r["image"] for r in again] == [r["image"] for r in side]


def test_stacked_resumes_where_it_was_cut(synthetic_dataset, tmp_path, monkeypatch):
    whole = tmp_path / "whole"
    crossval(_cfg(synthetic_dataset, whole, "crossval.stacked=true", "crossval.scenes=[alpha,beta]"))

    cut = tmp_path / "cut"
    save = stacked._save_atomic

    def save_then_die(obj, path):
        save(obj, path)
        if path.name == STATE_NAME:
            raise KeyboardInterrupt  # killed right after the first epoch's state was written

    monkeypatch.setattr(stacked, "_save_atomic", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        crossval(_cfg(synthetic_dataset, cut, "crossval.stacked=true", "crossval.scenes=[alpha,beta]"))
    assert torch.load(cut / STATE_NAME, weights_only=True)["epoch"] == 1
    assert not (cut / "folds" / "alpha" / RESULT_NAME).exists()
    monkeypatch.setattr(stacked, "_save_atomic", save)
    crossval(_cfg(synthetic_dataset, cut, "crossval.stacked=true", "crossval.scenes=[alpha,beta]"))
    for scene in ("alpha", "beta"):
        a, b = _weights(whole, scene), _weights(cut, scene)
        assert all(torch.equal(a[k], b[k]) for k in a), scene
        assert json.loads((cut / "folds" / scene / RESULT_NAME).read_text())["steps"] == 6

    # the state of other folds is not taken for these
    with pytest.raises(FoldError, match="delete it"):
        stacked.train_stacked(_cfg(synthetic_dataset, cut, "crossval.stacked=true"), ["alpha", "gamma"], cut)


def _beta_fails_from_step_2(monkeypatch):
    losses = StackedNets.losses
    calls = []

    def beta_fails(self, x, y, loss_fn):
        out = losses(self, x, y, loss_fn)
        calls.append(1)
        if len(calls) >= 3:
            out = out * torch.tensor([1.0, float("nan")])
        return out

    monkeypatch.setattr(StackedNets, "losses", beta_fails)


def test_stacked_fold_with_nonfinite_loss_stops_alone(synthetic_dataset, tmp_path, monkeypatch):
    _beta_fails_from_step_2(monkeypatch)
    results = stacked.train_stacked(
        _cfg(synthetic_dataset, tmp_path, "crossval.stacked=true"), ["alpha", "beta"], tmp_path
    )
    assert "first_nonfinite_step" not in results["alpha"]
    assert results["beta"]["first_nonfinite_step"] == 2 and results["beta"]["nonfinite_steps"] == 1
    state = torch.load(tmp_path / STATE_NAME, weights_only=True)
    assert state["history"][-1]["loss"][1] == 0.0 and state["history"][-1]["loss"][0] > 0  # beta took no step after
    assert all(torch.isfinite(v).all() for v in _weights(tmp_path, "beta").values() if v.is_floating_point())


def test_stacked_fold_that_skips_nonfinite_steps_counts_them(synthetic_dataset, tmp_path, monkeypatch):
    # model.stop_on_nonfinite=false: each bad step is skipped and the fold goes on; the result says when and how often
    _beta_fails_from_step_2(monkeypatch)
    cfg = _cfg(synthetic_dataset, tmp_path, "crossval.stacked=true", "+model.stop_on_nonfinite=false")
    results = stacked.train_stacked(cfg, ["alpha", "beta"], tmp_path)
    assert "first_nonfinite_step" not in results["alpha"] and results["alpha"]["steps"] == 6
    assert results["beta"]["first_nonfinite_step"] == 2 and results["beta"]["nonfinite_steps"] == 6 - 2
    assert all(torch.isfinite(v).all() for v in _weights(tmp_path, "beta").values() if v.is_floating_point())


@pytest.mark.parametrize(
    "extra, message",
    [
        ("hard_sampling.mix=0.5", "hard_sampling.mix"),
        ("freeze_bn=true", "freeze_bn"),
        ("freeze_bn_from=1", "freeze_bn_from"),
        ("bn_refresh=2", "bn_refresh"),
        ("data.anchor_scenes=[alpha]", "data.anchor_scenes"),
        ("+trainer.gradient_clip_val=1.0", "gradient_clip_val"),
        ("++model.scheduler={_target_:torch.optim.lr_scheduler.ReduceLROnPlateau,_partial_:true}", "watches a metric"),
    ],
)
def test_stacked_refuses_what_it_does_not_do(synthetic_dataset, tmp_path, extra, message):
    cfg = _cfg(synthetic_dataset, tmp_path, "crossval.stacked=true", extra)
    with pytest.raises(FoldError, match=message):
        crossval(cfg)
    assert not (tmp_path / STATE_NAME).exists()


@pytest.mark.parametrize(
    "extra, message",
    [
        (
            "trainer.max_epochs=2.5",
            "trainer.max_epochs=2.5: give a whole number >= 1 (schedule.<model>.epochs sets it)",
        ),
        ("seed=abc", "seed=abc: give a whole number >= 0"),
    ],
)
def test_stacked_reads_its_counts_as_one_fold_does(synthetic_dataset, tmp_path, extra, message):
    # the same check and line as nriqa.training.fit.train, before any data is loaded or anything written
    cfg = _cfg(synthetic_dataset, tmp_path, "crossval.stacked=true", extra)
    with pytest.raises(ValueError) as info:
        stacked.train_stacked(cfg, ["alpha", "beta"], tmp_path)
    assert str(info.value) == message
    assert not (tmp_path / STATE_NAME).exists()


def test_parse_max_time():
    assert parse_max_time(None) is None
    assert parse_max_time("00:00:07:00") == 420.0
    assert parse_max_time("01:02:03:04") == ((24 + 2) * 60 + 3) * 60 + 4
    assert parse_max_time({"minutes": 2}) == 120.0
    with pytest.raises(ValueError, match="DD:HH:MM:SS"):
        parse_max_time("7 minutes")
