"""Random training patches and fixed validation patches cut from tone-mapped image pairs.

Training patch ``k`` is a pure function of ``(seed, k)``: its own generator picks the image, the
position and the jitter. An :class:`EpochSampler` hands out indices ``k`` that are fresh every
epoch (and distinct per DDP rank), so runs are reproducible whatever the number of workers.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.distributed as dist
from torch import Tensor
from torch.utils.data import Dataset, Sampler, TensorDataset

from nriqa.data.images import ImagePair
from nriqa.data.jitter import jitter_pair
from nriqa.data.targets import check_target, compute_target


def item_generator(seed: int, index: int) -> torch.Generator:
    """A generator for item ``index`` of stream ``seed``; well mixed, so nearby indices are unrelated."""
    state = np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint64)[0]
    return torch.Generator().manual_seed(int(state))


def check_patch_size(pairs: list[ImagePair], patch_size: int) -> None:
    """Raise a one-line ``ValueError`` if any image is smaller than a patch."""
    for p in pairs:
        h, w = p.noisy.shape[-2:]
        if h < patch_size or w < patch_size:
            raise ValueError(f"{p.record.path} is {h}x{w}, smaller than patch_size={patch_size}; lower data.patch_size")


def cut(pair: ImagePair, generator: torch.Generator, size: int) -> tuple[Tensor, Tensor]:
    """Cut one ``size`` x ``size`` patch at a uniformly random position, the same from noisy and ref."""
    h, w = pair.noisy.shape[-2:]
    y = int(torch.randint(0, h - size + 1, (1,), generator=generator))
    x = int(torch.randint(0, w - size + 1, (1,), generator=generator))
    return pair.noisy[:, y : y + size, x : x + size], pair.ref[:, y : y + size, x : x + size]


class TrainPatches(Dataset):
    """Random jittered training patches; item ``k`` is ``(noisy (3,P,P), target)`` drawn from ``(seed, k)``.

    The image is picked uniformly, then the position, then the jitter (applied to noisy and
    reference alike), and the target is computed from the jittered pair. Any ``k >= 0`` is valid;
    ``len`` is the number of items per epoch.
    """

    def __init__(
        self,
        pairs: list[ImagePair],
        patch_size: int,
        target: str,
        length: int,
        seed: int,
        hsv: bool = True,
        geometric: bool = True,
    ) -> None:
        if not pairs:
            raise ValueError("TrainPatches needs at least one image pair")
        check_patch_size(pairs, patch_size)
        self.pairs = pairs
        self.patch_size = patch_size
        self.target = check_target(target)
        self.length = length
        self.seed = seed
        self.hsv = hsv
        self.geometric = geometric

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, index: int) -> tuple[Tensor, Tensor]:
        g = item_generator(self.seed, index)
        pair = self.pairs[int(torch.randint(0, len(self.pairs), (1,), generator=g))]
        noisy, ref = cut(pair, g, self.patch_size)
        if self.hsv or self.geometric:
            noisy, ref = jitter_pair(noisy, ref, g, hsv=self.hsv, geometric=self.geometric)
        target = compute_target(self.target, noisy[None], ref[None])[0]
        return noisy.contiguous(), target


class EpochSampler(Sampler[int]):
    """Indices ``[(epoch * world + rank) * n, ... + n)``: new patches each epoch and on each rank.

    Lightning calls :meth:`set_epoch` before every training epoch.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return self.n

    def __iter__(self):
        rank, world = (dist.get_rank(), dist.get_world_size()) if dist.is_available() and dist.is_initialized() else (0, 1)
        start = (self.epoch * world + rank) * self.n
        return iter(range(start, start + self.n))


def fixed_patches(pairs: list[ImagePair], n: int, patch_size: int, target: str, seed: int) -> TensorDataset:
    """``n`` patches at seeded random positions, no jitter: a fixed evaluation set ``(noisy, target)``.

    Images are visited round-robin (so each held-out image contributes alike), positions drawn
    from one generator seeded with ``seed``.
    """
    if not pairs:
        raise ValueError("fixed_patches needs at least one image pair")
    check_patch_size(pairs, patch_size)
    g = torch.Generator().manual_seed(int(seed))
    cuts = [cut(pairs[i % len(pairs)], g, patch_size) for i in range(n)]
    noisy = torch.stack([c[0] for c in cuts])
    ref = torch.stack([c[1] for c in cuts])
    return TensorDataset(noisy, compute_target(target, noisy, ref))
