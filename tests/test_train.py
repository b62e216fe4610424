"""train.py and its configs: every experiment runs, checkpoints rebuild the net, errors are one line."""

from __future__ import annotations

import os
from pathlib import Path

import lightning as L
import pytest
import torch
from conftest import REPO, load_script, make_dataset
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig
from torch import nn

from nriqa.configs import CONFIG_DIR
from nriqa.data.datamodule import NRIQADataModule
from nriqa.training.checkpoint import CheckpointError, load_net_from_checkpoint
from nriqa.training.fit import train, user_error
from nriqa.training.module import NRIQAModule

EXPERIMENTS = sorted(p.stem for p in (CONFIG_DIR / "experiment").glob("*.yaml"))


def compose_cfg(tmp_path: Path, data_dir: Path | str, *overrides: str) -> DictConfig:
    """The real train config, writing into ``tmp_path``, on the smoke schedule, on CPU."""
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        return compose(
            "train",
            overrides=[
                f"paths.data_dir={data_dir}",
                f"paths.output_dir={tmp_path}",
                f"paths.log_dir={tmp_path}/logs",
                "schedule=smoke",
                "trainer.accelerator=cpu",
                "trainer.enable_progress_bar=false",
                "trainer.enable_model_summary=false",
                *overrides,
            ],
        )


def test_experiments_exist():
    assert {"patch", "fcnn", "fcnn11", "fcnn_fast"} <= set(EXPERIMENTS)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_runs_one_batch(experiment, synthetic_dataset, striped_dataset, tmp_path):
    # 32x32 patches keep the big FCNNs quick on CPU; the configs are otherwise the real ones
    overrides = (
        f"experiment={experiment}",
        "debug=fdr",
        "data.val_scene=beta",
        "data.batch_size=1",
        "data.patch_size=32",
    )
    cfg = compose_cfg(tmp_path, synthetic_dataset, *overrides)
    if cfg.data.get("albedo_pass"):  # the model reads the albedo pass beside each reference
        cfg = compose_cfg(tmp_path, striped_dataset, *overrides)
    metrics, objects = train(cfg)
    (row,) = objects["model"].history
    assert torch.isfinite(torch.tensor(row["train/loss"])) and "val/loss" in row
    assert objects["model"].net.output == ("patch" if experiment == "patch" else "map")
    if experiment.startswith("unet_fast"):  # a context model states the side of the pieces it learnt from
        assert objects["model"].net.window == 32


def test_checkpoint_alone_rebuilds_the_net(synthetic_dataset, tmp_path):
    overrides = ("experiment=fcnn_fast", "data.val_scene=beta", "trainer.max_epochs=2", "+model.net.width=8")
    cfg = compose_cfg(tmp_path, synthetic_dataset, *overrides)
    metrics, objects = train(cfg)
    assert {"train/loss", "val/loss", "val/pcc", "val/srocc", "val/tau", "train/tau"} <= set(metrics)
    best = Path(objects["best_ckpt"])
    assert best.is_file() and best.parent == tmp_path / "checkpoints"
    assert (tmp_path / "checkpoints" / "last.ckpt").is_file()
    assert (tmp_path / "training_curves.png").stat().st_size > 1000
    assert (tmp_path / "csv" / "metrics.csv").is_file()
    assert list((tmp_path / "tensorboard").glob("events.*"))
    assert len(objects["model"].history) == 2

    net = load_net_from_checkpoint(best)
    # the trained module, set to the best epoch's weights, must agree exactly with the rebuilt net
    reference = objects["model"].net
    state = torch.load(best, weights_only=True)["state_dict"]
    reference.load_state_dict({k[len("net.") :]: v for k, v in state.items() if k.startswith("net.")})
    x = torch.rand(2, 3, 64, 64)
    with torch.no_grad():
        assert torch.equal(net(x), reference.eval()(x))
    assert not net.training


def test_without_val_scene_keeps_the_last_checkpoint(synthetic_dataset, tmp_path):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "trainer.max_epochs=1", "+model.net.width=8")
    metrics, objects = train(cfg)
    assert cfg.optimized_metric == "train/loss" and "train/loss" in metrics and "val/loss" not in metrics
    assert Path(objects["best_ckpt"]).is_file()
    assert load_net_from_checkpoint(objects["best_ckpt"]).output == "map"


def test_cosine_schedule_anneals_the_rate_to_zero_over_the_run(synthetic_dataset, tmp_path):
    cfg = compose_cfg(
        tmp_path, synthetic_dataset, "experiment=fcnn_fast", "+model/scheduler=cosine", "+model.net.width=8"
    )
    assert cfg.model.scheduler.T_max == cfg.trainer.max_epochs == 2  # the smoke schedule's epochs
    _, objects = train(cfg)
    optimizer = objects["trainer"].optimizers[0]
    assert optimizer.param_groups[0]["lr"] == pytest.approx(0.0, abs=1e-12)
    assert objects["trainer"].lr_scheduler_configs[0].scheduler.base_lrs == [cfg.schedule.map.lr]


def test_several_dataset_roots_from_the_command_line(synthetic_dataset, tmp_path):
    other = make_dataset(tmp_path / "longer", size=64, scenes=("alpha",), spps=(256,))
    cfg = compose_cfg(
        tmp_path, f"[{synthetic_dataset},{other}]", "experiment=fcnn_fast", "debug=fdr", "+model.net.width=8"
    )
    metrics, objects = train(cfg)
    assert "train/loss" in metrics
    assert any(p.record.spp == 256 for p in objects["datamodule"].train_pairs)
    assert load_net_from_checkpoint(objects["best_ckpt"]).output == "map"  # weights_only: no ListConfig inside


def test_unknown_scene_is_a_one_line_error(synthetic_dataset, tmp_path):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "data.val_scene=nope")
    with pytest.raises(ValueError) as info:
        train(cfg)
    message = user_error(info.value)
    assert "alpha, beta, gamma" in message and "\n" not in message


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("seed=abc", "seed=abc: give a whole number >= 0"),
        (
            "schedule.map.epochs=abc",
            "trainer.max_epochs=abc: give a whole number >= 1 (schedule.<model>.epochs sets it)",
        ),
        ("schedule.map.epochs=0", "trainer.max_epochs=0: give a whole number >= 1"),
        ("data.patch_size=2.5", "data.patch_size=2.5: give a whole number of pixels >= 1"),
        ("data.batch_size=abc", "data.batch_size=abc: give a whole number of patches >= 1"),
        ("data.num_workers=-1", "data.num_workers=-1: give a whole number of worker processes >= 0"),
    ],
)
def test_a_count_of_the_wrong_type_is_one_line_naming_its_key(synthetic_dataset, tmp_path, override, message):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=unet_fast", "data.val_scene=beta", override)
    with pytest.raises(Exception) as info:  # the data module's ValueError comes wrapped by Hydra's instantiate
        train(cfg)
    assert user_error(info.value).startswith(message) and "\n" not in user_error(info.value)


def test_missing_dataset_exits_with_one_line(tmp_path):
    script = load_script("train.py")
    cfg = compose_cfg(tmp_path, tmp_path / "none")
    # __wrapped__ is train.py's main without Hydra's command-line runner (which prints the message)
    with pytest.raises(SystemExit) as info:
        script.main.__wrapped__(cfg)
    message = str(info.value.code)
    assert message.startswith("error: ") and "no manifest" in message and "\n" not in message


def test_bad_checkpoint(tmp_path):
    with pytest.raises(CheckpointError, match="no such checkpoint"):
        load_net_from_checkpoint(tmp_path / "missing.ckpt")
    (tmp_path / "junk.ckpt").write_bytes(b"junk")
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        load_net_from_checkpoint(tmp_path / "junk.ckpt")


class NaNLoss(nn.Module):
    def forward(self, pred, target):
        return (pred - target).abs().mean() * float("nan")


def test_nonfinite_loss_is_recorded_and_stops(synthetic_dataset, tmp_path):
    dm = NRIQADataModule(
        synthetic_dataset, val_scene=None, patch_size=32, target="patch_mae", batch_size=2, batches_per_epoch=4
    )
    model = NRIQAModule({"name": "patch_cnn"}, NaNLoss(), optimizer=lambda params: torch.optim.SGD(params, lr=0.1))
    before = [p.detach().clone() for p in model.net.parameters()]
    trainer = L.Trainer(
        max_epochs=3,
        accelerator="cpu",
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        default_root_dir=tmp_path,
    )
    trainer.fit(model, dm)
    assert model.nonfinite_steps == 1 and model.first_nonfinite_step == 0
    assert len(model.history) == 1 and model.history[0]["train/nonfinite_steps"] == 1
    assert all(torch.equal(a, b) for a, b in zip(before, model.net.parameters()))


def test_project_root_is_the_checkout_else_the_working_directory(monkeypatch, tmp_path):
    from nriqa.training import fit

    monkeypatch.delenv("PROJECT_ROOT", raising=False)
    fit.set_project_root()
    assert os.environ["PROJECT_ROOT"] == str(REPO)  # tests run from a source checkout
    monkeypatch.delenv("PROJECT_ROOT")
    monkeypatch.setattr(fit, "source_checkout", lambda: None)  # an installed package
    monkeypatch.chdir(tmp_path)
    fit.set_project_root()
    assert os.environ["PROJECT_ROOT"] == str(tmp_path)
    monkeypatch.setenv("PROJECT_ROOT", "/somewhere/else")  # the user's choice wins
    fit.set_project_root()
    assert os.environ["PROJECT_ROOT"] == "/somewhere/else"
