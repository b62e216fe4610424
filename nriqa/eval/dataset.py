"""The test images an evaluation scores, with their true scores and maps.

A dataset root with a manifest (:mod:`nriqa.io.manifest`) or an external folder of renders
(:mod:`nriqa.io.external`) gives records; :func:`load_dataset` loads their ``test`` images as
display-referred LDR (:func:`nriqa.io.imread.load_ldr`) and computes the truth: the SSIM map of
each image against its reference (:func:`nriqa.core.ssim.ssim_map`) and its mean.

With a ``display`` (:class:`nriqa.core.display.Display`) linear EXR renders are shown through it
instead of the tone map, the image, its twin and its reference alike with the reference's key
exposure, and the truth is measured after it -- the SSIM a user of that display pipeline would
measure, as training computes its targets (issue 15).
"""

from __future__ import annotations

import dataclasses
import fnmatch
from pathlib import Path

import torch

from nriqa.core.display import Display, apply_display, key_exposure
from nriqa.core.ssim import ssim_map
from nriqa.data.images import load_albedo_many, load_linear_many
from nriqa.errors import NriqaError
from nriqa.eval.baselines import Item
from nriqa.io.external import DEFAULT_PATTERN, DEFAULT_REFERENCE, scan_external
from nriqa.io.imread import HDR_SUFFIXES, load_ldr
from nriqa.io.manifest import MANIFEST_NAME, Record, albedo_path, read_manifest


class EvaluationError(NriqaError):
    """A dataset or option evaluation cannot work with; one line saying what to do."""


@dataclasses.dataclass
class Dataset:
    """Loaded test images: ``items`` (with true scores), ``refs`` reference LDR by path, ``true_maps`` by id."""

    items: list[Item]
    refs: dict[str, torch.Tensor]
    true_maps: dict[str, torch.Tensor]


def records_of(
    data: str | Path, pattern: str = DEFAULT_PATTERN, reference: str = DEFAULT_REFERENCE
) -> tuple[Path, list[Record]]:
    """The records of a dataset root (with a manifest) or of an external folder (without one)."""
    root = Path(data)
    if not root.exists():
        raise EvaluationError(f"{root}: no such dataset or folder")
    if (root / MANIFEST_NAME).is_file():
        return root, read_manifest(root)[0]
    return root, scan_external(root, pattern, reference)


class _Loader:
    """Loads an image as the evaluation sees it: :func:`load_ldr`, or linear EXR through a display."""

    def __init__(self, root: Path, display: Display | None) -> None:
        self.root, self.display = root, display
        self.keys: dict[str, torch.Tensor] = {}

    def __call__(self, path: str, reference: str) -> torch.Tensor:
        if self.display is None:
            return load_ldr(self.root / path)
        linear = self._linear(path)
        if reference not in self.keys:
            self.keys[reference] = key_exposure(linear if path == reference else self._linear(reference))
        return apply_display(linear, self.display, self.keys[reference])

    def _linear(self, path: str) -> torch.Tensor:
        if Path(path).suffix.lower() not in HDR_SUFFIXES:
            raise EvaluationError(
                f"{self.root / path}: --display needs linear EXR renders, this one is already displayed; "
                "leave --display out"
            )
        return load_linear_many([self.root / path])[0]


def load_dataset(
    root: Path, records: list[Record], algorithms: str = "*", twins: bool = True, display: Display | None = None
) -> Dataset:
    """Load the ``test`` images of the algorithms matching ``algorithms`` (comma-separated globs).

    Each image's reference is loaded once; with ``twins`` each image's twin too (the dual-buffer
    baselines need it); each scene variant's albedo pass where the dataset holds one (models with
    the albedo pass need it). Items keep the order of ``records``. ``display``: show linear renders
    through it (module docstring); ``None`` loads as :func:`load_ldr` does.

    Raises:
        EvaluationError: no test image left, an image and its reference differ in size, or a
            ``display`` meets an image that is not linear EXR.
    """
    patterns = [p.strip() for p in algorithms.split(",") if p.strip()]
    by_id = {r.id: r for r in records}
    tests = [r for r in records if r.role == "test" and any(fnmatch.fnmatchcase(r.algorithm, p) for p in patterns)]
    if not tests:
        raise EvaluationError(f"{root}: no test images (algorithms {algorithms!r}); check the dataset or --algorithms")
    load = _Loader(root, display)
    refs: dict[str, torch.Tensor] = {}
    albedos: dict[str, torch.Tensor | None] = {}
    items, true_maps = [], {}
    for rec in tests:
        if rec.reference not in refs:
            refs[rec.reference] = load(rec.reference, rec.reference)
        ldr, ref = load(rec.path, rec.reference), refs[rec.reference]
        if ldr.shape != ref.shape:
            raise EvaluationError(
                f"{root / rec.path} is {tuple(ldr.shape[1:])} but its reference is {tuple(ref.shape[1:])}"
            )
        has_twin = twins and rec.twin and rec.twin in by_id
        twin = load(by_id[rec.twin].path, rec.reference) if has_twin else None
        true_map = ssim_map(ldr[None], ref[None])[0, 0]
        true_maps[rec.id] = true_map
        albedo = albedo_path(rec)
        if albedo not in albedos:
            albedos[albedo] = load_albedo_many([root / albedo])[0] if (root / albedo).is_file() else None
        items.append(Item(rec, ldr, twin, float(true_map.mean()), albedos[albedo]))
    return Dataset(items, refs, true_maps)
