"""The dataset manifest: one record per image (the contract between data_gen and everything else).

``<root>/manifest.json`` holds ``{"format": FORMAT, "meta": {...}, "records": [...]}``. Every
path is relative to ``<root>``. Loaders take everything from the records; nothing is parsed out of
file names.

Roles:
  * ``reference`` -- the converged image of a (scene, variant); its ``reference`` is itself.
  * ``test``      -- a noisy image on the spp ladder; ``twin`` names its independent twin.
  * ``twin``      -- the same algorithm and spp with another seed; ``twin`` names the test image.

Beside each variant's reference a dataset may hold its albedo pass, ``albedo.exr``
(:func:`albedo_path`; rendered by ``python -m data_gen.albedo_pass``): not a record, an input of
the models that take it.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path

from nriqa.errors import NriqaError
from nriqa.io.atomic import write_text_atomic

FORMAT = "nriqa-dataset/1"
MANIFEST_NAME = "manifest.json"
ROLES = ("reference", "test", "twin")
ALBEDO_FILE = "albedo.exr"


class ManifestError(NriqaError):
    """A missing or malformed manifest; the message says which file and what to do."""


@dataclasses.dataclass(frozen=True)
class Record:
    """One image of the dataset."""

    id: str
    scene: str
    variant: int
    algorithm: str
    role: str
    spp: int
    seed: int
    path: str
    reference: str
    width: int
    height: int
    render_seconds: float
    backend: str
    twin: str | None = None
    nonfinite: int = 0
    pixel_filter: str = "box"  # the film's reconstruction filter (data_gen's pixel_filter)
    zoom: int = 1  # > 1: the crop of a film zoom times as wide and high (data_gen's zoom)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


_FIELDS = {f.name for f in dataclasses.fields(Record)}
_REQUIRED = {f.name for f in dataclasses.fields(Record) if f.default is dataclasses.MISSING}


def write_manifest(root: str | os.PathLike, records: list[Record], meta: dict | None = None) -> Path:
    """Write ``<root>/manifest.json`` atomically; records sorted by id for stable diffs."""
    path = Path(root) / MANIFEST_NAME
    body = {"format": FORMAT, "meta": meta or {}, "records": [r.to_dict() for r in sorted(records, key=lambda r: r.id)]}
    write_text_atomic(path, json.dumps(body, indent=1) + "\n")
    return path


def read_manifest(root: str | os.PathLike) -> tuple[list[Record], dict]:
    """Read and validate ``<root>/manifest.json``; return ``(records, meta)``."""
    path = Path(root) / MANIFEST_NAME
    if not path.is_file():
        raise ManifestError(f"{path}: no manifest; render a dataset first (python -m data_gen out={root})")
    try:
        body = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ManifestError(
            f"{path}: unreadable manifest ({exc}); delete it and rerun data_gen to rebuild it"
        ) from None
    if not isinstance(body, dict) or body.get("format") != FORMAT:
        raise ManifestError(f"{path}: not an {FORMAT} manifest; rerun data_gen to rebuild it")
    records = []
    for i, raw in enumerate(body.get("records", [])):
        missing = _REQUIRED - set(raw)
        if missing:
            raise ManifestError(f"{path}: record {i} lacks {sorted(missing)}; rerun data_gen to rebuild it")
        rec = Record(**{k: v for k, v in raw.items() if k in _FIELDS})
        if rec.role not in ROLES:
            raise ManifestError(f"{path}: record {rec.id} has unknown role {rec.role!r}")
        records.append(rec)
    return records, body.get("meta", {})


def read_datasets(roots: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Record]:
    """The records of one dataset root or of several, each path prefixed with its root.

    Records of several roots can then be loaded together (their paths are relative to the working
    directory, not to a root). With more than one root, ids are prefixed with ``<root>:`` too, since
    two datasets rendered by the same presets share ids.

    Raises:
        ManifestError: a root has no readable manifest, or no root is given.
    """
    roots = [roots] if isinstance(roots, (str, os.PathLike)) else list(roots)
    if not roots:
        raise ManifestError("no dataset root given; pass a directory holding manifest.json (or a list of them)")
    out = []
    for root in roots:
        records, _ = read_manifest(root)
        prefix = f"{root}:" if len(roots) > 1 else ""
        for rec in records:
            out.append(
                dataclasses.replace(
                    rec,
                    id=prefix + rec.id,
                    twin=None if rec.twin is None else prefix + rec.twin,
                    path=str(Path(root) / rec.path),
                    reference=str(Path(root) / rec.reference),
                )
            )
    return out


def albedo_path(record: Record) -> str:
    """Where the albedo pass of ``record``'s scene variant lies: ``albedo.exr`` beside its reference."""
    return str(Path(record.reference).parent / ALBEDO_FILE)


def scenes_of(records: list[Record]) -> list[str]:
    """Scene families present, sorted (the fold units)."""
    return sorted({r.scene for r in records})
