"""Leave-one-scene-out folds trained side by side in one process (``nriqa-crossval crossval.stacked=true``).

Every fold of :mod:`nriqa.training.crossval` trains the same network from the same initial weights, each on
its own patches. Run as one process per fold on a shared GPU, the processes take turns on it: stop 45 measured
68 ms a step with 17 folds on one H100 (165 ms with patches made there) where the network's own step takes
10 ms alone. Here the folds' networks are one: their parameters and batch-norm buffers are stacked
(``torch.func.stack_module_state``) and run with ``torch.func.vmap``, so one forward and backward per step
serves every fold, each on its own batch. The folds' losses are summed, which gives each fold's parameters
exactly its own gradient, and Adam's update is per element, so each fold follows the path it would alone
(tested against the per-fold training of ``nriqa-crossval``: the same patches, initial weights and updates).

What it does not do, and refuses with one line: hard-example sampling, ``bn_estimate``, ``bn_refresh``, ``freeze_bn``,
``freeze_bn_from``,
``data.anchor_scenes`` or ``data.anchor_data``, several devices, gradient clipping or accumulation, another
precision, a scheduler that watches a metric.
It validates nothing while training (the fold tables use each fold's end of training, ``last.ckpt``, the
checkpoint ``nriqa-evaluate --crossval`` scores with anyway), and keeps ``trainer.max_epochs`` and
``trainer.max_time`` as Lightning does. A fold whose loss turns non-finite stops there (its weights as they
were before that step), the others go on.

Resumable: after every epoch the whole state (weights, optimiser, sampler epoch, elapsed time) is written
atomically to ``<out_dir>/stacked_state.pt``; a rerun over the same folds picks it up. At the end each fold
gets ``folds/<scene>/checkpoints/last.ckpt`` (the network's spec and weights, as
:func:`nriqa.training.checkpoint.load_net_from_checkpoint` reads them) and its ``result.json``.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

import hydra
import torch
from omegaconf import DictConfig, OmegaConf
from torch import Tensor, nn
from torch.func import functional_call, stack_module_state, vmap
from torch.utils.data import DataLoader, Dataset

from nriqa.data.folds import FoldError
from nriqa.data.images import PairCache
from nriqa.data.patches import EpochSampler, TrainPatches
from nriqa.io.atomic import atomic_path
from nriqa.models import create_model
from nriqa.training.fit import max_epochs, seed_run
from nriqa.training.last_checkpoint import LAST_NAME

STATE_NAME = "stacked_state.pt"


class BatchNormByOps(nn.BatchNorm2d):
    """``nn.BatchNorm2d`` in training mode written as plain tensor operations, which ``vmap`` runs on any device.

    ``torch.batch_norm`` chooses its CUDA kernel by asking the input for its memory layout, a question a batched
    tensor cannot answer inside ``vmap`` ("NYI: querying is_contiguous inside of vmap for memory_format other
    than torch.contiguous_format", seen on an H100 in stop 48; on the CPU it never asks). The same arithmetic:
    normalised with the batch's biased variance, running statistics updated with the unbiased one.
    """

    def forward(self, x: Tensor) -> Tensor:
        if not self.training:
            return super().forward(x)
        n = x.numel() // x.shape[1]
        if n < 2:
            raise ValueError(f"Expected more than 1 value per channel when training, got input size {tuple(x.shape)}")
        mean = x.mean((0, 2, 3))
        var = x.var((0, 2, 3), correction=0)
        if self.track_running_stats:
            with torch.no_grad():
                self.num_batches_tracked.add_(1)
                m = self.momentum if self.momentum is not None else 1.0 / self.num_batches_tracked
                self.running_mean.mul_(1 - m).add_(m * mean)
                self.running_var.mul_(1 - m).add_(m * var * (n / (n - 1)))
        y = (x - mean[:, None, None]) * torch.rsqrt(var + self.eps)[:, None, None]
        if self.affine:
            y = y * self.weight[:, None, None] + self.bias[:, None, None]
        return y


class StackedNets:
    """``folds`` copies of ``net`` (its weights and buffers at the time of the call) trained as one.

    ``params`` and ``buffers`` hold each tensor of ``net`` stacked on a new first dimension, one row per
    fold; :meth:`losses` runs every fold's network on its own batch in one call.
    """

    def __init__(self, net: nn.Module, folds: int) -> None:
        if folds < 1:
            raise ValueError(f"StackedNets needs at least one fold, got {folds}")
        self.folds = folds
        params, buffers = stack_module_state([net] * folds)
        self.params = {k: v.detach().clone().requires_grad_(True) for k, v in params.items()}
        self.buffers = {k: v.detach().clone() for k, v in buffers.items()}
        self.skeleton = copy.deepcopy(net).to("meta").train()
        for m in self.skeleton.modules():
            if hasattr(m, "memory_format"):
                m.memory_format = torch.contiguous_format  # vmap cannot lay a batched tensor out otherwise
            if type(m) is nn.BatchNorm2d:
                m.__class__ = BatchNormByOps  # torch.batch_norm cannot pick its CUDA kernel inside vmap

    def to(self, device: torch.device) -> StackedNets:
        with torch.no_grad():
            self.params = {k: v.detach().to(device).requires_grad_(True) for k, v in self.params.items()}
            self.buffers = {k: v.to(device) for k, v in self.buffers.items()}
        return self

    def losses(self, x: Tensor, y: Tensor, loss_fn: nn.Module) -> Tensor:
        """``(folds,)`` training losses: fold ``f``'s network (in training mode) on ``x[f]`` against ``y[f]``.

        Batch-norm running statistics are updated in place, each fold's from its own batch.
        """

        def one(params, buffers, xf, yf):
            return loss_fn(functional_call(self.skeleton, (params, buffers), (xf,)), yf)

        return vmap(one, randomness="error")(self.params, self.buffers, x, y)

    def fold_state(self, fold: int) -> dict[str, Tensor]:
        """Fold ``fold``'s network as a ``state_dict`` of the original module (on the CPU)."""
        return {k: v[fold].detach().cpu().clone() for k, v in {**self.params, **self.buffers}.items()}

    def state_dict(self) -> dict:
        return {"params": {k: v.detach() for k, v in self.params.items()}, "buffers": dict(self.buffers)}

    def load_state_dict(self, state: dict) -> None:
        with torch.no_grad():
            for k, v in state["params"].items():
                self.params[k].copy_(v)
            for k, v in state["buffers"].items():
                self.buffers[k].copy_(v)


class StackedPatches(Dataset):
    """Item ``k`` of every fold's training set: ``(inputs (folds, C, P, P), targets (folds, 1, P, P))``.

    A batch of indices is made fold by fold with :meth:`TrainPatches.__getitems__`, as each fold's own
    loader would make it.
    """

    def __init__(self, sets: list[TrainPatches]) -> None:
        if len({len(s) for s in sets}) != 1:
            raise ValueError("StackedPatches needs training sets of one length (patches per epoch)")
        self.sets = sets

    def __len__(self) -> int:
        return len(self.sets[0])

    def __getitem__(self, index: int) -> tuple[Tensor, Tensor]:
        return self.__getitems__([index])[0]

    def __getitems__(self, indices: list[int]) -> list[tuple[Tensor, Tensor]]:
        per_fold = [s.__getitems__(indices) for s in self.sets]
        return [
            (torch.stack([fold[i][0] for fold in per_fold]), torch.stack([fold[i][1] for fold in per_fold]))
            for i in range(len(indices))
        ]


def parse_max_time(value) -> float | None:
    """Lightning's ``max_time`` (``"DD:HH:MM:SS"`` or a dict of ``timedelta`` fields) in seconds; ``None``: none."""
    if value is None:
        return None
    if isinstance(value, str):
        parts = value.split(":")
        if len(parts) != 4 or not all(p.strip().isdigit() for p in parts):
            raise ValueError(f"trainer.max_time={value!r}: give DD:HH:MM:SS, e.g. 00:00:07:00")
        days, hours, minutes, seconds = (int(p) for p in parts)
        return float(((days * 24 + hours) * 60 + minutes) * 60 + seconds)
    import datetime

    return datetime.timedelta(**dict(value)).total_seconds()


def check_supported(cfg: DictConfig) -> None:
    """Raise a one-line :class:`FoldError` for what stacked training does not do (see the module docstring)."""
    why = []
    if (cfg.get("hard_sampling") or {}).get("mix"):
        why.append("hard_sampling.mix")
    if cfg.get("ladder_weight"):
        why.append("ladder_weight")
    if cfg.get("bn_estimate"):
        why.append("bn_estimate")
    if cfg.get("bn_refresh"):
        why.append("bn_refresh")
    if cfg.get("freeze_bn"):
        why.append("freeze_bn")
    if cfg.get("freeze_bn_from") is not None:
        why.append("freeze_bn_from")
    if (cfg.get("data") or {}).get("anchor_scenes"):
        why.append("data.anchor_scenes")
    if (cfg.get("data") or {}).get("anchor_data"):
        why.append("data.anchor_data")
    trainer = cfg.trainer
    if str(trainer.get("devices", 1)) not in ("1", "auto") or trainer.get("strategy") not in (None, "auto"):
        why.append("several devices")
    if trainer.get("gradient_clip_val"):
        why.append("trainer.gradient_clip_val")
    if (trainer.get("accumulate_grad_batches") or 1) != 1:
        why.append("trainer.accumulate_grad_batches")
    if str(trainer.get("precision") or 32) not in ("32", "32-true"):
        why.append(f"trainer.precision={trainer.precision}")
    scheduler = cfg.model.get("scheduler")
    if scheduler is not None and "ReduceLROnPlateau" in str(scheduler.get("_target_")):
        why.append("a scheduler that watches a metric")
    if why:
        raise FoldError(f"crossval.stacked does not do {', '.join(why)}; drop it, or train the folds one by one")


def _device(cfg: DictConfig) -> torch.device:
    accelerator = str(cfg.trainer.get("accelerator") or "cpu")
    if accelerator in ("gpu", "cuda"):
        if not torch.cuda.is_available():
            raise FoldError(f"trainer.accelerator={accelerator}, but torch sees no CUDA device; use trainer=cpu")
        return torch.device("cuda")
    if accelerator in ("cpu", "auto"):
        return torch.device("cuda" if accelerator == "auto" and torch.cuda.is_available() else "cpu")
    raise FoldError(f"crossval.stacked runs on cpu or gpu, not trainer.accelerator={accelerator}")


def _fold_datamodules(cfg: DictConfig, scenes: list[str]) -> list:
    """Each fold's datamodule, set up with the images read once for all of them."""
    cache = PairCache()
    modules = []
    for scene in scenes:
        dm = hydra.utils.instantiate(cfg.data, val_scene=scene)
        dm.pair_source = cache
        dm.setup("fit")
        modules.append(dm)
    return modules


def _save_atomic(obj, path: Path) -> None:
    # Through a file object, as nriqa.inference.pretrained does: torch.save names its records after the path.
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        torch.save(obj, fh)


def train_stacked(cfg: DictConfig, scenes: list[str], out_dir: str | Path) -> dict[str, dict]:
    """Train the folds ``scenes`` of ``cfg`` side by side; write each fold's checkpoint and result.

    Returns ``{scene: result}`` as :func:`nriqa.training.crossval.fold_result` writes them.
    """
    from nriqa.training.crossval import fold_result  # crossval calls this module: import at call time

    check_supported(cfg)
    out_dir = Path(out_dir)
    device = _device(cfg)
    epochs = max_epochs(cfg)
    max_seconds = parse_max_time(cfg.trainer.get("max_time"))
    seed_run(cfg)
    # As nriqa.training.fit.train: the data first (a bad path fails before anything is built), then the network,
    # so each fold starts from the weights its own run would draw.
    modules = _fold_datamodules(cfg, scenes)
    spec = OmegaConf.to_container(cfg.model.net, resolve=True)
    stack = StackedNets(create_model(**spec), len(scenes)).to(device)
    loss_fn = hydra.utils.instantiate(cfg.model.loss).to(device)
    optimizer = hydra.utils.instantiate(cfg.model.optimizer)(params=list(stack.params.values()))
    scheduler = cfg.model.get("scheduler")
    scheduler = hydra.utils.instantiate(scheduler)(optimizer=optimizer) if scheduler is not None else None
    stop_on_nonfinite = bool(cfg.model.get("stop_on_nonfinite", True))

    state_path = out_dir / STATE_NAME
    epoch, step, seconds, stopped, history = 0, 0, 0.0, {}, []
    nonfinite: dict[int, list[int]] = {}  # fold -> [first step with a non-finite loss, how many such steps]
    if state_path.is_file():
        state = torch.load(state_path, map_location=device, weights_only=True)
        if state["scenes"] != scenes:
            raise FoldError(
                f"{state_path} trains folds {state['scenes']}, not {scenes}; delete it to start these afresh"
            )
        stack.load_state_dict(state["stack"])
        optimizer.load_state_dict(state["optimizer"])
        if scheduler is not None:
            scheduler.load_state_dict(state["scheduler"])
        epoch, step, seconds, history = state["epoch"], state["step"], state["seconds"], state["history"]
        stopped = {int(k): v for k, v in state["stopped"].items()}
        nonfinite = {int(k): v for k, v in state.get("nonfinite", {}).items()}
        print(f"stacked: resumed at epoch {epoch} (step {step}, {seconds:.0f} s) from {state_path}")

    data = cfg.data
    sampler = EpochSampler(len(modules[0].train_set))
    loader = DataLoader(
        StackedPatches([dm.train_set for dm in modules]),
        batch_size=int(data.batch_size),
        sampler=sampler,
        num_workers=int(data.get("num_workers") or 0),
        pin_memory=bool(data.get("pin_memory")),
        persistent_workers=bool(data.get("num_workers")),
    )
    out_of_time = max_seconds is not None and seconds >= max_seconds
    while epoch < epochs and not out_of_time and len(stopped) < len(scenes):
        sampler.set_epoch(epoch)
        started = time.perf_counter()
        sums, counts = torch.zeros(len(scenes), dtype=torch.float64), torch.zeros(len(scenes))
        for x, y in loader:
            x = x.to(device, non_blocking=True).transpose(0, 1)
            y = y.to(device, non_blocking=True).transpose(0, 1)
            losses = stack.losses(x, y, loss_fn)
            finite = torch.isfinite(losses.detach()).cpu()
            for f in (~finite).nonzero().flatten().tolist():
                if f not in stopped:
                    nonfinite.setdefault(f, [step, 0])[1] += 1
                    print(f"fold {scenes[f]}: non-finite training loss at step {step}; its weights stay as they were")
                    stopped[f] = {"state": stack.fold_state(f)}  # its first bad step: nonfinite[f]
            active = torch.tensor([f not in stopped for f in range(len(scenes))]) & finite
            optimizer.zero_grad(set_to_none=True)
            if bool(active.any()):
                losses[active.to(losses.device)].sum().backward()
                optimizer.step()
            _restore(stack, stopped)
            if not stop_on_nonfinite:  # a skipped step only: the fold goes on from the next batch
                stopped.clear()
            sums += torch.where(active, losses.detach().cpu().double(), 0.0)
            counts += active
            step += 1
            if max_seconds is not None and seconds + time.perf_counter() - started >= max_seconds:
                out_of_time = True
                break
        seconds += time.perf_counter() - started
        epoch += 1
        if scheduler is not None:
            scheduler.step()
        means = (sums / counts.clamp(min=1)).tolist()
        history.append({"epoch": epoch - 1, "step": step, "seconds": seconds, "loss": means})
        print(f"stacked: epoch {epoch - 1} done, step {step}, {seconds:.0f} s, mean loss {sum(means) / len(means):.4f}")
        _save_atomic(
            {
                "scenes": scenes,
                "stack": stack.state_dict(),
                "optimizer": optimizer.state_dict(),
                "scheduler": scheduler.state_dict() if scheduler is not None else None,
                "epoch": epoch,
                "step": step,
                "seconds": seconds,
                "history": history,
                "stopped": {str(k): v for k, v in stopped.items()},
                "nonfinite": {str(k): v for k, v in nonfinite.items()},
            },
            state_path,
        )

    results = {}
    for f, (scene, dm) in enumerate(zip(scenes, modules)):
        fold_dir = out_dir / "folds" / scene
        ckpt = fold_dir / "checkpoints" / LAST_NAME
        _save_atomic(
            {
                "hyper_parameters": {"net": spec, "loss": repr(loss_fn), "stacked": {"folds": scenes}},
                "state_dict": {f"net.{k}": v for k, v in stack.fold_state(f).items()},
                "epoch": epoch - 1,
                "global_step": step,
            },
            ckpt,
        )
        run = {"epochs": epoch, "steps": step, "seconds": seconds, "stacked_folds": len(scenes)}
        if f in nonfinite:  # as the one-by-one module counts them, whether the fold stopped or skipped the steps
            run["first_nonfinite_step"], run["nonfinite_steps"] = nonfinite[f]
        last = {"train/loss": history[-1]["loss"][f]} if history else {}
        results[scene] = fold_result(cfg, scene, fold_dir, dm, str(ckpt), run, last)
    return results


def _restore(stack: StackedNets, stopped: dict[int, dict]) -> None:
    """Put the folds that stopped back as they were (Adam's momentum and the batch-norm statistics move them)."""
    with torch.no_grad():
        tensors = {**stack.params, **stack.buffers}
        for f, info in stopped.items():
            for k, v in info["state"].items():
                tensors[k][f] = v
