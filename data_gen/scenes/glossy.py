"""Glossy and metallic objects: rough conductors and rough plastic, a torus mesh built in numpy."""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._parts import (
    METALS,
    PATH_FAMILY,
    area_light,
    camera,
    diffuse,
    floor,
    jitter,
    random_color,
    rectangle,
    rgb,
    torus_mesh,
    transform,
)


def build(rng: np.random.Generator) -> dict:
    t = transform
    scene = {
        "type": "scene",
        "sensor": camera(jitter(rng, [0, 1.5, 3.5], [0.8, 0.3, 0.3]), [0, 0.4, 0], 40),
        "floor": floor(0.0, 4.0, diffuse(random_color(rng, 0.3, 0.7))),
        "light": rectangle(
            t()
            .translate(jitter(rng, [-1.0, 3.0, 1.0], [0.8, 0.2, 0.8]))
            .rotate([1, 0, 0], 90)
            .scale(rng.uniform(0.4, 0.8)),
            emitter=area_light(np.full(3, rng.uniform(6, 12))),
        ),
        "sky": {"type": "constant", "radiance": rgb(np.full(3, rng.uniform(0.05, 0.2)))},
        "metal": {
            "type": "sphere",
            "center": [-0.7, 0.45, 0.0],
            "radius": 0.45,
            "bsdf": {
                "type": "roughconductor",
                "material": str(rng.choice(METALS)),
                "alpha": float(rng.uniform(0.05, 0.35)),
            },
        },
        "ring": torus_mesh(
            "ring",
            {
                "type": "roughplastic",
                "diffuse_reflectance": rgb(random_color(rng)),
                "alpha": float(rng.uniform(0.05, 0.3)),
            },
            major=0.45,
            minor=0.15,
            to_world=t()
            .translate([0.7, 0.35, 0.2])
            .rotate([1, 0, 0], rng.uniform(30, 90))
            .rotate([0, 1, 0], rng.uniform(0, 180)),
        ),
    }
    return scene


SPEC = register_scene(
    SceneSpec(
        name="glossy",
        build=build,
        algorithms=(*PATH_FAMILY, "ptracer_independent"),
        max_depth=8,
        summary="rough metal sphere and rough plastic torus",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 256, "path_multijitter": 256},
    )
)
