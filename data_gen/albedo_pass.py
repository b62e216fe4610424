"""The albedo pass of every scene variant of a dataset: ``{scene}/v{NNN}/albedo.exr`` beside its reference.

Renderers write an albedo pass (the surface colour a ray first meets, before any light) for their
denoisers; it is nearly free of Monte Carlo noise at a few samples, and shows where the image's
detail is texture and geometry rather than noise. Models with ``data.albedo_pass=true`` take it as
a second input (:mod:`nriqa.data.images`). Rendered with Mitsuba's ``aov`` integrator into the
same film (and pixel filter) as the dataset's images, the variant rebuilt from the dataset's seed exactly
as :mod:`data_gen.plan` builds it. A file that exists is kept, so an interrupted run resumes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from data_gen.plan import ImageTask, Job, derive_seed
from data_gen.render import sanitize, scene_dict
from data_gen.scenes import get_scene
from nriqa.io.exr import write_exr
from nriqa.io.manifest import ALBEDO_FILE, Record, albedo_path

ALBEDO_SPP = 64  # antialiased edges; the pass has no lighting noise, only pixel coverage and defocus


def variants_of(records: list[Record]) -> dict[str, Record]:
    """One record per scene variant, keyed by the albedo pass's path relative to the dataset root."""
    out: dict[str, Record] = {}
    for rec in records:
        out.setdefault(albedo_path(rec), rec)
    return out


def without_null_surfaces(scene: dict) -> dict:
    """``scene`` without its null-BSDF shapes (the boundaries of participating media) and its sensor's medium.

    Such a boundary is invisible in the render, where its medium shows; Mitsuba's ``aov`` integrator stops at it
    and reads an albedo of 0, which would black out a fog block and, where the camera stands in a medium (the
    ``shafts`` family), the whole pass. Without them the pass shows the surfaces behind, as the render does
    through a thin haze (the integrator ignores media).
    """
    out = {k: v for k, v in scene.items() if not (isinstance(v, dict) and v.get("bsdf") == {"type": "null"})}
    out["sensor"] = {k: v for k, v in scene["sensor"].items() if k != "medium"}
    return out


def albedo_scene(rec: Record, seed: int, spp: int = ALBEDO_SPP) -> dict:
    """The Mitsuba scene of ``rec``'s variant (dataset ``seed``) with the albedo ``aov`` integrator, seen through
    its media (:func:`without_null_surfaces`)."""
    spec = get_scene(rec.scene)
    vseed = derive_seed(seed, rec.scene, rec.variant)
    job = Job(
        rec.scene,
        rec.variant,
        vseed,
        spec.reference_algorithm,
        (rec.width, rec.height),
        spec.max_depth,
        (),
        rec.pixel_filter,
        rec.zoom,
    )
    task = ImageTask("albedo", "albedo", spp, 0, ALBEDO_FILE, rec.reference)
    scene = without_null_surfaces(scene_dict(job, task))
    scene["integrator"] = {"type": "aov", "aovs": "albedo:albedo"}
    return scene


def render_albedo(root: Path, rec: Record, seed: int, spp: int = ALBEDO_SPP) -> Path:
    """Render and write (atomically) the albedo pass of ``rec``'s variant; return its path."""
    import mitsuba as mi

    image = np.array(mi.render(mi.load_dict(albedo_scene(rec, seed, spp)), seed=0), dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise RuntimeError(f"{rec.scene} v{rec.variant}: the aov integrator gave shape {image.shape}, not (H, W, 3)")
    image, _ = sanitize(image)
    path = root / albedo_path(rec)
    write_exr(path, np.clip(image, 0.0, 1.0))
    return path


def render_scene_file(scene_file: Path, out: Path, spp: int = ALBEDO_SPP, **params: int) -> np.ndarray:
    """The albedo pass of a Mitsuba scene file (its own sensor and film; ``params`` as ``mi.load_file``
    takes them, e.g. ``res=128``), written atomically to ``out``; returns it ``(H, W, 3)``."""
    import mitsuba as mi

    scene = mi.load_file(str(scene_file), **params)
    aov = mi.load_dict({"type": "aov", "aovs": "albedo:albedo"})
    image = np.array(mi.render(scene, integrator=aov, spp=spp, seed=0), dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise RuntimeError(f"{scene_file}: the aov integrator gave shape {image.shape}, not (H, W, 3)")
    image = np.clip(sanitize(image)[0], 0.0, 1.0)
    write_exr(out, image)
    return image


def main(argv: list[str] | None = None) -> int:
    """``python -m data_gen.albedo_pass DATA [--spp N]``: the albedo pass of each scene variant of DATA (resumable);
    ``--scene-file XML --out FILE [--res N]``: of one Mitsuba scene file."""
    import argparse
    import sys

    from nriqa.io.manifest import ManifestError, read_manifest
    from nriqa.render.backend import ensure_variant

    parser = argparse.ArgumentParser(prog="python -m data_gen.albedo_pass", description=main.__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, nargs="?", help="dataset root (holds manifest.json)")
    parser.add_argument("--scene-file", type=Path, help="instead of DATA: one Mitsuba scene file (with --out)")
    parser.add_argument("--out", type=Path, help="with --scene-file: the albedo pass's EXR file")
    parser.add_argument("--res", type=int, default=None, help="with --scene-file: its $res parameter, if it has one")
    parser.add_argument("--spp", type=int, default=ALBEDO_SPP, help=f"samples per pixel (default {ALBEDO_SPP})")
    parser.add_argument("--backend", default="auto", help="Mitsuba variant: auto, llvm_ad_rgb, cuda_ad_rgb, scalar_rgb")
    args = parser.parse_args(argv)
    if args.spp < 1:
        print(f"data_gen.albedo_pass: error: --spp {args.spp}: need at least 1 sample per pixel", file=sys.stderr)
        return 2
    if (args.data is None) == (args.scene_file is None) or (args.scene_file is None) != (args.out is None):
        message = "give a dataset root DATA, or --scene-file XML with --out FILE"
        print(f"data_gen.albedo_pass: error: {message}", file=sys.stderr)
        return 2
    if args.scene_file is not None:
        return _one_scene_file(args)
    try:
        records, meta = read_manifest(args.data)
    except ManifestError as exc:
        print(f"data_gen.albedo_pass: error: {exc}", file=sys.stderr)
        return 2
    seed = (meta.get("config") or {}).get("seed")
    if seed is None:
        print(
            f"data_gen.albedo_pass: error: {args.data}/manifest.json names no seed (meta.config.seed); "
            "render the dataset with python -m data_gen",
            file=sys.stderr,
        )
        return 2
    todo = {p: r for p, r in variants_of(records).items() if not (args.data / p).is_file()}
    print(f"{args.data}: {len(variants_of(records))} scene variants, {len(todo)} albedo passes to render")
    if todo:
        try:
            ensure_variant(args.backend)
        except (RuntimeError, ValueError) as exc:
            print(f"data_gen.albedo_pass: error: {exc}", file=sys.stderr)
            return 2
    for rec in todo.values():
        render_albedo(args.data, rec, int(seed), args.spp)
    return 0


def _one_scene_file(args) -> int:
    """``--scene-file XML --out FILE``: one line on success, one line and exit 2 on a file Mitsuba cannot load."""
    import sys

    from nriqa.render.backend import ensure_variant

    if not args.scene_file.is_file():
        print(f"data_gen.albedo_pass: error: {args.scene_file}: no such scene file", file=sys.stderr)
        return 2
    try:
        ensure_variant(args.backend)
        params = {} if args.res is None else {"res": args.res}
        image = render_scene_file(args.scene_file, args.out, args.spp, **params)
    except (RuntimeError, ValueError) as exc:  # Mitsuba's load errors are RuntimeError
        print(f"data_gen.albedo_pass: error: {args.scene_file}: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: {image.shape[1]}x{image.shape[0]} albedo pass of {args.scene_file}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
