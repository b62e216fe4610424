"""The LightningDataModule of both experiments: manifest -> fold -> tone-mapped pairs -> patches."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence

import lightning as L
from torch.utils.data import DataLoader, TensorDataset

from nriqa.core.display import DisplayMix
from nriqa.data.albedo import LINE_PERIOD, check_albedo_lines, check_albedo_p, check_line_period, check_min_spp
from nriqa.data.coarse import check_coarse_p
from nriqa.data.converged import check_converged_p
from nriqa.data.cutmix import check_cutmix_p
from nriqa.data.anchors import Anchors
from nriqa.data.ladders import check_span
from nriqa.data.options import check_names, check_whole
from nriqa.data.pixel_filter import SIGMA_RANGE, check_pixel_filter
from nriqa.data.folds import only_scenes, split_by_scene
from nriqa.data.images import ImagePair, load_pairs, pairs_to
from nriqa.data.jitter import check_value_mode
from nriqa.data.patches import EpochSampler, TrainPatches, fixed_patches
from nriqa.data.targets import check_target
from nriqa.io.manifest import read_datasets

# Offsets that give training and the two fixed evaluation sets independent random streams.
_VAL_STREAM = 1_000_003
_TRAIN_EVAL_STREAM = 2_000_003


def display_mix(options: Mapping[str, float]) -> DisplayMix:
    """A :class:`DisplayMix` from config options; an unknown option is a one-line ``ValueError``."""
    known = {f.name for f in dataclasses.fields(DisplayMix)}
    for key in options:
        if key not in known:
            raise ValueError(f"unknown display mix option {key!r}; use {', '.join(sorted(known))}")
    return DisplayMix(**options)


class NRIQADataModule(L.LightningDataModule):
    """Patches for NR-IQA training from a rendered dataset (thesis ch. 5).

    Noisy images are the manifest's ``test`` and ``twin`` records, each paired with its reference;
    every image is tone-mapped once (:func:`nriqa.core.tonemap.tonemap`) and kept in memory.

    Training: ``batches_per_epoch * batch_size`` random patches per epoch from every scene but
    ``val_scene``, jittered (flip/rot90 and HSV, eq. 5.1, each switchable) before the target is
    computed. Validation: ``val_patches`` fixed seeded patches of ``val_scene``, never jittered.

    Args:
        data_dir: dataset root holding ``manifest.json``, or a list of roots trained on together
            (e.g. the default dataset and one rendered with a longer spp ladder).
        val_scene: scene family held out for validation; ``None`` trains on all, no validation.
        scenes: use only these scene families (training and validation); ``None``: every family of
            ``data_dir``. For holding families back from a run, to measure on them afterwards.
        patch_size: 32 for the patch CNN, 64 for the FCNNs.
        target: ``"ssim_map"`` (experiment II) or ``"patch_mae"`` (experiment I).
        batch_size: patches per batch (training and validation).
        batches_per_epoch: training batches per epoch.
        val_patches: size of the fixed validation set.
        jitter: ``{"hsv": bool, "geometric": bool, "value": "add" | "scale" | "off"}``; ``value`` ``"add"`` (or
            true) is the thesis's additive value shift, ``"off"`` (or false) keeps the hue and saturation shifts and
            drops it, ``"scale"`` multiplies value instead (:func:`nriqa.data.jitter.sample_jitter`).
        display: ``None`` (every image through the package tone map), or the fields of a
            :class:`nriqa.core.display.DisplayMix`: training then draws a display transform per patch
            (tone map, exposure + sRGB / gamma 2.2 with clipping, 8-bit quantisation), applied to
            the noisy image and its reference alike before the target. Validation keeps the tone map.
        twins: feed the model the noisy image and its independent twin (6 channels), for the
            two-buffer scorer; the target stays the noisy image's quality.
        albedo_p: the share of training patches multiplied by a random albedo texture, noisy image,
            twin and reference alike, before the display and the target (:mod:`nriqa.data.albedo`);
            0 (the default) draws none and leaves every other draw as it was.
        albedo_lines: the share of those albedo textures that are grilles of thin lines, as fine
            geometry and its shadows draw (:func:`nriqa.data.albedo.grille`); 0 (the default): none.
        albedo_line_period: ``[low, high]``, the spacing of a grille's lines uniform in it, in pixels; ``[3, 12]``
            (the default) as before; down to 1-2 pixels a crossed grille shows as a moire, as a shadow lattice finer
            than the pixel grid does.
        albedo_min_spp: only images of at least this many samples per pixel get albedo textures (the draw is
            made all the same, so the other images' draws stay as they were); 0 (the default): every image. A
            texture on an image noisier than its contrast teaches that noise may be texture.
        albedo_pass: also feed the model each scene variant's albedo pass (``albedo.exr`` beside the
            reference, ``python -m data_gen.albedo_pass DATA``), stacked after the image (and twin):
            cut, textured and jittered with the image, never displayed.
        pixel_filter_p: the share of training patches through a renderer's pixel filter, a Gaussian of
            Mitsuba's form with a standard deviation uniform in ``pixel_filter_sigma`` pixels, noisy image,
            twin and reference alike, before the display and the target (:mod:`nriqa.data.pixel_filter`);
            0 (the default) draws none and leaves every other draw as it was. Images the manifest says were
            rendered through a filter (data_gen's ``pixel_filter``) are never filtered again, so such
            renders and box-filtered ones can be learnt together.
        converged_p: the share of training patches whose input is the reference itself, learnt at its target (1
            everywhere), anchored sets included (:mod:`nriqa.data.converged`); 0 (the default) draws none and
            leaves every other draw as it was. Single-image models only.
        cutmix_p: the share of training patches that carry a rectangle of another training patch (its own image,
            display and jitter), noisy image, reference, twin and albedo pass alike, before the target
            (:mod:`nriqa.data.cutmix`); 0 (the default) draws none and leaves every other draw as it was. Not with
            ``ladder_pairs``.
        coarse_p: the share of training patches that carry, in a random half-size square, a copy of their whole cut
            at half the resolution (each pixel a 2 x 2 block's mean: four times the samples a pixel), noisy image,
            reference, twin and albedo pass alike, right after the cut (:mod:`nriqa.data.coarse`); 0 (the default)
            draws none and leaves every other draw as it was. Needs an even ``patch_size``.
        anchor_scenes: scene families whose training patches learn the starting network's map instead of
            their SSIM target (with ``init_from``: :class:`nriqa.training.module.NRIQAModule`'s teacher),
            so a fine-tune on a few scenes of them keeps what the start learnt from many while the other
            families teach it something new; empty (the default): every patch learns its target.
        anchor_data: dataset roots (some of ``data_dir``) whose every training patch learns the starting
            network's map, whatever its family: keep the start's reading of one set while another set of the
            same families (e.g. data_gen's ``zoom`` crops) teaches it (:mod:`nriqa.data.anchors`).
        ladder_pairs: draw training items in pairs, item ``2i + 1`` the same cut of another rung of item
            ``2i``'s ladder within ``ladder_span`` doublings of its sample count (:mod:`nriqa.data.ladders`), for
            the training module's ``ladder_weight`` (``nriqa-train ladder_weight=W`` sets both); needs an even
            ``batch_size``. False (the default): every item drawn alone, as before.
        seed: seeds patch positions, jitter and the validation set.
        num_workers, pin_memory: passed to the DataLoaders.
        device: where training patches are made. ``None``: on the CPU, in the loader (and its
            workers). ``"cuda"`` (any torch device): the training images are moved there once and
            each batch is cut, displayed, jittered and scored there, so an accelerator is not left
            waiting on CPU patch preparation; needs ``num_workers=0`` and ``pin_memory=False``.
            The patches are the same draws as on the CPU (the random choices stay on the CPU).
            For one run on a GPU (measured on an H100: 1.8x faster batches); not for many runs
            sharing one GPU, where the CPU makes them faster (docs/training.md).
    """

    def __init__(
        self,
        data_dir: str | os.PathLike | Sequence[str | os.PathLike],
        val_scene: str | None = None,
        scenes: Sequence[str] | None = None,
        patch_size: int = 64,
        target: str = "ssim_map",
        batch_size: int = 16,
        batches_per_epoch: int = 256,
        val_patches: int = 256,
        jitter: Mapping[str, bool] | None = None,
        display: Mapping[str, float] | None = None,
        twins: bool = False,
        albedo_p: float = 0.0,
        albedo_pass: bool = False,
        albedo_lines: float = 0.0,
        albedo_line_period: Sequence[float] = LINE_PERIOD,
        albedo_min_spp: int = 0,
        pixel_filter_p: float = 0.0,
        pixel_filter_sigma: Sequence[float] = SIGMA_RANGE,
        converged_p: float = 0.0,
        cutmix_p: float = 0.0,
        coarse_p: float = 0.0,
        anchor_scenes: Sequence[str] = (),
        anchor_data: Sequence[str | os.PathLike] = (),
        ladder_pairs: bool = False,
        ladder_span: int = 2,
        seed: int = 12345,
        num_workers: int = 0,
        pin_memory: bool = False,
        device: str | None = None,
    ) -> None:
        super().__init__()
        check_target(target)
        # whole numbers before anything uses them (and as ints in the checkpoint's hyperparameters)
        patch_size = check_whole(patch_size, "data.patch_size", 1, "pixels")
        batch_size = check_whole(batch_size, "data.batch_size", 1, "patches")
        batches_per_epoch = check_whole(batches_per_epoch, "data.batches_per_epoch", 1, "batches")
        val_patches = check_whole(val_patches, "data.val_patches", 1, "patches")
        num_workers = check_whole(num_workers, "data.num_workers", 0, "worker processes")
        if device is not None and (num_workers or pin_memory):
            raise ValueError(
                f"data.device={device} makes patches in the training process; set num_workers=0 and pin_memory=false"
            )
        jitter = dict(jitter or {})
        unknown = set(jitter) - {"hsv", "geometric", "value"}
        if unknown:
            raise ValueError(f"unknown jitter switches {sorted(unknown)}; use hsv, value and geometric")
        # plain str / list before saving: a checkpoint must load with weights_only=True (no ListConfig)
        data_dir = str(data_dir) if isinstance(data_dir, (str, os.PathLike)) else [str(d) for d in data_dir]
        display = None if display is None else {k: float(v) for k, v in dict(display).items()}
        scenes = check_names(scenes, "data.scenes")
        anchor_scenes = check_names(anchor_scenes, "data.anchor_scenes") or []
        anchor_data = [str(d) for d in anchor_data or ()]
        self.display = None if display is None else display_mix(display)
        self.twins = bool(twins)
        self.albedo_p = check_albedo_p(albedo_p)
        self.albedo_pass = bool(albedo_pass)
        self.albedo_lines = check_albedo_lines(albedo_lines)
        self.albedo_line_period = check_line_period(albedo_line_period)
        albedo_line_period = list(self.albedo_line_period)  # a plain list in the checkpoint
        self.albedo_min_spp = check_min_spp(albedo_min_spp)
        self.pixel_filter_p, self.pixel_filter_sigma = check_pixel_filter(pixel_filter_p, pixel_filter_sigma)
        pixel_filter_sigma = list(self.pixel_filter_sigma)  # a plain list in the checkpoint
        self.converged_p = check_converged_p(converged_p, self.twins)
        self.cutmix_p = check_cutmix_p(cutmix_p, ladder_pairs)
        self.coarse_p = check_coarse_p(coarse_p, patch_size)
        self.save_hyperparameters(logger=False)
        self.data_dir = data_dir
        self.val_scene = val_scene
        self.scenes = scenes
        self.anchors = Anchors(frozenset(anchor_scenes), tuple(anchor_data))
        self.ladder_pairs = bool(ladder_pairs)
        self.ladder_span = check_span(ladder_span)
        if self.ladder_pairs and batch_size % 2:
            raise ValueError(f"data.ladder_pairs draws pairs of items: data.batch_size must be even, got {batch_size}")
        self.patch_size = patch_size
        self.target = target
        self.batch_size = batch_size
        self.batches_per_epoch = batches_per_epoch
        self.val_patches = val_patches
        self.hsv = bool(jitter.get("hsv", True))
        self.geometric = bool(jitter.get("geometric", True))
        self.value = check_value_mode(jitter.get("value", "add"))
        self.seed = seed
        self.num_workers = num_workers
        self.pin_memory = pin_memory
        self.device = None if device is None else str(device)
        self.train_pairs: list[ImagePair] = []
        self.val_pairs: list[ImagePair] = []
        self.train_set: TrainPatches | None = None
        self.val_set: TensorDataset | None = None
        # Where the image pairs come from: load_pairs, or a PairCache shared by several folds (not a setting).
        self.pair_source = load_pairs

    def setup(self, stage: str | None = None) -> None:
        """Read the manifest, split the fold, tone-map the images (once) and build the patch sets.

        Raises ``ManifestError`` / ``FoldError`` / ``ValueError`` with one-line messages.
        """
        if self.train_set is not None:
            return
        train, val = split_by_scene(only_scenes(read_datasets(self.data_dir), self.scenes), self.val_scene)
        self.train_pairs = self.pair_source(
            train, linear=self.display is not None, twins=self.twins, albedo=self.albedo_pass
        )
        self.val_pairs = self.pair_source(val, twins=self.twins, albedo=self.albedo_pass)
        self.train_set = TrainPatches(
            self.train_pairs if self.device is None else pairs_to(self.train_pairs, self.device),
            self.patch_size,
            self.target,
            self.batches_per_epoch * self.batch_size,
            self.seed,
            hsv=self.hsv,
            geometric=self.geometric,
            value=self.value,
            display=self.display,
            twins=self.twins,
            albedo_p=self.albedo_p,
            albedo_pass=self.albedo_pass,
            albedo_lines=self.albedo_lines,
            albedo_line_period=self.albedo_line_period,
            albedo_min_spp=self.albedo_min_spp,
            pixel_filter_p=self.pixel_filter_p,
            pixel_filter_sigma=self.pixel_filter_sigma,
            anchors=self.anchors,
            ladder_pairs=self.ladder_pairs,
            ladder_span=self.ladder_span,
            converged_p=self.converged_p,
            cutmix_p=self.cutmix_p,
            coarse_p=self.coarse_p,
        )
        if self.val_pairs:
            self.val_set = fixed_patches(
                self.val_pairs,
                self.val_patches,
                self.patch_size,
                self.target,
                self.seed + _VAL_STREAM,
                self.twins,
                self.albedo_pass,
            )

    def train_eval_set(self, n: int | None = None) -> TensorDataset:
        """A fixed seeded set of ``n`` (default ``val_patches``) unjittered training patches, for reports."""
        self.setup()
        n = self.val_patches if n is None else n
        seed = self.seed + _TRAIN_EVAL_STREAM
        return fixed_patches(self.train_pairs, n, self.patch_size, self.target, seed, self.twins, self.albedo_pass)

    def train_dataloader(self) -> DataLoader:
        return DataLoader(
            self.train_set,
            batch_size=self.batch_size,
            sampler=EpochSampler(len(self.train_set)),
            num_workers=self.num_workers,
            pin_memory=self.pin_memory,
            persistent_workers=self.num_workers > 0,
        )

    def val_dataloader(self) -> DataLoader | list:
        # An empty list tells Lightning there is no validation (val_scene=None).
        if self.val_set is None:
            return []
        return self.eval_dataloader(self.val_set)

    def eval_dataloader(self, dataset: TensorDataset) -> DataLoader:
        """A sequential loader over a fixed patch set."""
        return DataLoader(dataset, batch_size=self.batch_size, shuffle=False, num_workers=0, pin_memory=self.pin_memory)
