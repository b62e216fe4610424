"""The LightningModule of both experiments: one network, one loss, per-epoch correlations.

``net`` is given as a spec ``{"name": ..., **kwargs}`` for :func:`nriqa.models.create_model`, so
the checkpoint's hyper-parameters alone rebuild the network
(:func:`nriqa.training.checkpoint.load_net_from_checkpoint`).
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable, Mapping

import lightning as L
import torch
from omegaconf import DictConfig, OmegaConf
from torch import Tensor, nn
from torchmetrics import CatMetric, MeanMetric

from nriqa.core.sampling import evenly_spaced, metric_samples
from nriqa.losses.ladder import check_ladder_weight, ladder_term
from nriqa.models import create_model
from nriqa.training.batchnorm import freeze_batchnorm
from nriqa.training.metrics import correlations

STAGES = ("train", "val")


def _spec(obj) -> dict:
    return OmegaConf.to_container(obj, resolve=True) if isinstance(obj, DictConfig) else dict(obj)


def _describe(factory) -> dict | str | None:
    """A plain-data record of an optimizer/scheduler factory for the hyper-parameters."""
    if factory is None:
        return None
    if isinstance(factory, functools.partial):
        return {"name": f"{factory.func.__module__}.{factory.func.__qualname__}", **factory.keywords}
    return repr(factory)


class NRIQAModule(L.LightningModule):
    """Train a patch CNN or an FCNN on (noisy patch, full-reference target) pairs (thesis ch. 5).

    Logs per epoch for ``train`` and ``val``: ``loss``, ``pcc``, ``srocc``, ``tau`` (predictions
    and targets are gathered over the epoch with torchmetrics, maps subsampled with
    :func:`nriqa.core.sampling.metric_samples`, capped at ``max_metric_samples`` evenly spaced samples).

    Anchoring (:meth:`set_teacher`): training items ``(input, target, anchored)`` learn the teacher's map
    where ``anchored`` is true (``data.anchor_scenes``, ``data.anchor_data``) and their target elsewhere, so a
    fine-tune keeps
    the starting network's reading of families it learnt from many more scenes than the fine-tune holds.
    The teacher is frozen, runs in eval mode, and is neither trained nor saved in checkpoints.

    Ladder pairs (``ladder_weight`` > 0): training batches hold pairs ``(2i, 2i + 1)`` of one view at two sample
    counts (:mod:`nriqa.data.ladders`), and the training loss adds ``ladder_weight * Charbonnier(dp - dt)``
    over the pairs (:func:`nriqa.losses.ladder.ladder_term`), ``dp`` the difference of the two predicted means
    and ``dt`` of the two targets' (after anchoring), so the score rises and falls along a ladder as the
    quality does; logged as ``train/ladder``.

    A non-finite training loss is counted (``nonfinite_steps``, ``first_nonfinite_step``), the
    optimizer step is skipped, and, with ``stop_on_nonfinite``, training stops after that batch.
    ``history`` holds one row of plain floats per epoch; ``last_val`` the last validation samples.

    Args:
        net: ``{"name": str, **kwargs}`` for :func:`nriqa.models.create_model`, or a built module
            (then a checkpoint cannot rebuild it).
        loss: ``loss(pred, target) -> scalar`` module (:func:`nriqa.losses.create_loss`).
        optimizer: factory ``optimizer(params=...)`` (Hydra ``_partial_: true``).
        scheduler: optional factory ``scheduler(optimizer=...)``, stepped per epoch.
        scheduler_monitor: metric a plateau scheduler watches.
        metric_pixels_per_map: pixels per predicted map fed to the correlations.
        max_metric_samples: cap on correlation samples per stage and epoch.
        stop_on_nonfinite: stop training at the first NaN/Inf loss.
        freeze_bn: keep every batch-norm layer in eval mode while training (running statistics fixed,
            :func:`nriqa.training.batchnorm.freeze_batchnorm`): the network trained is the one run.
        ladder_weight: weight of the ladder-pair term, >= 0; 0 (the default): the loss alone.
    """

    def __init__(
        self,
        net: Mapping | nn.Module,
        loss: nn.Module,
        optimizer: Callable,
        scheduler: Callable | None = None,
        scheduler_monitor: str = "val/loss",
        metric_pixels_per_map: int = 16,
        max_metric_samples: int = 2048,
        stop_on_nonfinite: bool = True,
        freeze_bn: bool = False,
        ladder_weight: float = 0.0,
    ) -> None:
        super().__init__()
        if isinstance(net, nn.Module):
            net_spec = None
        else:
            net_spec = _spec(net)
            net = create_model(**net_spec)
        self.net = net
        self.loss_fn = loss
        self.optimizer_factory = optimizer
        self.scheduler_factory = scheduler
        self.scheduler_monitor = scheduler_monitor
        self.metric_pixels_per_map = metric_pixels_per_map
        self.max_metric_samples = max_metric_samples
        self.stop_on_nonfinite = stop_on_nonfinite
        self.freeze_bn = bool(freeze_bn)
        self.ladder_weight = check_ladder_weight(ladder_weight)
        self.save_hyperparameters(
            {
                "net": net_spec,
                "loss": repr(loss),
                "optimizer": _describe(optimizer),
                "scheduler": _describe(scheduler),
                "metric_pixels_per_map": metric_pixels_per_map,
                "max_metric_samples": max_metric_samples,
                "freeze_bn": self.freeze_bn,
                "ladder_weight": self.ladder_weight,
            }
        )
        for stage in STAGES:
            setattr(self, f"{stage}_loss", MeanMetric())
            setattr(self, f"{stage}_pred", CatMetric())
            setattr(self, f"{stage}_target", CatMetric())
        self.nonfinite_steps = 0
        self.first_nonfinite_step: int | None = None
        self.history: list[dict[str, float]] = []
        self.last_val: tuple[Tensor, Tensor] | None = None
        self._val_row: dict[str, float] = {}
        self._teacher: tuple[nn.Module, ...] = ()  # a tuple: not a submodule, so not trained nor saved

    def forward(self, x: Tensor) -> Tensor:
        return self.net(x)

    def set_teacher(self, teacher: nn.Module) -> None:
        """Anchored training items learn ``teacher``'s map from now on (a frozen copy is kept)."""
        teacher = copy.deepcopy(teacher).eval()
        for p in teacher.parameters():
            p.requires_grad_(False)
        self._teacher = (teacher,)

    def anchored_target(self, x: Tensor, y: Tensor, anchored: Tensor) -> Tensor:
        """``y`` with the teacher's map of ``x`` where ``anchored`` (one flag per item)."""
        if not self._teacher:
            raise RuntimeError(
                "anchored training items need a teacher: set data.anchor_scenes or data.anchor_data with init_from"
            )
        if not bool(anchored.any()):
            return y
        teacher = self._teacher[0]
        first = next(teacher.parameters(), None)
        if first is not None and first.device != x.device:
            teacher.to(x.device)
        with torch.no_grad():
            t = teacher(x).to(y.dtype)
        return torch.where(anchored.to(y.device).view(-1, *([1] * (y.ndim - 1))), t, y)

    def on_train_batch_start(self, batch, batch_idx: int) -> None:
        # Lightning sets and restores modes itself (validation captures and restores each module's),
        # so the layers are put back in eval mode before every step, not once.
        if self.freeze_bn:
            freeze_batchnorm(self.net)

    def _step(self, batch, stage: str) -> Tensor:
        x, y, *anchored = batch
        if anchored:
            y = self.anchored_target(x, y, anchored[0])
        pred = self(x)
        loss = self.loss_fn(pred, y)
        if stage == "train" and self.ladder_weight > 0:
            term = ladder_term(pred, y)
            if torch.isfinite(term) and self._trainer is not None:
                self.log("train/ladder", term.detach(), on_step=False, on_epoch=True, batch_size=x.shape[0])
            loss = loss + self.ladder_weight * term
        if torch.isfinite(loss):
            getattr(self, f"{stage}_loss").update(loss.detach(), weight=x.shape[0])
            p, t = metric_samples(pred.detach(), y, self.metric_pixels_per_map)
            getattr(self, f"{stage}_pred").update(p)
            getattr(self, f"{stage}_target").update(t)
        return loss

    def training_step(self, batch, batch_idx: int) -> Tensor | None:
        loss = self._step(batch, "train")
        if torch.isfinite(loss):
            return loss
        self.nonfinite_steps += 1
        if self.first_nonfinite_step is None:
            self.first_nonfinite_step = int(self.global_step)
            self.print(f"non-finite training loss ({loss.item()}) at step {self.global_step}")
        if self.stop_on_nonfinite:
            self.trainer.should_stop = True
        # Returning None skips the optimizer step, so the weights stay as they were.
        return None

    def validation_step(self, batch, batch_idx: int) -> Tensor:
        return self._step(batch, "val")

    def _epoch_metrics(self, stage: str) -> dict[str, float]:
        """Compute, log and reset the epoch's ``{stage}/loss|pcc|srocc|tau``."""
        metrics = {}
        loss_m, pred_m, target_m = (getattr(self, f"{stage}_{k}") for k in ("loss", "pred", "target"))
        if loss_m.update_count:
            metrics["loss"] = float(loss_m.compute())
        if pred_m.update_count:
            pred, target = pred_m.compute().cpu(), target_m.compute().cpu()
            pred, target = evenly_spaced(pred, target, self.max_metric_samples)
            finite = torch.isfinite(pred) & torch.isfinite(target)
            metrics.update(correlations(pred[finite], target[finite]))
            if stage == "val":
                self.last_val = (pred, target)
        for m in (loss_m, pred_m, target_m):
            m.reset()
        metrics = {f"{stage}/{k}": v for k, v in metrics.items()}
        if metrics and not self.trainer.sanity_checking:
            self.log_dict(metrics, sync_dist=False)
        return metrics

    def on_validation_epoch_end(self) -> None:
        row = self._epoch_metrics("val")
        if not self.trainer.sanity_checking:
            self._val_row = row

    def on_train_epoch_end(self) -> None:
        row = {"epoch": float(self.current_epoch), **self._epoch_metrics("train"), **self._val_row}
        row["train/nonfinite_steps"] = float(self.nonfinite_steps)
        row["nonfinite_params"] = float(not all(torch.isfinite(p).all() for p in self.net.parameters()))
        self.log_dict({k: row[k] for k in ("train/nonfinite_steps", "nonfinite_params")})
        self.history.append(row)
        self._val_row = {}

    def configure_optimizers(self):
        opt = self.optimizer_factory(params=self.parameters())
        if self.scheduler_factory is None:
            return opt
        sched = self.scheduler_factory(optimizer=opt)
        scheduler = {"scheduler": sched, "monitor": self.scheduler_monitor, "interval": "epoch"}
        return {"optimizer": opt, "lr_scheduler": scheduler}
