"""Clutter: a dozen small objects of mixed materials on a table, under a window light and a dim sky.

Many small shapes, each with its own material (diffuse, plastic, rough plastic, rough metal,
glass): occlusion edges, contact shadows, glossy highlights and small caustics side by side, so
the noise of one material sits next to the texture and edges of another. Exposure varies by
2^U(-3,3) per variant.
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


def _item(rng: np.random.Generator) -> dict:
    x, z, size = float(rng.uniform(-1.0, 1.0)), float(rng.uniform(-0.8, 0.6)), float(rng.uniform(0.06, 0.18))
    kind = SHAPES[int(rng.integers(len(SHAPES)))]
    bsdf = random_material(rng)
    turn, height = float(rng.uniform(0, 90)), float(rng.uniform(1.5, 4.0) * size)
    return standing_shape(kind, x, z, size, bsdf, turn, height)


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [0, 1.3, 2.2], [0.5, 0.3, 0.3]),
            jitter(rng, [0, 0.1, -0.1], [0.2, 0.05, 0.2]),
            rng.uniform(40, 55),
        ),
        "table": floor(0.0, 3.0, diffuse(random_color(rng, 0.3, 0.8))),
        "back": rectangle(t().translate([0, 1.5, -1.5]).scale([3, 1.5, 1]), diffuse(random_color(rng, 0.3, 0.8))),
        "window": rectangle(
            t()
            .translate(jitter(rng, [-1.2, 2.2, 0.6], [0.4, 0.2, 0.4]))
            .rotate([0, 0, 1], 40)  # tilted towards the table
            .rotate([1, 0, 0], 90)
            .scale(rng.uniform(0.4, 0.8)),
            emitter=area_light(np.asarray(random_color(rng, 0.8, 1.0)) * rng.uniform(15, 30)),
        ),
        "sky": {"type": "constant", "radiance": rgb(np.asarray(random_color(rng, 0.5, 1.0)) * rng.uniform(0.02, 0.15))},
    }
    for k in range(int(rng.integers(8, 16))):
        scene[f"item{k:02d}"] = _item(rng)
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="clutter",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=10,
        summary="a dozen small objects of mixed materials (glass and metal among them), exposure 2^U(-3,3)",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 64, "path_multijitter": 256},
    )
)
