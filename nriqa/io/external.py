"""Bring an external folder of renders into the dataset form, so any renderer's output can be evaluated.

A folder such as::

    renders/cornell/path - 16.exr      renders/cornell/path - 64.exr     renders/cornell/reference.exr
    renders/door/bdpt - 8.png          renders/door/bdpt - 2048.png

becomes :class:`nriqa.io.manifest.Record` s (role ``test``, or ``twin`` for a second seed, and one
``reference`` per scene), in memory (:func:`scan_external`) or as a manifest written into an
output folder (:func:`import_external`; ``nriqa-external``, :mod:`nriqa.cli.external`). Names are parsed with a
pattern of ``{scene}``, ``{algorithm}``, ``{spp}`` and optionally ``{variant}`` and ``{seed}``
fields over the path relative to the folder, without its suffix (default
``"{scene}/{algorithm} - {spp}"``). The reference of each scene is either

* a glob relative to the folder, ``{scene}`` substituted (default ``"{scene}/reference.*"``), or
* ``"highest:ALGO"``: the highest-spp image of algorithm ALGO in that scene (it is then not a test image).

An ``albedo.exr`` beside a scene's reference is its albedo pass (:func:`nriqa.io.manifest.albedo_path`),
for scorers that take one, not a test image.

Images are EXR (linear HDR, tone-mapped by :func:`nriqa.core.tonemap.tonemap` when loaded) or PNG/JPEG
(display-referred LDR: used as they are, no tone map). :func:`nriqa.io.imread.load_ldr` loads either.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from nriqa.errors import NriqaError
from nriqa.io.imread import SUFFIXES, read_image
from nriqa.io.manifest import ALBEDO_FILE, Record, write_manifest

DEFAULT_PATTERN = "{scene}/{algorithm} - {spp}"
DEFAULT_REFERENCE = "{scene}/reference.*"
_FIELDS = {"scene": r"[^/]+?", "algorithm": r"[^/]+?", "spp": r"\d+", "variant": r"\d+", "seed": r"\d+"}
_EXAMPLE = {"scene": "cornell", "algorithm": "path", "spp": "16", "variant": "0", "seed": "1"}  # for error messages


class ExternalError(NriqaError):
    """An external folder that cannot be read as a dataset; the message says which file and what to do."""


def compile_pattern(pattern: str) -> re.Pattern:
    """Turn ``"{scene}/{algorithm} - {spp}"`` into a regex with one named group per field.

    Raises:
        ExternalError: an unknown field, or ``{scene}``, ``{algorithm}`` or ``{spp}`` missing.
    """
    fields = re.findall(r"\{(\w+)\}", pattern)
    unknown = sorted(set(fields) - set(_FIELDS))
    if unknown:
        raise ExternalError(
            f"pattern {pattern!r}: unknown field(s) {unknown}; "
            "use {scene}, {algorithm}, {spp}, {variant}, {seed}"
        )
    missing = [f for f in ("scene", "algorithm", "spp") if f not in fields]
    if missing:
        raise ExternalError(f"pattern {pattern!r} lacks {', '.join('{' + f + '}' for f in missing)}")
    parts = re.split(r"(\{\w+\})", pattern)
    regex = "".join(
        f"(?P<{p[1:-1]}>{_FIELDS[p[1:-1]]})" if re.fullmatch(r"\{\w+\}", p) else re.escape(p) for p in parts
    )
    return re.compile(regex)


def _images(folder: Path) -> list[Path]:
    return sorted(
        p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in SUFFIXES and not p.name.startswith(".")
    )


def _find_reference(folder: Path, scene: str, reference: str, parsed: list[tuple[Path, dict]]) -> Path:
    if reference.startswith("highest:"):
        algorithm = reference.split(":", 1)[1]
        own = [(int(f["spp"]), p) for p, f in parsed if f["scene"] == scene and f["algorithm"] == algorithm]
        if not own:
            raise ExternalError(
                f"{folder}: scene {scene!r} has no image of algorithm {algorithm!r} to take the reference from"
            )
        return max(own)[1]
    glob = reference.replace("{scene}", scene)
    hits = sorted(p for p in folder.glob(glob) if p.is_file() and p.suffix.lower() in SUFFIXES)
    if not hits:
        raise ExternalError(
            f"{folder}: scene {scene!r} has no reference matching {glob!r}; add one or pass --reference"
        )
    if len(hits) > 1:
        names = ", ".join(str(h.relative_to(folder)) for h in hits)
        raise ExternalError(
            f"{folder}: reference pattern {glob!r} matches {len(hits)} files ({names}); make it match one"
        )
    return hits[0]


def _parse(folder: Path, pattern: str, reference: str) -> tuple[list[tuple[Path, dict]], dict[str, Path]]:
    """Every image of ``folder`` with its parsed name fields, and each scene's reference file."""
    if not folder.is_dir():
        raise ExternalError(f"{folder}: no such folder")
    regex = compile_pattern(pattern)
    files = _images(folder)
    if not files:
        raise ExternalError(f"{folder}: no images ({', '.join(SUFFIXES)}) found")
    parsed, unparsed = [], []
    for path in files:
        m = regex.fullmatch(path.relative_to(folder).with_suffix("").as_posix())
        if m:
            parsed.append((path, m.groupdict()))
        else:
            unparsed.append(path)
    refs = {s: _find_reference(folder, s, reference, parsed) for s in sorted({f["scene"] for _, f in parsed})}
    is_glob_reference = not reference.startswith("highest:")
    albedo_passes = {ref.parent / ALBEDO_FILE for ref in refs.values()}  # beside a reference: not a test image
    bad = [p for p in unparsed if not (is_glob_reference and p in refs.values()) and p not in albedo_passes]
    if bad:
        example = pattern
        for field, value in _EXAMPLE.items():
            example = example.replace("{" + field + "}", value)
        raise ExternalError(
            f"{bad[0]}: name does not match pattern {pattern!r} (e.g. '{example}.exr'); rename it or pass --pattern"
        )
    if not parsed:
        raise ExternalError(f"{folder}: no image name matches pattern {pattern!r}; pass --pattern")
    return parsed, refs


def scan_external(
    folder: str | os.PathLike, pattern: str = DEFAULT_PATTERN, reference: str = DEFAULT_REFERENCE
) -> list[Record]:
    """Records for every image of an external ``folder``; paths relative to ``folder``.

    Images sharing scene, variant, algorithm and spp but differing in ``{seed}`` are paired as
    ``test`` and ``twin`` (the lower seed is the test image).

    Raises:
        ExternalError: no images, an image name the pattern does not parse, a scene without a
            (unique) reference, more than two images for one (scene, variant, algorithm, spp), or
            an image whose size differs from its reference.
    """
    folder = Path(folder)
    parsed, refs = _parse(folder, pattern, reference)
    sizes: dict[Path, tuple[int, int]] = {}

    def record(path: Path, ref: Path, **fields) -> Record:
        if path not in sizes:
            sizes[path] = tuple(read_image(path)[0].shape[:2])
        h, w = sizes[path]
        rel = path.relative_to(folder).as_posix()
        ref_rel = ref.relative_to(folder).as_posix()
        return Record(path=rel, reference=ref_rel, width=w, height=h, render_seconds=0.0, backend="external", **fields)

    records = [
        record(
            ref, ref, id=f"{s}/reference", scene=s, variant=0, algorithm="reference", role="reference", spp=0, seed=0
        )
        for s, ref in refs.items()
    ]
    groups: dict[tuple, list[tuple[int, Path]]] = {}
    for path, f in parsed:
        if path != refs[f["scene"]]:
            key = (f["scene"], int(f.get("variant") or 0), f["algorithm"], int(f["spp"]))
            groups.setdefault(key, []).append((int(f.get("seed") or 0), path))
    for (scene, variant, algorithm, spp), members in sorted(groups.items()):
        if len(members) > 2:
            names = ", ".join(str(p.relative_to(folder)) for _, p in members)
            raise ExternalError(
                f"{folder}: {len(members)} images for {scene} {algorithm} {spp} spp ({names}); "
                "keep one, or two with a {seed} field"
            )
        members.sort()
        ids = [p.relative_to(folder).with_suffix("").as_posix() for _, p in members]
        ref = refs[scene]
        for k, (seed, path) in enumerate(members):
            twin = ids[1 - k] if len(members) == 2 else None
            rec = record(
                path,
                ref,
                id=ids[k],
                scene=scene,
                variant=variant,
                algorithm=algorithm,
                role=("test", "twin")[k],
                spp=spp,
                seed=seed,
                twin=twin,
            )
            if (rec.height, rec.width) != sizes[ref]:
                rh, rw = sizes[ref]
                raise ExternalError(
                    f"{path}: size {rec.width}x{rec.height} differs from its reference {ref} ({rw}x{rh})"
                )
            records.append(rec)
    return records


def import_external(
    folder: str | os.PathLike,
    out: str | os.PathLike,
    pattern: str = DEFAULT_PATTERN,
    reference: str = DEFAULT_REFERENCE,
) -> Path:
    """Scan ``folder`` and write ``<out>/manifest.json`` whose paths point back into it; returns the manifest path.

    The images are not copied. The manifest may name PNG files: :func:`nriqa.io.imread.load_ldr`,
    which evaluation and training load through, reads them.
    """
    folder, out = Path(folder).resolve(), Path(out).resolve()
    records = scan_external(folder, pattern, reference)
    rebased = [
        Record(
            **{
                **r.to_dict(),
                "path": os.path.relpath(folder / r.path, out),
                "reference": os.path.relpath(folder / r.reference, out),
            }
        )
        for r in records
    ]
    return write_manifest(out, rebased, {"external": str(folder), "pattern": pattern, "reference": reference})
