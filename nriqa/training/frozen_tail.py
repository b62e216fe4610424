"""The frozen batch-norm tail: the last epochs of a run trained with the statistics the Scorer runs with.

A network trained with batch norm in train mode normalises each batch of patches by that batch's own
statistics; the Scorer runs it on running averages. Trained from scratch, that mismatch left the
composed-map recipe reading its own training images +0.014 too good (mean SSIM); the same run
polished for 15 epochs with the statistics fixed read them +0.005 (docs/results/evaluation.md, stop 86).

``nriqa-train ... freeze_bn_from=E [freeze_bn_batches=N]``: at the start of epoch ``E`` (0-based) the
running statistics become their average over ``N`` training batches
(:func:`~nriqa.training.batchnorm.estimate_batchnorm`), then every batch-norm layer stays in eval mode to
the end of the run (the module's ``freeze_bn``), so the weights of the last epochs fit those statistics.
A run resumed past ``E`` keeps the statistics its checkpoint holds and stays frozen.
"""

from __future__ import annotations

import lightning as L

from nriqa.training.batchnorm import estimate_batchnorm, freeze_batchnorm, repeated

__all__ = ["FrozenBatchNormTail", "check_tail"]


def check_tail(from_epoch, batches, max_epochs: int, freeze_bn: bool, bn_refresh) -> tuple[int, int] | None:
    """``(from_epoch, batches)`` checked against the run, or ``None`` without a tail.

    Raises:
        ValueError: a start outside ``[0, max_epochs)``, fewer than one batch, or a tail beside ``freeze_bn``
            (frozen from the start already) or ``bn_refresh`` (which would re-estimate what the tail trained under).
    """
    if from_epoch is None:
        return None
    if isinstance(from_epoch, bool) or not isinstance(from_epoch, int) or not 0 <= from_epoch < max_epochs:
        raise ValueError(
            f"freeze_bn_from={from_epoch}: give the epoch the frozen tail starts at, 0 <= E < {max_epochs} "
            "(the run's epochs), or null for none"
        )
    if isinstance(batches, bool) or not isinstance(batches, int) or batches < 1:
        raise ValueError(f"freeze_bn_batches={batches}: the statistics need at least 1 training batch")
    if freeze_bn:
        raise ValueError("freeze_bn=true freezes batch norm from the start: drop it or freeze_bn_from")
    if bn_refresh:
        raise ValueError(
            "bn_refresh re-estimates the statistics after training, which the frozen tail trained under: "
            "drop bn_refresh or freeze_bn_from"
        )
    return from_epoch, batches


class FrozenBatchNormTail(L.Callback):
    """At the start of epoch ``from_epoch``: estimate the statistics over ``batches`` training batches, then freeze.

    The estimate's batch count is recorded in the module's hyper-parameters (``freeze_bn_tail``), so every
    checkpoint written after it says so.
    """

    def __init__(self, from_epoch: int, batches: int) -> None:
        self.from_epoch = int(from_epoch)
        self.batches = int(batches)

    def on_train_epoch_start(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        epoch = trainer.current_epoch
        if epoch < self.from_epoch or pl_module.freeze_bn:
            return
        if epoch == self.from_epoch:
            used = estimate_batchnorm(pl_module.net, repeated(trainer.datamodule.train_dataloader()), self.batches)
            pl_module.hparams["freeze_bn_tail"] = {"from_epoch": self.from_epoch, "batches": used}
        # past the start (a resumed run) the checkpoint holds the statistics estimated then
        pl_module.freeze_bn = True
        freeze_batchnorm(pl_module.net)
