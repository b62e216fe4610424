"""A dim room lit only indirectly: the light faces the ceiling, hides behind a partition, or shines in
through small openings.

Like the public Cornell box with its luminaire turned to the ceiling: at a few samples per pixel
the image is mostly black with sparse bright samples, and only many bounces fill it in. Exposure
varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._parts import (
    PATH_FAMILY,
    area_light,
    camera,
    diffuse,
    jitter,
    random_color,
    rectangle,
    room,
    transform,
    wall_x,
    wall_x_with_opening,
)

W, D, H = 2.0, 2.0, 2.5  # room: x in [-W, W], z in [-D, D], y in [0, H]
MODES = ("ceiling", "partition", "openings")


def _lighting(rng: np.random.Generator, mode: str, wall: dict) -> dict:
    """The emitter (never seen directly from inside) and what hides it; the wall at x = +W when it has holes."""
    t = transform
    colour = np.asarray(random_color(rng, 0.8, 1.0))
    if mode == "ceiling":  # a small panel under the ceiling, facing it
        size = rng.uniform(0.15, 0.3)
        pos = jitter(rng, [0.3, H - 0.25, -0.3], [0.8, 0.1, 0.8])
        return {
            "light": rectangle(
                t().translate(pos).rotate([1, 0, 0], -90).scale(size),
                bsdf=diffuse([0.2, 0.2, 0.2]),
                emitter=area_light(colour * 1.2 / size**2),
            ),
            "east": wall_x(W, -D, D, 0, H, wall),
        }
    if mode == "partition":  # a panel behind a low wall near the back, facing the back wall
        z, height = -D + rng.uniform(0.4, 0.7), rng.uniform(1.0, 1.6)
        size = rng.uniform(0.15, 0.3)
        pos = jitter(rng, [0, height * 0.6, z + 0.05], [1.0, 0.1, 0])
        return {
            "light": rectangle(
                t().translate(pos).rotate([0, 1, 0], 180).scale(size),
                bsdf=diffuse([0.2, 0.2, 0.2]),
                emitter=area_light(colour * 1.2 / size**2),
            ),
            "partition": rectangle(t().translate([0, height / 2, z + 0.15]).scale([W, height / 2, 1]), wall),
            "east": wall_x(W, -D, D, 0, H, wall),
        }
    # small openings in the east wall, a bright panel outside facing them
    z0, y0 = rng.uniform(-1.5, 0.8), rng.uniform(0.6, 1.6)
    z1, y1 = z0 + rng.uniform(0.2, 0.6), y0 + rng.uniform(0.15, 0.5)
    return {
        "outside": rectangle(
            t().translate([W + 1.5, 1.2, (z0 + z1) / 2]).rotate([0, 1, 0], -90).scale([1.5, 1.2, 1]),
            emitter=area_light(colour * 20.0),
        ),
        **wall_x_with_opening(W, D, H, z0, z1, y0, y1, wall),
    }


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    mode = MODES[int(rng.integers(len(MODES)))]
    t = transform
    wall = diffuse(jitter(rng, [0.7, 0.68, 0.62], 0.08))
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [-1.5, 1.3, 1.6], [0.3, 0.3, 0.3]),
            jitter(rng, [1.0, 0.9, -1.0], [0.4, 0.3, 0.4]),
            rng.uniform(60, 75),
        ),
        **room(rng, W, D, H, wall),
        "table": {
            "type": "cube",
            "to_world": t()
            .translate(jitter(rng, [0.3, 0.4, 0.3], [0.6, 0, 0.5]))
            .rotate([0, 1, 0], rng.uniform(0, 90))
            .scale([0.5, 0.4, 0.35]),
            "bsdf": diffuse(random_color(rng)),
        },
        **_lighting(rng, mode, wall),
    }
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="dim_interior",
        build=build,
        algorithms=(*PATH_FAMILY, "ptracer_independent"),
        max_depth=12,
        summary="room lit only indirectly (light to the ceiling, behind a partition, through openings), "
        "exposure 2^U(-3,3)",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"ptracer_independent": 32},
    )
)
