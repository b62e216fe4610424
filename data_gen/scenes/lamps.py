"""Night: small visible lamps (spherical area lights) over a glossy floor, nothing else lit.

Unlike ``shadows``' point and spot lights, whose contribution a path tracer samples exactly,
small area lights are found by chance and by light sampling both: at a few samples per pixel the
floor's glossy reflections and the soft shadows are speckled with bright samples, and the lamps
themselves are blown out while most of the frame stays dark. Exposure varies by 2^U(-3,3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._parts import (
    PATH_FAMILY,
    SHAPES,
    area_light,
    camera,
    diffuse,
    floor,
    jitter,
    random_color,
    random_material,
    rectangle,
    rgb,
    standing_shape,
    transform,
)


def _object(rng: np.random.Generator) -> dict:
    """A ball, block or pillar on the floor: diffuse, rough plastic or rough metal."""
    kind = SHAPES[int(rng.integers(len(SHAPES)))]
    bsdf = random_material(rng, ("diffuse", "roughplastic", "roughconductor"))
    x, z, size = float(rng.uniform(-1.6, 1.6)), float(rng.uniform(-1.6, 0.8)), float(rng.uniform(0.15, 0.35))
    turn, height = float(rng.uniform(0, 90)), float(rng.uniform(0.5, 1.2))
    return standing_shape(kind, x, z, size if kind != "cylinder" else size / 2, bsdf, turn, height)


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [0, 1.4, 3.6], [0.6, 0.3, 0.3]), jitter(rng, [0, 0.7, 0], [0.3, 0.2, 0.3]), rng.uniform(45, 65)
        ),
        "floor": floor(
            0.0,
            5.0,
            {
                "type": "roughplastic",
                "diffuse_reflectance": rgb(random_color(rng, 0.05, 0.4)),
                "alpha": float(rng.uniform(0.02, 0.25)),
            },
        ),
        "back": rectangle(t().translate([0, 2.5, -2.5]).scale([5, 2.5, 1]), diffuse(random_color(rng, 0.1, 0.6))),
    }
    for k in range(int(rng.integers(2, 6))):
        radius = float(rng.uniform(0.03, 0.12))
        colour = np.asarray(random_color(rng, 0.6, 1.0))
        scene[f"lamp{k}"] = {
            "type": "sphere",
            "center": jitter(rng, [0, 1.3, -0.8], [1.8, 0.9, 1.2]),
            "radius": radius,
            # the same power for every size: a smaller lamp is brighter, and harder to find
            "emitter": area_light(colour * 0.6 / radius**2),
        }
    for k in range(int(rng.integers(2, 5))):
        scene[f"object{k}"] = _object(rng)
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="lamps",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=8,
        summary="night: small visible spherical lamps over a glossy floor, exposure 2^U(-3,3)",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 64, "path_multijitter": 256},
    )
)
