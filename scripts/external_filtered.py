"""The external test set's three Cornell boxes rendered again through another pixel filter.

``../shared/external/renders`` is box-filtered; renderers filter with wider kernels by default (Mitsuba's is a
Gaussian), which spreads each sample over neighbouring pixels. This renders the scene files its README names
(``scenes/cbox``) in the same layout, through ``--filter``: ``OUT/<scene>/reference.exr`` (independent sampler,
16384 spp, seed 99) and ``OUT/<scene>/<algorithm> - <spp> - <seed>.exr`` for path_independent and
path_ldsampler, 2..512 spp, seeds 1 and 2; max depth 8 (cbox_official) and 12 (the others), 128x128.
Every file is written atomically and kept when it exists, so an interrupted run resumes. Then, e.g.:

    nriqa-evaluate OUT --out reports/external_gaussian --model unet_fast \\
        --pattern "{scene}/{algorithm} - {spp} - {seed}" --reference "{scene}/reference.exr"

    python scripts/external_filtered.py --filter gaussian --out data/external_gaussian [--external ../shared/external]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

SCENES = {
    "cbox_official": ("cbox-rgb.xml", 8),
    "cbox_indirect": ("cbox-indirect.xml", 12),
    "cbox_glass": ("cbox-glass.xml", 12),
}
SAMPLERS = {"path_independent": "independent", "path_ldsampler": "ldsampler"}
LADDER = [2**n for n in range(1, 10)]  # 2 .. 512
REFERENCE_SPP, REFERENCE_SEED, RESOLUTION = 16384, 99, 128


def scene_files(external: Path, out: Path, pixel_filter: str, sampler: str) -> Path:
    """A copy of the cbox scene files whose film filters with ``pixel_filter`` and samples with ``sampler``."""
    src = external / "scenes" / "cbox"
    dst = out / "scene_files" / f"{pixel_filter}_{sampler}"
    (dst / "fragments").mkdir(parents=True, exist_ok=True)
    if not (dst / "meshes").exists():
        (dst / "meshes").symlink_to((src / "meshes").resolve())
    for xml in src.glob("*.xml"):
        (dst / xml.name).write_text(xml.read_text())
    for frag in (src / "fragments").glob("*.xml"):
        text = frag.read_text()
        if frag.name == "base.xml":
            text, n_filter = re.subn(r'<rfilter type="box"/>', f'<rfilter type="{pixel_filter}"/>', text)
            text, n_sampler = re.subn(r'<sampler type="independent">', f'<sampler type="{sampler}">', text)
            if (n_filter, n_sampler) != (1, 1):
                sys.exit(f"external_filtered: error: {frag}: expected one box rfilter and one independent sampler")
        (dst / "fragments" / frag.name).write_text(text)
    return dst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--filter", required=True, help="Mitsuba rfilter type: gaussian, tent, mitchell, lanczos, ...")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--external", type=Path, default=Path("../shared/external"))
    args = ap.parse_args()
    if not (args.external / "scenes" / "cbox").is_dir():
        sys.exit(f"external_filtered: error: {args.external}/scenes/cbox not found; pass --external DIR")

    from nriqa.io.atomic import write_text_atomic
    from nriqa.io.exr import write_exr
    from nriqa.render.backend import select_backend

    variant = select_backend("auto")
    import mitsuba as mi

    mi.set_variant(variant)
    log_path = args.out / "render_log.json"
    log = json.loads(log_path.read_text()) if log_path.is_file() else []
    files = {s: scene_files(args.external, args.out, args.filter, s) for s in {"independent", *SAMPLERS.values()}}
    for scene, (xml, depth) in SCENES.items():
        jobs = [("reference", "independent", REFERENCE_SPP, REFERENCE_SEED, "reference.exr")]
        jobs += [
            (alg, s, spp, seed, f"{alg} - {spp} - {seed}.exr")
            for alg, s in SAMPLERS.items()
            for spp in LADDER
            for seed in (1, 2)
        ]
        for alg, sampler, spp, seed, name in jobs:
            path = args.out / scene / name
            if path.is_file():
                continue
            loaded = mi.load_file(str(files[sampler] / xml), res=RESOLUTION, spp=spp, max_depth=depth)
            start = time.perf_counter()
            image = mi.render(loaded, seed=seed).numpy()
            seconds = time.perf_counter() - start
            path.parent.mkdir(parents=True, exist_ok=True)
            write_exr(path, image)
            log.append(
                {
                    "scene": scene,
                    "alg": alg,
                    "spp": spp,
                    "seed": seed,
                    "seconds": round(seconds, 3),
                    "filter": args.filter,
                    "backend": variant,
                }
            )
            write_text_atomic(log_path, json.dumps(log, indent=1) + "\n")
            print(f"{scene} {name}: {seconds:.1f} s", flush=True)


if __name__ == "__main__":
    main()
