"""Fit one model as a composed Hydra config describes (the body of ``nriqa-train`` / ``python train.py``).

Kept in the package so that cross validation (:mod:`nriqa.training.crossval`) and the stability study
(:mod:`nriqa.training.stability`) run exactly the same training as ``nriqa-train``.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import hydra
import lightning as L
from lightning.pytorch.utilities.exceptions import SIGTERMException
from omegaconf import DictConfig, OmegaConf, open_dict

from nriqa.data.options import check_whole
from nriqa.losses.ladder import check_ladder_weight
from nriqa.training.batchnorm import estimate_batchnorm, repeated
from nriqa.training.frozen_tail import FrozenBatchNormTail, check_tail
from nriqa.training.hard_sampling import check_mix, check_power, draw_weights
from nriqa.training.last_checkpoint import LastCheckpoint
from nriqa.training.module import NRIQAModule
from nriqa.training.warm_start import warm_start


def source_checkout() -> Path | None:
    """The repository root when nriqa runs from a source checkout (editable installs too), else None."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() and (root / "nriqa" / "configs").is_dir() else None


def set_project_root() -> None:
    """Point ``${paths.root_dir}`` (env ``PROJECT_ROOT``) at the repository of a source checkout, else at
    the current working directory (an installed package: ``data/``, ``logs/`` are where the user runs).

    A ``PROJECT_ROOT`` the user set wins.
    """
    os.environ.setdefault("PROJECT_ROOT", str(source_checkout() or Path.cwd()))


def user_error(exc: BaseException) -> str | None:
    """The one-line message of an error a user can cause and fix (bad path, scene, option), else None.

    Hydra wraps errors raised while instantiating in ``InstantiationException``; the cause chain
    is searched for a ``ValueError`` (``ManifestError``, ``FoldError``, ``ImageReadError``,
    ``CheckpointError`` and bad option values all are) or a missing file.
    """
    seen = exc
    while seen is not None:
        if isinstance(seen, (ValueError, FileNotFoundError)) and not isinstance(
            seen, hydra.errors.InstantiationException
        ):
            return str(seen)
        seen = seen.__cause__ or seen.__context__
    return None


SIGTERM_EXIT = 128 + signal.SIGTERM  # the status a shell gives a process that SIGTERM ended
STOPPED_BY_SIGTERM = (
    "error: stopped by SIGTERM before training finished (the run in progress is not marked done); its "
    "checkpoints/last.ckpt holds the last whole epoch: rerun the same command to resume "
    "(nriqa-train: add ckpt_path=<run dir>/checkpoints/last.ckpt)"
)


class StoppedBySigterm(SIGTERMException):
    """A fit that SIGTERM stopped, as :func:`train` raises it: Lightning's ``SIGTERMException`` with status 143.

    Lightning's own exception is a ``SystemExit`` of no status, so a script that calls :func:`train` (or
    :func:`nriqa.training.crossval.crossval`) and lets it through would end with status 0, as if finished.
    """

    def __init__(self) -> None:
        super().__init__(SIGTERM_EXIT)


def exit_on_user_error(fn, *args):
    """Return ``fn(*args)``; an error :func:`user_error` recognises exits with its one line instead.

    A SIGTERM during training (a scheduler's time limit, ``kill``) exits with status 143 and one line
    (:class:`StoppedBySigterm`).
    """
    try:
        return fn(*args)
    except SIGTERMException:
        print(STOPPED_BY_SIGTERM, file=sys.stderr)
        raise SystemExit(SIGTERM_EXIT) from None
    except Exception as exc:
        message = user_error(exc)
        if message is None:
            raise
        sys.exit(f"error: {message}")


def check_count(cfg: DictConfig, key: str, low: int, note: str = "") -> int:
    """The value at the dotted ``key`` of ``cfg`` as an int if it is a whole number >= ``low``; else the one-line
    ``ValueError`` of :func:`nriqa.data.options.check_whole` naming the key and ``note``."""
    return check_whole(OmegaConf.select(cfg, key), key, low, note=note)


def max_epochs(cfg: DictConfig) -> int:
    """``trainer.max_epochs``, checked as a whole number >= 1 (the schedule sets it)."""
    return check_count(cfg, "trainer.max_epochs", 1, " (schedule.<model>.epochs sets it)")


def seed_run(cfg: DictConfig) -> None:
    """Seed torch, numpy, Python and the loader workers from ``seed`` (a whole number >= 0) where it is set."""
    if cfg.get("seed") is not None:
        L.seed_everything(check_count(cfg, "seed", 0), workers=True)


def _instantiate_group(cfg: DictConfig | None) -> list:
    """Instantiate every ``_target_`` entry of a callbacks/logger group (null or empty -> [])."""
    return [hydra.utils.instantiate(c) for c in (cfg or {}).values() if c is not None and "_target_" in c]


def _fit_without_val(cfg: DictConfig) -> None:
    # With no held-out scene there is no val/loss: keep the latest checkpoint, watch train/loss.
    with open_dict(cfg):
        if cfg.get("callbacks") and cfg.callbacks.get("model_checkpoint"):
            cfg.callbacks.model_checkpoint.monitor = None
        if cfg.model.get("scheduler") is not None:
            cfg.model.scheduler_monitor = "train/loss"
        if str(cfg.get("optimized_metric") or "").startswith("val/"):
            cfg.optimized_metric = "train/loss"


def _estimate_batchnorm(model: NRIQAModule, datamodule, n: int, key: str) -> None:
    # the running statistics averaged over n training batches, the count recorded under key
    # (bn_estimate before training, bn_refresh after it)
    used = estimate_batchnorm(model.net, repeated(datamodule.train_dataloader()), n)
    model.hparams.update({key: used})


def _refresh_batchnorm(trainer: L.Trainer, model: NRIQAModule, datamodule, n: int) -> None:
    # bn_refresh: the trained weights' statistics estimated, then last.ckpt written again so
    # nriqa-evaluate --crossval and the Scorer read them
    _estimate_batchnorm(model, datamodule, n, "bn_refresh")
    for cb in trainer.callbacks:
        if isinstance(cb, LastCheckpoint):
            cb.write(trainer)


def train(cfg: DictConfig) -> tuple[dict[str, float], dict]:
    """Seed, build datamodule / model / callbacks / loggers / trainer from ``cfg``, and fit.

    Returns:
        ``(metrics, objects)``: the last epoch's logged metrics as floats, and
        ``{"cfg", "datamodule", "model", "trainer", "best_ckpt", "seconds"}``.

    Raises:
        StoppedBySigterm: SIGTERM arrived during the fit (status 143 if not caught); ``last.ckpt`` holds the
            last whole epoch, and calling again with the same ``cfg`` (``ckpt_path`` set to it) resumes.
    """
    seed_run(cfg)
    epochs = max_epochs(cfg)
    if cfg.data.get("val_scene") is None:
        _fit_without_val(cfg)

    ladder_weight = check_ladder_weight(cfg.get("ladder_weight") or 0.0)  # checked before any work
    tail = check_tail(
        cfg.get("freeze_bn_from"),
        cfg.get("freeze_bn_batches", 500),
        epochs,
        bool(cfg.get("freeze_bn")),
        cfg.get("bn_refresh"),
    )
    body_only = bool(cfg.get("init_body_only"))
    if body_only and not cfg.get("init_from"):
        raise ValueError("init_body_only=true loads the body of init_from's network: set init_from")
    # ladder pairs are drawn exactly when the loss uses them (nriqa.data.ladders)
    datamodule = hydra.utils.instantiate(cfg.data, ladder_pairs=ladder_weight > 0)
    # Load (and tone-map) the data first: a wrong path or scene fails before anything is built.
    datamodule.setup("fit")
    if datamodule.anchors and not cfg.get("init_from"):
        raise ValueError(
            "data.anchor_scenes / data.anchor_data learn the starting network's map there: the run needs init_from"
        )
    if datamodule.anchors and body_only:
        raise ValueError(
            "data.anchor_scenes / data.anchor_data learn the starting network's map, but init_body_only=true starts "
            "with an untrained head: drop the anchors or init_body_only"
        )
    hard = cfg.get("hard_sampling") or {}
    # both checked before any work; a power of 0 is refused, not read as the default
    mix, power = check_mix(hard.get("mix") or 0.0), check_power(hard.get("power", 1.0))
    model: NRIQAModule = hydra.utils.instantiate(
        cfg.model, freeze_bn=bool(cfg.get("freeze_bn")), ladder_weight=ladder_weight
    )
    if cfg.get("init_from"):
        warm_start(model.net, str(cfg.init_from), cfg.get("init_member"), body_only=body_only)
        model.hparams.update(
            {"init_from": str(cfg.init_from), "init_member": cfg.get("init_member"), "init_body_only": body_only}
        )
    if cfg.get("bn_estimate"):
        _estimate_batchnorm(model, datamodule, int(cfg.bn_estimate), "bn_estimate")
    if datamodule.anchors:
        model.set_teacher(model.net)  # the start, after init_from and bn_estimate
        model.hparams.update(datamodule.anchors.describe())
    if mix:
        weights, summary = draw_weights(model.net, datamodule.train_pairs, mix, power, datamodule.anchors)
        datamodule.train_set.set_weights(weights)
        model.hparams.update({"hard_sampling": {"mix": mix, "power": power, **summary}})
        print(
            f"hard sampling: {int(summary['images'])} images, mean error {summary['mean_error']:.4f}; the 1 % read "
            f"worst (error {summary['worst_1pct_error']:.3f}) get {summary['worst_1pct_share']:.1%} of the draws"
        )
    callbacks = _instantiate_group(cfg.get("callbacks"))
    if tail:
        callbacks.append(FrozenBatchNormTail(*tail))
    loggers = _instantiate_group(cfg.get("logger"))
    trainer: L.Trainer = hydra.utils.instantiate(cfg.trainer, callbacks=callbacks, logger=loggers or False)
    for lg in loggers:
        lg.log_hyperparams(OmegaConf.to_container(cfg, resolve=True))

    start = time.perf_counter()
    try:
        trainer.fit(model=model, datamodule=datamodule, ckpt_path=cfg.get("ckpt_path"))
    except SIGTERMException:
        raise StoppedBySigterm() from None
    seconds = time.perf_counter() - start

    metrics = {k: float(v) for k, v in trainer.callback_metrics.items()}
    ckpt_cb = trainer.checkpoint_callback
    if cfg.get("bn_refresh"):
        _refresh_batchnorm(trainer, model, datamodule, int(cfg.bn_refresh))
    last = next((c.path for c in trainer.callbacks if isinstance(c, LastCheckpoint) and c.path.is_file()), "")
    best = (ckpt_cb.best_model_path if ckpt_cb is not None else "") or str(last)
    if (cfg.get("bn_refresh") or tail) and last:
        # only last.ckpt holds the refreshed statistics (or the end of the frozen tail): an epoch checkpoint (the
        # latest, or a held-out scene's lowest val/loss) may come from before, so the run reports, and
        # nriqa-crossval's tables score, last.ckpt
        best = str(last)
    objects = {
        "cfg": cfg,
        "datamodule": datamodule,
        "model": model,
        "trainer": trainer,
        "best_ckpt": best,
        "seconds": seconds,
    }
    return metrics, objects
