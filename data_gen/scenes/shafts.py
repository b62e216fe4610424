"""Shafts: sunlight through a window into a hazy room, the light drawn as beams in the air.

A closed room filled with a thin homogeneous haze; the sun enters only through one window, split by
mullions into several beams that cross the air and land as a bright patch on the floor or wall, the
rest of the room lit by what the haze and the patch scatter. The camera stands in the haze (its
medium is the room's), so every pixel's path crosses it: a volumetric noise over dim, indirectly
lit surfaces with a few surfaces far brighter. No shipped network learnt this family (the ``heldout``
preset renders it to measure them). Exposure varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._meshes import rods_mesh
from data_gen.scenes._parts import (
    VOLPATH_FAMILY,
    camera,
    diffuse,
    jitter,
    rgb,
    room,
    transform,
    wall_x_with_opening,
)

W, D, H = 2.0, 2.0, 2.5  # room: x in [-W, W], z in [-D, D], y in [0, H]; the window in the wall x = +W
GAP = 0.01  # the haze's box stops this far inside the walls
HAZE = {"type": "ref", "id": "haze"}


def window(rng: np.random.Generator, wall: dict) -> dict:
    """The wall x = +W with one window, and its mullions (rods just outside, so none stands in the haze)."""
    z0, y0 = rng.uniform(-1.6, 0.2), rng.uniform(0.7, 1.2)
    z1, y1 = z0 + rng.uniform(0.6, 1.4), min(y0 + rng.uniform(0.6, 1.1), H - 0.1)
    parts = wall_x_with_opening(W, D, H, z0, z1, y0, y1, wall)
    bars = int(rng.integers(1, 4))
    zs = z0 + (z1 - z0) * np.arange(1, bars + 1) / (bars + 1)
    starts = [[W + 0.04, y0, z] for z in zs] + [[W + 0.04, (y0 + y1) / 2, z0]]
    ends = [[W + 0.04, y1, z] for z in zs] + [[W + 0.04, (y0 + y1) / 2, z1]]
    parts["mullions"] = rods_mesh("mullions", starts, ends, rng.uniform(0.015, 0.04), diffuse([0.3, 0.3, 0.3]))
    return parts


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    wall = diffuse(jitter(rng, [0.7, 0.68, 0.62], 0.08))
    sun = np.array([-1.0, -rng.uniform(0.4, 1.0), rng.uniform(-0.5, 0.5)])
    scene = {
        "type": "scene",
        "haze": {
            "type": "homogeneous",
            "albedo": rgb(np.full(3, rng.uniform(0.7, 0.95))),
            "sigma_t": float(rng.uniform(0.05, 0.35)),
            "phase": {"type": "hg", "g": float(rng.uniform(0.2, 0.7))},
        },
        "sensor": {
            **camera(
                jitter(rng, [-1.6, 1.2, 1.6], [0.2, 0.3, 0.2]),
                jitter(rng, [0.8, 0.9, -0.6], [0.4, 0.3, 0.5]),
                rng.uniform(60, 75),
            ),
            "medium": HAZE,
        },
        "air": {
            "type": "cube",
            "to_world": t().translate([0, H / 2, 0]).scale([W - GAP, H / 2 - GAP, D - GAP]),
            "bsdf": {"type": "null"},
            "interior": HAZE,
        },
        **room(rng, W, D, H, wall),
        **window(rng, wall),
        "sun": {
            "type": "directional",
            "direction": (sun / np.linalg.norm(sun)).tolist(),
            "irradiance": rgb(np.array([1.0, 0.95, 0.85]) * rng.uniform(5, 15)),
        },
        "sky": {"type": "constant", "radiance": rgb(np.array([0.5, 0.7, 1.0]) * rng.uniform(0.1, 0.6))},
    }
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="shafts",
        build=build,
        algorithms=VOLPATH_FAMILY,
        max_depth=8,
        medium=True,
        summary="sun through a mullioned window into a hazy room, beams in the air: exposure 2^U(-3,3)",
    )
)
