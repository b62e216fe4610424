"""Cross validation and the loss stability study on the synthetic dataset, with the tiniest budget."""

from __future__ import annotations

import csv
import importlib
import json
import math
import os
import signal

import lightning as L
import pytest
import torch
from hydra import compose, initialize_config_dir

from nriqa.configs import CONFIG_DIR
from nriqa.core.ssim import ssim_map
from nriqa.data.datamodule import NRIQADataModule
from nriqa.eval.fold_eval import image_level, true_image_score
from nriqa.models import create_model
from nriqa.training.crossval import RESULT_NAME, crossval
from nriqa.training.fit import StoppedBySigterm
from nriqa.training.stability import stability

TINY = [
    "schedule=smoke",
    "trainer.max_epochs=1",
    "data.batches_per_epoch=2",
    "trainer.enable_progress_bar=false",
    "trainer.enable_model_summary=false",
    "logger=csv",
    "++trainer.num_sanity_val_steps=0",
]


def test_crossval_runs_every_fold_and_resumes(synthetic_dataset, tmp_path, capsys):
    overrides = [f"paths.data_dir={synthetic_dataset}", f"crossval.out_dir={tmp_path}", "experiment=fcnn_fast", *TINY]
    overrides += ["+model.net.width=8", "crossval.scenes=[alpha,beta]"]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        cfg = compose("crossval", overrides=overrides)
    results = crossval(cfg)
    assert [r["scene"] for r in results] == ["alpha", "beta"]
    for r in results:
        assert {"pcc", "srocc", "tau"} <= set(r["val"]) and r["image"]["n"] == 8
        assert all(row["scene"] == r["scene"] for row in r["images"])
        assert (tmp_path / "folds" / r["scene"] / "training_curves.png").is_file()
    rows = list(csv.DictReader((tmp_path / "folds.csv").open()))
    assert [row["scene"] for row in rows] == ["alpha", "beta"] and float(rows[0]["seconds"]) > 0
    assert "mean ± std" in (tmp_path / "folds.md").read_text()
    assert "pooled" in (tmp_path / "images.md").read_text()
    assert len(list(csv.DictReader((tmp_path / "images.csv").open()))) == 16

    # a rerun skips finished folds (their result files are untouched) and rewrites the same tables
    stamp = (tmp_path / "folds" / "alpha" / RESULT_NAME).stat().st_mtime_ns
    table = (tmp_path / "folds.csv").read_text()
    capsys.readouterr()
    again = crossval(cfg)
    out = capsys.readouterr().out
    assert "fold alpha: done, skipped" in out and "fold beta: done, skipped" in out and "training" not in out
    assert (tmp_path / "folds" / "alpha" / RESULT_NAME).stat().st_mtime_ns == stamp
    assert (tmp_path / "folds.csv").read_text() == table
    assert json.loads((tmp_path / "folds" / "beta" / RESULT_NAME).read_text())["val"] == again[1]["val"]


class SigtermAt(L.Callback):
    """Sends this process SIGTERM at the end of the first batch of epoch ``epoch``, as a scheduler's kill would."""

    def __init__(self, epoch: int) -> None:
        self.epoch = epoch

    def on_train_batch_end(self, trainer, *args) -> None:
        if trainer.current_epoch == self.epoch and not trainer.received_sigterm:
            os.kill(os.getpid(), signal.SIGTERM)


class EpochsSeen(L.Callback):
    """Records the epochs a fit trains (class-wide: Hydra builds the instance)."""

    seen: list[int] = []

    def on_train_epoch_start(self, trainer, *args) -> None:
        EpochsSeen.seen.append(trainer.current_epoch)


def test_a_fold_stopped_by_sigterm_exits_non_zero_unscored_and_resumes(synthetic_dataset, tmp_path, capsys):
    main = importlib.import_module("nriqa.cli.crossval").main.__wrapped__  # without Hydra's command-line runner
    overrides = [f"paths.data_dir={synthetic_dataset}", f"crossval.out_dir={tmp_path}", "experiment=fcnn_fast", *TINY]
    overrides += ["+model.net.width=8", "crossval.scenes=[alpha]", "trainer.max_epochs=2"]
    killed = overrides + ["+callbacks.sigterm._target_=test_crossval.SigtermAt", "+callbacks.sigterm.epoch=1"]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        cfg_killed = compose("crossval", overrides=killed)
    fold = tmp_path / "folds" / "alpha"
    # called as a library: Lightning's SystemExit of no status (0: "finished") comes out with status 143
    with pytest.raises(StoppedBySigterm) as info:
        crossval(cfg_killed)
    assert info.value.code == 128 + signal.SIGTERM and not (fold / RESULT_NAME).exists()
    capsys.readouterr()
    # and from the command line (it resumes epoch 1, and is stopped there again)
    with pytest.raises(SystemExit) as info:
        main(cfg_killed)
    # the CLI exits 143 with one line
    assert info.value.code == 128 + signal.SIGTERM
    # one error line (Lightning's own log lines, and in a full run other tests' stray log output, may surround it)
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and errors[0].startswith("error: stopped by SIGTERM") and "rerun" in errors[0]
    assert not (fold / RESULT_NAME).exists() and not (tmp_path / "folds.csv").exists()
    assert torch.load(fold / "checkpoints" / "last.ckpt", weights_only=False)["epoch"] == 0  # epoch 0 kept whole

    # the same command again resumes from there (it trains epoch 1 only) and finishes the fold
    EpochsSeen.seen.clear()
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        cfg = compose("crossval", overrides=overrides + ["+callbacks.seen._target_=test_crossval.EpochsSeen"])
    (result,) = crossval(cfg)
    assert EpochsSeen.seen == [1] and result["epochs"] == 2 and (fold / RESULT_NAME).is_file()


def test_crossval_folds_stay_within_data_scenes(synthetic_dataset, tmp_path):
    from nriqa.training.crossval import fold_scenes

    overrides = [f"paths.data_dir={synthetic_dataset}", f"crossval.out_dir={tmp_path}", "experiment=fcnn_fast"]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        held_back = compose("crossval", overrides=[*overrides, "data.scenes=[alpha,gamma]"])
        everything = compose("crossval", overrides=overrides)
    assert fold_scenes(held_back) == ["alpha", "gamma"] and fold_scenes(everything) == ["alpha", "beta", "gamma"]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        one = compose("crossval", overrides=[*overrides, "crossval.scenes=beta"])
        number = compose("crossval", overrides=[*overrides, "crossval.scenes=5"])
    assert fold_scenes(one) == ["beta"]  # one bare name: a list of one
    with pytest.raises(ValueError, match=r"^crossval.scenes=5: give a list of names, e.g. crossval.scenes=\[a,b\]$"):
        fold_scenes(number)


def test_stability_table(synthetic_dataset, tmp_path):
    forwarded = [f"paths.data_dir={synthetic_dataset}", f"stability.out_dir={tmp_path}", *TINY, "data.batch_size=2"]
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        cfg = compose(
            "stability",
            overrides=[*forwarded, "stability.experiments=[patch,fcnn_fast]", "stability.losses=[l2,joint_signed]"],
        )
        rows = stability(cfg, forwarded)
    assert [(r["experiment"], r["loss"]) for r in rows] == [
        ("patch", "l2"),
        ("patch", "joint_signed"),
        ("fcnn_fast", "l2"),
        ("fcnn_fast", "joint_signed"),
    ]
    assert all(-1 <= r["final_train_pcc"] <= 1 for r in rows)
    assert all(r["nonfinite_loss"] is False and r["nonfinite_params"] is False for r in rows)
    table = list(csv.DictReader((tmp_path / "stability.csv").open()))
    assert len(table) == 4 and all(float(r["final_train_loss"]) >= 0 for r in table)
    assert "nonfinite_loss" in (tmp_path / "stability.md").read_text()
    assert not list(tmp_path.rglob("*.ckpt"))


def test_image_level_scores(synthetic_dataset):
    dm = NRIQADataModule(synthetic_dataset, val_scene="beta", patch_size=32, target="patch_mae", val_patches=4)
    dm.setup()
    pair = dm.val_pairs[0]
    assert true_image_score(pair, "patch_mae") == pytest.approx(float((pair.noisy - pair.ref).abs().mean()))
    assert true_image_score(pair, "ssim_map") == pytest.approx(float(ssim_map(pair.noisy[None], pair.ref[None]).mean()))
    for net, target in ((create_model("patch_cnn"), "patch_mae"), (create_model("fcnn_fast", width=8), "ssim_map")):
        rows, stats = image_level(net.eval(), dm.val_pairs[:3], target, 32)
        assert [r["id"] for r in rows] == [p.record.id for p in dm.val_pairs[:3]]
        assert all(math.isfinite(r["predicted"]) for r in rows) and stats["n"] == 3


def test_image_level_gives_a_two_buffer_model_its_twin(synthetic_dataset):
    dm = NRIQADataModule(
        synthetic_dataset, val_scene="beta", patch_size=32, target="ssim_map", val_patches=4, twins=True
    )
    dm.setup()
    pairs = dm.val_pairs[:3]
    rows, stats = image_level(create_model("dual_fast").eval(), pairs, "ssim_map", 32)
    # untrained, dual_fast is the corrected dual buffer of the image and its twin
    expected = [float((2 * s / (1 + s)).mean()) for s in (ssim_map(p.noisy[None], p.twin[None]) for p in pairs)]
    assert [r["predicted"] for r in rows] == pytest.approx(expected, abs=1e-5) and stats["n"] == 3
