"""last.ckpt is the end of training even when the monitored loss got worse (Lightning >= 2.6 copies the best)."""

from __future__ import annotations

import lightning as L
import torch
from lightning.pytorch.callbacks import ModelCheckpoint
from test_train import compose_cfg
from torch.utils.data import DataLoader, TensorDataset

from nriqa.training.fit import train
from nriqa.training.last_checkpoint import LastCheckpoint


class _WorseEveryEpoch(L.LightningModule):
    """A linear fit whose logged val/loss rises every epoch, so the best checkpoint is epoch 0."""

    def __init__(self) -> None:
        super().__init__()
        self.lin = torch.nn.Linear(2, 1)

    def training_step(self, batch, _):
        x, y = batch
        return torch.nn.functional.mse_loss(self.lin(x), y)

    def validation_step(self, batch, _):
        self.log("val/loss", float(self.current_epoch))

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.1)


def _loader() -> DataLoader:
    g = torch.Generator().manual_seed(0)
    x = torch.rand(8, 2, generator=g)
    return DataLoader(TensorDataset(x, x.sum(1, keepdim=True)), batch_size=4)


def _fit(tmp_path, *callbacks) -> L.Trainer:
    trainer = L.Trainer(
        max_epochs=3,
        callbacks=list(callbacks),
        logger=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        num_sanity_val_steps=0,
        default_root_dir=tmp_path,
    )
    trainer.fit(_WorseEveryEpoch(), _loader(), _loader())
    return trainer


def test_last_checkpoint_is_the_final_epoch_not_the_best(tmp_path):
    best = ModelCheckpoint(dirpath=tmp_path, filename="best", monitor="val/loss", save_top_k=1, save_last=False)
    last = LastCheckpoint(tmp_path)
    trainer = _fit(tmp_path, best, last)
    ckpt = torch.load(tmp_path / "last.ckpt", weights_only=True)
    assert trainer.global_step == 6
    assert ckpt["global_step"] == 6 and ckpt["epoch"] == 2
    assert torch.load(best.best_model_path, weights_only=True)["global_step"] == 2  # the best stayed epoch 0
    assert not list(tmp_path.glob("*partial*"))  # the temp file was renamed, nothing left half-written
    # its weights are the trained module's final ones
    final = trainer.lightning_module.lin.weight.detach()
    assert torch.equal(ckpt["state_dict"]["lin.weight"], final)


def test_the_train_config_writes_last_at_the_end_of_training(synthetic_dataset, tmp_path):
    overrides = ("experiment=fcnn_fast", "data.val_scene=beta", "trainer.max_epochs=3", "+model.net.width=8")
    cfg = compose_cfg(tmp_path, synthetic_dataset, *overrides)
    assert cfg.callbacks.model_checkpoint.save_last is False
    _, objects = train(cfg)
    ckpt = torch.load(tmp_path / "checkpoints" / "last.ckpt", weights_only=True)
    assert ckpt["global_step"] == objects["trainer"].global_step and ckpt["epoch"] == 2
