"""A half-float copy of a dataset, or of some of its variants, small enough to carry to a lent GPU.

``python -m data_gen.half_copy SRC DST [--variants 26 27 ...] [--no-twins]`` writes every image the
kept records name (noisy images and their references) as a half-float PIZ EXR under ``DST``, then
``DST/manifest.json`` with those records (written last: a copy without one is unfinished; rerun it).
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


def half_copy(src: str | os.PathLike, dst: str | os.PathLike, variants=None, twins: bool = True) -> tuple[int, int]:
    """Copy ``src``'s selected records to ``dst`` as half floats; returns ``(records, bytes)``."""
    src, dst = Path(src), Path(dst)
    records, meta = read_manifest(src)
    kept = select(records, None if variants is None else {int(v) for v in variants}, twins)
    if not kept:
        which = "no record" if variants is None else f"no record of variants {sorted(variants)}"
        raise HalfCopyError(f"{src}: {which}; see its manifest for the variants it has")
    files = sorted({r.path for r in kept} | {r.reference for r in kept})
    size = sum(write_half(src / f, dst / f) for f in files)
    write_manifest(dst, kept, {**meta, "half_copy_of": str(src)})
    return len(kept), size


def main(argv: list[str] | None = None) -> None:
    """``python -m data_gen.half_copy SRC DST [--variants V ...] [--no-twins]``: a half-float copy of a dataset."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m data_gen.half_copy", description=main.__doc__.splitlines()[0])
    parser.add_argument("src", type=Path, help="dataset root (holds manifest.json)")
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
