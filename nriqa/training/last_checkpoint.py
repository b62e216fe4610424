"""``last.ckpt``: the state at the end of the latest training epoch, whatever the monitored metric did.

Lightning 2.6 changed ``ModelCheckpoint(save_last=True)``: it writes ``last.ckpt`` only when a top-k
checkpoint is written at the same step, so with ``monitor="val/loss", save_top_k=1`` the "last"
checkpoint is a copy of the *best* one. Two things here rest on ``last.ckpt`` being the end of
training: ``nriqa-evaluate --crossval`` scores each held-out scene with it (so that no checkpoint is
chosen by the held-out scene's loss), and a killed run resumes from it (resuming from the best would
replay epochs). :class:`LastCheckpoint` writes it at the end of every training epoch, atomically;
the configs turn ``save_last`` off.
"""

from __future__ import annotations

import os
from pathlib import Path

import lightning as L

from nriqa.io.atomic import PARTIAL_MARK

LAST_NAME = "last.ckpt"


class LastCheckpoint(L.Callback):
    """Write ``dirpath/last.ckpt`` after every training epoch (after its validation), atomically.

    Also under ``fast_dev_run`` (where ModelCheckpoint writes nothing): a debug run still leaves a
    checkpoint that rebuilds its network.

    Every rank calls :meth:`lightning.Trainer.save_checkpoint` (it is collective; rank 0 writes);
    rank 0 then renames the finished file onto ``last.ckpt``, so a run killed mid-write keeps the
    previous epoch's file.
    """

    def __init__(self, dirpath: str | os.PathLike) -> None:
        self.dirpath = Path(dirpath)

    @property
    def path(self) -> Path:
        return self.dirpath / LAST_NAME

    def on_train_epoch_end(self, trainer: L.Trainer, pl_module: L.LightningModule) -> None:
        if trainer.sanity_checking:
            return
        self.write(trainer)

    def write(self, trainer: L.Trainer) -> None:
        """Write the trainer's state to ``last.ckpt`` now, atomically (also after training: ``bn_refresh``)."""
        # one name for every rank (save_checkpoint is collective); the partial mark lets a resume sweep it
        tmp = self.dirpath / f".last{PARTIAL_MARK}.ckpt"
        trainer.save_checkpoint(tmp, weights_only=False)  # whole (a resume needs the optimiser); said, not logged
        if trainer.is_global_zero:
            os.replace(tmp, self.path)
