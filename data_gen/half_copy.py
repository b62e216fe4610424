"""A half-float copy of a dataset, or of some of its variants, small enough to carry to a lent GPU.

``python -m data_gen.half_copy SRC [SRC ...] DST [--variants 26 27 ...] [--no-twins]`` writes every image
the kept records name (noisy images and their references) as a half-float PIZ EXR under ``DST``, then
``DST/manifest.json`` with those records (written last: a copy without one is unfinished; rerun it).
Several sources make one dataset (the variants of separate renders, carried together); a record id
or image path that two sources both hold is refused.
Half floats keep 11 significant bits (a relative rounding of at most 2^-11, far below any noise the
SSIM target sees); a finite value beyond half's range (65504) is refused, not clipped.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from pathlib import Path

import numpy as np

from nriqa.io.exr import read_exr, write_exr
from nriqa.io.manifest import ManifestError, Record, read_manifest, write_manifest

HALF_MAX = float(np.finfo(np.float16).max)


class HalfCopyError(ValueError):
    """An image that half floats cannot hold, or a selection that keeps nothing."""


def select(records: list[Record], variants: set[int] | None, twins: bool) -> list[Record]:
    """The records of ``variants`` (all if None), twins dropped (and unlinked) unless ``twins``."""
    kept = [r for r in records if variants is None or r.variant in variants]
    if not twins:
        kept = [dataclasses.replace(r, twin=None) for r in kept if r.role != "twin"]
    return kept


def write_half(src: Path, dst: Path) -> int:
    """Copy one EXR as half floats (PIZ); returns the bytes written. Raises HalfCopyError past half's range."""
    rgb = read_exr(src)
    finite = np.isfinite(rgb)
    peak = float(np.abs(rgb[finite]).max()) if finite.any() else 0.0
    if peak > HALF_MAX:
        raise HalfCopyError(f"{src}: value {peak:.3g} is beyond half-float range ({HALF_MAX:.0f}); copy it as float32")
    write_exr(dst, rgb, half=True)
    return dst.stat().st_size


def half_copy(src, dst: str | os.PathLike, variants=None, twins: bool = True) -> tuple[int, int]:
    """Copy the selected records of ``src`` (one dataset root or several) to ``dst`` as half floats.

    Returns ``(records, bytes)``. The copy's manifest keeps the first source's metadata.
    """
    sources = [Path(src)] if isinstance(src, (str, os.PathLike)) else [Path(s) for s in src]
    dst = Path(dst)
    chosen = None if variants is None else {int(v) for v in variants}
    plan: list[tuple[Path, list[Record]]] = []
    owner: dict[str, Path] = {}
    meta: dict = {}
    for root in sources:
        records, root_meta = read_manifest(root)
        meta = meta or root_meta
        kept = select(records, chosen, twins)
        if not kept:
            which = "no record" if variants is None else f"no record of variants {sorted(chosen)}"
            raise HalfCopyError(f"{root}: {which}; see its manifest for the variants it has")
        for key in [r.id for r in kept] + [r.path for r in kept]:
            if owner.setdefault(key, root) != root:
                raise HalfCopyError(f"{root}: {key} is also in {owner[key]}; copy sources that hold different variants")
        plan.append((root, kept))
    size = 0
    for root, kept in plan:
        files = sorted({r.path for r in kept} | {r.reference for r in kept})
        size += sum(write_half(root / f, dst / f) for f in files)
    records = [r for _, kept in plan for r in kept]
    copied_from = str(sources[0]) if len(sources) == 1 else [str(s) for s in sources]
    write_manifest(dst, records, {**meta, "half_copy_of": copied_from})
    return len(records), size


def main(argv: list[str] | None = None) -> None:
    """``python -m data_gen.half_copy SRC [SRC ...] DST [--variants V ...] [--no-twins]``: a half-float copy."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m data_gen.half_copy", description=main.__doc__.splitlines()[0])
    parser.add_argument("src", type=Path, nargs="+", help="dataset roots (each holds manifest.json)")
    parser.add_argument("dst", type=Path, help="folder for the copy")
    parser.add_argument("--variants", type=int, nargs="+", default=None, help="keep only these scene variants")
    parser.add_argument("--no-twins", action="store_true", help="drop the twin images (the copy is half the size)")
    args = parser.parse_args(argv)
    try:
        n, size = half_copy(args.src, args.dst, args.variants, twins=not args.no_twins)
    except (HalfCopyError, ManifestError) as exc:
        sys.exit(f"data_gen.half_copy: error: {exc}")
    print(f"wrote {args.dst}: {n} records, {size / 2**20:.1f} MiB of images")


if __name__ == "__main__":
    main()
