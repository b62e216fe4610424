"""Leave-one-scene-out cross validation (``nriqa-crossval experiment=fcnn_fast``, :mod:`nriqa.cli.crossval`).

Trains one model per scene family (that scene held out) with exactly ``train.py``'s training,
then writes into ``crossval.out_dir``:

* ``folds.csv`` / ``folds.md``  -- per fold: train and val PCC, SROCC, Kendall tau on fixed
  unjittered patch sets, and the image-level correlations; mean ± std (tables 5.3 / 5.7);
* ``images.csv`` / ``images.md`` -- every held-out noisy image: true full-image score vs the
  mean-pooled prediction, and the pooled correlations (tables 5.4 / 5.8);
* ``folds/<scene>/`` -- that fold's run: checkpoints, CSV/TensorBoard logs,
  ``training_curves.png``, and ``result.json`` (its presence marks the fold done: a rerun skips it;
  a fold killed mid-training resumes from its ``last.ckpt``).

With ``crossval.stacked=true`` the folds not yet done train side by side in this one process
(:mod:`nriqa.training.stacked`: the same training, for a GPU shared by every fold), then are evaluated
as here.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import torch
from omegaconf import DictConfig, open_dict

from nriqa.core.correlation import kendall_tau, pcc, srocc
from nriqa.data.folds import FoldError, noisy_records, only_scenes
from nriqa.data.options import check_names
from nriqa.eval.fold_eval import image_level, patch_correlations
from nriqa.io.atomic import write_text_atomic
from nriqa.io.manifest import read_datasets, scenes_of
from nriqa.io.tables import markdown_table, mean_std_row, write_csv
from nriqa.training.checkpoint import load_net_from_checkpoint
from nriqa.training.fit import check_count, train

RESULT_NAME = "result.json"
_STATS = ("pcc", "srocc", "tau")
FOLD_COLUMNS = [
    "scene",
    *(f"{s}_{m}" for s in ("train", "val", "image") for m in _STATS),
    "images",
    "epochs",
    "seconds",
]
IMAGE_COLUMNS = ["scene", "id", "role", "spp", "true", "predicted"]


def fold_scenes(cfg: DictConfig) -> list[str]:
    """The folds to run: ``crossval.scenes`` if given (checked), else every scene with noisy images.

    With ``data.scenes`` only those families exist for the folds (held-back families are neither
    trained on nor held out).
    """
    if cfg.get("init_from"):
        raise FoldError(
            f"init_from={cfg.init_from}: leave-one-scene-out must start every fold from random weights (trained "
            "weights may have learnt the held-out scene); drop init_from, or fine-tune with nriqa-train"
        )
    scenes = check_names(cfg.data.get("scenes"), "data.scenes")
    available = scenes_of(noisy_records(only_scenes(read_datasets(cfg.data.data_dir), scenes)))
    wanted = check_names(cfg.crossval.get("scenes"), "crossval.scenes") or available
    unknown = [s for s in wanted if s not in available]
    if unknown:
        raise FoldError(f"unknown scenes {unknown} in crossval.scenes; the dataset has: {', '.join(available)}")
    if len(available) < 2:
        raise FoldError(f"cross validation needs at least 2 scenes; the dataset has {available}")
    return wanted


def run_fold(cfg: DictConfig, scene: str, fold_dir: Path) -> dict:
    """Train with ``scene`` held out into ``fold_dir``, evaluate the best checkpoint, write its result."""
    cfg = copy.deepcopy(cfg)
    with open_dict(cfg):
        cfg.data.val_scene = scene
        cfg.paths.output_dir = str(fold_dir)
        last = fold_dir / "checkpoints" / "last.ckpt"
        if last.is_file():
            cfg.ckpt_path = str(last)
    metrics, objects = train(cfg)
    trainer = objects["trainer"]
    run = {"epochs": trainer.current_epoch, "steps": trainer.global_step, "seconds": objects["seconds"]}
    return fold_result(cfg, scene, fold_dir, objects["datamodule"], objects["best_ckpt"], run, metrics)


def fold_result(cfg: DictConfig, scene: str, fold_dir: Path, dm, ckpt: str, run: dict, metrics: dict) -> dict:
    """Evaluate fold ``scene``'s checkpoint ``ckpt`` on its datamodule ``dm``; write and return its result.

    ``run``: ``{"epochs", "steps", "seconds"}`` of its training (and anything else to record);
    ``metrics``: the last logged ones.
    """
    net = load_net_from_checkpoint(ckpt)
    n = dm.val_patches if cfg.crossval.get("eval_patches") is None else check_count(cfg, "crossval.eval_patches", 1)
    train_stats = patch_correlations(net, dm.eval_dataloader(dm.train_eval_set(n)))
    val_stats = patch_correlations(net, dm.eval_dataloader(dm.val_set))
    rows, image_stats = image_level(net, dm.val_pairs, dm.target, dm.patch_size)
    result = {
        "scene": scene,
        "train": train_stats,
        "val": val_stats,
        "image": image_stats,
        "images": rows,
        **run,
        "epochs": int(run["epochs"]),
        "steps": int(run["steps"]),
        "best_ckpt": str(ckpt),
        "last_logged": metrics,
    }
    write_text_atomic(fold_dir / RESULT_NAME, json.dumps(result, indent=1) + "\n")
    return result


def fold_row(result: dict) -> dict:
    row = {
        "scene": result["scene"],
        "images": result["image"]["n"],
        "epochs": result["epochs"],
        "seconds": round(result["seconds"], 1),
    }
    for s in ("train", "val", "image"):
        for m in _STATS:
            row[f"{s}_{m}"] = result[s][m]
    return row


def write_reports(out_dir: Path, results: list[dict], title: str) -> None:
    """Write folds.csv/.md and images.csv/.md from the fold results."""
    folds = [fold_row(r) for r in results]
    write_csv(out_dir / "folds.csv", folds, FOLD_COLUMNS)
    summary = mean_std_row(folds, FOLD_COLUMNS[1:-3], "scene")
    text = (
        f"# Cross validation: {title}\n\n"
        "Leave-one-scene-out. Patch level (thesis tables 5.3/5.7): correlations of predictions with "
        "targets on fixed unjittered patch sets of the training scenes (train) and of the held-out "
        "scene (val). Image level (tables 5.4/5.8): mean-pooled prediction vs the true full-image "
        "score of each held-out noisy image. Seconds: wall time of the fold's training.\n\n"
        + markdown_table([*folds, summary], FOLD_COLUMNS)
        + "\nPer-fold training curves: "
        + ", ".join(f"[{r['scene']}](folds/{r['scene']}/training_curves.png)" for r in results)
        + "\n"
    )
    write_text_atomic(out_dir / "folds.md", text)

    images = [row for r in results for row in r["images"]]
    write_csv(out_dir / "images.csv", images, IMAGE_COLUMNS)
    true = torch.tensor([r["true"] for r in images], dtype=torch.float64)
    pred = torch.tensor([r["predicted"] for r in images], dtype=torch.float64)
    pooled = (
        {"pcc": pcc(pred, true), "srocc": srocc(pred, true), "tau": kendall_tau(pred, true)} if len(images) > 1 else {}
    )
    per_fold = [{"scene": r["scene"], **{m: r["image"][m] for m in _STATS}, "images": r["image"]["n"]} for r in results]
    per_fold.append(mean_std_row(per_fold, list(_STATS), "scene"))
    per_fold.append({"scene": "all held-out images pooled", **pooled, "images": len(images)})
    text = (
        f"# Image-level correlations: {title}\n\n"
        "Each held-out noisy image: mean-pooled predicted map (patch model: mean over a grid of "
        "patches) vs its true full-image score (mean SSIM map, or image MAE).\n\n"
        + markdown_table(per_fold, ["scene", *_STATS, "images"])
        + "\n## Images\n\n"
        + markdown_table(images, IMAGE_COLUMNS, digits=4)
    )
    write_text_atomic(out_dir / "images.md", text)


def crossval(cfg: DictConfig) -> list[dict]:
    """Run (or resume) every fold of ``cfg`` and write the reports; returns the fold results."""
    out_dir = Path(cfg.crossval.out_dir)
    scenes = fold_scenes(cfg)
    fresh: dict[str, dict] = {}
    if cfg.crossval.get("stacked"):
        from nriqa.training.stacked import train_stacked  # torch.func; only this path needs it

        todo = [s for s in scenes if not (out_dir / "folds" / s / RESULT_NAME).is_file()]
        if todo:
            print(f"folds {', '.join(todo)}: training side by side (crossval.stacked)")
            fresh = train_stacked(cfg, todo, out_dir)
    results = []
    for scene in scenes:
        fold_dir = out_dir / "folds" / scene
        done = fold_dir / RESULT_NAME
        if scene in fresh:
            result = fresh[scene]
        elif done.is_file():
            print(f"fold {scene}: done, skipped ({done})")
            results.append(json.loads(done.read_text(encoding="utf-8")))
            continue
        else:
            print(f"fold {scene}: training")
            result = run_fold(cfg, scene, fold_dir)
        val, image, took = result["val"]["pcc"], result["image"]["pcc"], result["seconds"]
        print(f"fold {scene}: val PCC {val:.3f}, image PCC {image:.3f}, {took:.0f} s, {result['steps']} steps")
        results.append(result)
        # Reports after each fold, so a long run can be read while it goes on.
        write_reports(out_dir, results, f"{cfg.experiment_name}, schedule {cfg.schedule.name}")
    write_reports(out_dir, results, f"{cfg.experiment_name}, schedule {cfg.schedule.name}")
    print(f"wrote {out_dir / 'folds.md'} and {out_dir / 'images.md'}")
    return results
