"""(Noisy, reference[, twin][, albedo pass]) image pairs held in memory, loaded once per dataset: tone-mapped or linear."""

from __future__ import annotations

import dataclasses
import os

import torch
from torch import Tensor

from nriqa.core.display import key_exposure
from nriqa.io.imread import load_ldr_many, read_image
from nriqa.io.manifest import Record, albedo_path


@dataclasses.dataclass(frozen=True)
class ImagePair:
    """One noisy render, its converged reference and optionally its independent twin, ``(3, H, W)`` each.

    Tone-mapped LDR in [0, 1], or with ``linear`` the linear HDR renders (display transforms are then
    applied per patch) and ``key`` the reference's key exposure (:func:`nriqa.core.display.key_exposure`).
    ``albedo``: the scene variant's albedo pass (:func:`nriqa.io.manifest.albedo_path`), reflectances
    in [0, 1] as rendered: neither tone-mapped nor displayed.
    """

    record: Record
    noisy: Tensor
    ref: Tensor
    twin: Tensor | None = None
    linear: bool = False
    key: float = 1.0
    albedo: Tensor | None = None


def load_linear_many(paths: list[str | os.PathLike]) -> list[Tensor]:
    """Read linear HDR images as ``(3, H, W)`` float32 tensors (no tone map); LDR files are refused."""
    out = []
    for path in paths:
        image, hdr = read_image(path)
        if not hdr:
            raise ValueError(f"{path} is display-referred LDR; display transforms need linear HDR (EXR) renders")
        out.append(torch.from_numpy(image).permute(2, 0, 1).contiguous())
    return out


def _twin_paths(records: list[Record]) -> dict[str, str]:
    """The path of each record's twin, looked up among ``records`` (its scene's noisy images)."""
    by_id = {r.id: r for r in records}
    out = {}
    for rec in records:
        twin = by_id.get(rec.twin) if rec.twin else None
        if twin is None:
            raise ValueError(f"{rec.path} has no twin among the images loaded; twin inputs need the twin renders")
        out[rec.path] = twin.path
    return out


def load_albedo_many(paths: list[str]) -> list[Tensor]:
    """Read albedo passes as ``(3, H, W)`` float32 in [0, 1]; a missing one is a one-line ``ValueError``."""
    out = []
    for path in paths:
        if not os.path.isfile(path):
            raise ValueError(
                f"{path} is missing: models with the albedo pass need it beside each reference; "
                "render it with python -m data_gen.albedo_pass DATA"
            )
        image, _ = read_image(path)
        out.append(torch.from_numpy(image).permute(2, 0, 1).clamp(0.0, 1.0).contiguous())
    return out


def load_pairs(
    records: list[Record], linear: bool = False, twins: bool = False, albedo: bool = False
) -> list[ImagePair]:
    """Load every record's image, its reference (with ``twins`` its twin, with ``albedo`` its albedo pass), each file once.

    LDR through :func:`nriqa.io.imread.load_ldr_many`, or with ``linear`` the linear HDR and each
    reference's key exposure. Paths are taken as the records give them:
    :func:`nriqa.io.manifest.read_datasets` puts each dataset's root in front. References are shared
    by many noisy images, so each is loaded once and the pairs point at the same tensor.

    Raises:
        ValueError: a noisy image and its reference differ in size, or a twin or albedo pass is missing
            (the message names the file).
    """
    twin_of = _twin_paths(records) if twins else {}
    albedo_files = list(dict.fromkeys(albedo_path(r) for r in records)) if albedo else []
    albedos = dict(zip(albedo_files, load_albedo_many(albedo_files)))
    files = list(dict.fromkeys([p for rec in records for p in (rec.reference, rec.path)]))
    images = dict(zip(files, (load_linear_many if linear else load_ldr_many)(files)))
    keys = {path: float(key_exposure(images[path]).item()) for path in {r.reference for r in records}} if linear else {}
    pairs = []
    for rec in records:
        noisy, ref = images[rec.path], images[rec.reference]
        if noisy.shape != ref.shape:
            raise ValueError(
                f"{rec.path} is {tuple(noisy.shape[1:])} but its reference {rec.reference} is "
                f"{tuple(ref.shape[1:])}; re-render one of them"
            )
        twin = images[twin_of[rec.path]] if twins else None
        alb = albedos[albedo_path(rec)] if albedo else None
        if alb is not None and alb.shape != ref.shape:
            raise ValueError(
                f"{albedo_path(rec)} is {tuple(alb.shape[1:])} but its reference is {tuple(ref.shape[1:])}; "
                "render it again with python -m data_gen.albedo_pass DATA"
            )
        pairs.append(ImagePair(rec, noisy, ref, twin, linear, keys.get(rec.reference, 1.0), alb))
    return pairs


class PairCache:
    """:func:`load_pairs` that keeps what it loaded: many folds of one dataset share each image in memory.

    Call it as :func:`load_pairs`; a record already loaded alike (same ``linear``, ``twins``, ``albedo``) is not read
    again, and the pairs returned are the same objects (:mod:`nriqa.training.stacked` builds every fold's
    training set from one cache).
    """

    def __init__(self) -> None:
        self.pairs: dict[tuple[str, bool, bool, bool], ImagePair] = {}

    def __call__(
        self, records: list[Record], linear: bool = False, twins: bool = False, albedo: bool = False
    ) -> list[ImagePair]:
        """The pairs of ``records`` as :func:`load_pairs` gives them; only the records not yet loaded are read."""
        key = (linear, twins, albedo)
        missing = [r for r in records if (r.path, *key) not in self.pairs]
        if missing:
            if twins:  # load_pairs looks a twin up among the records it is given
                wanted, have = {r.twin for r in missing}, {r.path for r in missing}
                missing += [r for r in records if r.id in wanted and r.path not in have]
            for pair in load_pairs(missing, linear, twins, albedo):
                self.pairs.setdefault((pair.record.path, *key), pair)
        return [self.pairs[(r.path, *key)] for r in records]


def pairs_to(pairs: list[ImagePair], device: str | torch.device) -> list[ImagePair]:
    """The same pairs with their images on ``device``; a reference shared by many pairs is moved once."""
    moved: dict[int, Tensor] = {}

    def to(t: Tensor | None) -> Tensor | None:
        if t is None:
            return None
        if id(t) not in moved:
            moved[id(t)] = t.to(device)
        return moved[id(t)]

    return [
        dataclasses.replace(p, noisy=to(p.noisy), ref=to(p.ref), twin=to(p.twin), albedo=to(p.albedo)) for p in pairs
    ]
