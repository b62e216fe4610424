"""A room lit only indirectly: a bright light outside shines through a door left ajar.

Most of what the camera sees receives light after two or more bounces, the hardest case for a
path tracer and an easy one for light tracing.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._parts import (
    PATH_FAMILY,
    area_light,
    camera,
    diffuse,
    jitter,
    random_color,
    rectangle,
    transform,
    wall_x,
)

W, H = 2.0, 2.5  # half width of the square room, height


def build(rng: np.random.Generator) -> dict:
    t = transform
    wall = diffuse(jitter(rng, [0.7, 0.68, 0.62], 0.08))
    door_w, door_h = 0.9, 2.0
    door_z = rng.uniform(-1.4, 0.2)
    angle = rng.uniform(8, 25)  # how far the door is ajar, degrees
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [-1.6, 1.3, 1.6], [0.2, 0.2, 0.2]), jitter(rng, [1.0, 0.7, -0.8], [0.3, 0.2, 0.4]), 70
        ),
        "floor": rectangle(
            t().translate([0, 0, 0]).rotate([1, 0, 0], -90).scale(W), diffuse(random_color(rng, 0.2, 0.6))
        ),
        "ceiling": rectangle(t().translate([0, H, 0]).rotate([1, 0, 0], 90).scale(W), wall),
        "back": rectangle(t().translate([0, H / 2, -W]).scale([W, H / 2, 1]), wall),
        "front": rectangle(t().translate([0, H / 2, W]).scale([W, H / 2, 1]), wall),
        "left": wall_x(-W, -W, W, 0, H, wall),
        # the door wall at x = +W, with an opening [door_z, door_z + door_w] x [0, door_h]
        "right_a": wall_x(W, -W, door_z, 0, H, wall),
        "right_b": wall_x(W, door_z + door_w, W, 0, H, wall),
        "lintel": wall_x(W, door_z, door_z + door_w, door_h, H, wall),
        # the door leaf, hinged at door_z and swung outwards by `angle`
        "door": rectangle(
            t()
            .translate([W, door_h / 2, door_z])
            .rotate([0, 1, 0], -angle)
            .translate([0, 0, door_w / 2])
            .rotate([0, 1, 0], -90)
            .scale([door_w / 2, door_h / 2, 1]),
            diffuse(random_color(rng, 0.3, 0.7)),
        ),
        "outside": rectangle(
            t().translate([W + 2.5, 1.5, door_z]).rotate([0, 1, 0], -90).scale([2.5, 1.5, 1]),
            emitter=area_light(np.asarray(random_color(rng, 0.8, 1.0)) * rng.uniform(15, 30)),
        ),
        "table": {
            "type": "cube",
            "to_world": t().translate(jitter(rng, [0.2, 0.4, -0.5], [0.5, 0, 0.5])).scale([0.5, 0.4, 0.35]),
            "bsdf": diffuse(random_color(rng)),
        },
    }
    return scene


SPEC = register_scene(
    SceneSpec(
        name="door",
        build=build,
        algorithms=(*PATH_FAMILY, "ptracer_independent"),
        ladder_top=128,
        max_depth=10,
        summary="room lit indirectly through a door ajar",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 256},
    )
)
