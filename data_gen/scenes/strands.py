"""Strands: tufts of grass or hair, hundreds of bent fibres standing on a ground, in sun and sky.

Fibres a fraction of a pixel wide, dense enough to overlap, with their own sharp shadows on the
ground: organic sub-pixel detail, curved and crowded where ``fine_geometry``'s rods are straight and
spaced. Held back at stops 79-81 (no shipped network learnt it); the default learnt it at stop 82
and ``v2`` renders it since. Exposure varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._meshes import rods_mesh
from data_gen.scenes._parts import (
    PATH_FAMILY,
    camera,
    diffuse,
    floor,
    jitter,
    random_color,
    rectangle,
    rgb,
    textured,
    transform,
)
from data_gen.scenes._photos import photo_texture

CONTROL_POINTS = 5  # per fibre: four straight segments through a bent stalk


def fibres(rng: np.random.Generator, count: int, spread: float, height: float, radius: float) -> np.ndarray:
    """Control points ``(count, CONTROL_POINTS, 4)`` (x, y, z, radius) of fibres rooted in a disc of ``spread``.

    Each rises to about ``height`` (±40 %), leans along a random direction by up to half its height with a
    quadratic bend, and thins from ``radius`` at its root to a fifth of it at its tip.
    """
    r = spread * np.sqrt(rng.uniform(0, 1, count))
    a = rng.uniform(0, 2 * np.pi, count)
    roots = np.stack([r * np.cos(a), np.zeros(count), r * np.sin(a)], 1)
    tall = height * rng.uniform(0.6, 1.4, count)
    lean_dir = rng.uniform(0, 2 * np.pi, count)
    lean = tall * rng.uniform(0, 0.5, count)
    t = np.linspace(0, 1, CONTROL_POINTS)[None, :]
    pts = np.empty((count, CONTROL_POINTS, 4))
    pts[..., 0] = roots[:, :1] + (lean * np.cos(lean_dir))[:, None] * t**2
    pts[..., 1] = tall[:, None] * t
    pts[..., 2] = roots[:, 2:] + (lean * np.sin(lean_dir))[:, None] * t**2
    pts[..., 3] = radius * (1 - 0.8 * t)
    return pts


def _tuft(rng: np.random.Generator, name: str, centre, count: int, height: float, radius: float) -> list:
    """One tuft of fibres of one colour (green to straw grass, dark to fair hair): a mesh per segment of the stalks.

    Segment ``k`` of every fibre is a thin prism from control point ``k`` to ``k + 1`` whose radius is the mean of
    the two, so the fibres taper from root to tip.
    """
    pts = fibres(rng, count, rng.uniform(0.4, 1.0), height, radius)
    pts[..., 0] += centre[0]
    pts[..., 2] += centre[1]
    colour = random_color(rng, 0.1, 0.8)
    glossy = {"type": "roughplastic", "diffuse_reflectance": rgb(colour)}
    bsdf = diffuse(colour) if rng.uniform() < 0.6 else glossy
    return [
        rods_mesh(f"{name}_{k}", pts[:, k, :3], pts[:, k + 1, :3], float(pts[0, k : k + 2, 3].mean()), bsdf, sides=4)
        for k in range(CONTROL_POINTS - 1)
    ]


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    radius = rng.uniform(0.002, 0.008)  # at 64-128 pixels across ~3 units: a tenth to a third of a pixel
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [0, 0.8, 2.2], [0.6, 0.3, 0.3]),
            jitter(rng, [0, 0.15, 0], [0.2, 0.1, 0.2]),
            rng.uniform(35, 55),
        ),
        "ground": floor(0.0, 6.0, textured(photo_texture(rng, str(rng.choice(["grass", "gravel"])), tiles=6))),
        "sun": {
            "type": "directional",
            "direction": jitter(rng, [0.3, -1.0, -0.4], [0.6, 0.2, 0.6]),
            "irradiance": rgb(np.array([1.0, 0.95, 0.85]) * rng.uniform(2, 5)),
        },
        "sky": {"type": "constant", "radiance": rgb(np.array([0.5, 0.7, 1.0]) * rng.uniform(0.1, 0.5))},
    }
    for k in range(int(rng.integers(2, 6))):
        centre = jitter(rng, [0, 0], [1.0, 1.0])
        meshes = _tuft(rng, f"tuft{k}", centre, int(rng.integers(300, 1000)), rng.uniform(0.2, 0.6), radius)
        scene.update({f"tuft{k}_{j}": mesh for j, mesh in enumerate(meshes)})
    if rng.uniform() < 0.5:
        scene["stone"] = {
            "type": "sphere",
            "center": jitter(rng, [0.6, 0.12, 0.4], [0.4, 0, 0.4]),
            "radius": 0.15,
            "bsdf": diffuse(random_color(rng, 0.3, 0.7)),
        }
    scene["back"] = rectangle(t().translate([0, 1.5, -3.0]).scale([6, 1.5, 1]), diffuse(random_color(rng, 0.2, 0.6)))
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="strands",
        build=build,
        algorithms=(*PATH_FAMILY, "ptracer_independent"),
        max_depth=6,
        summary="tufts of bent, tapering fibres (grass, hair) in sun and sky: sub-pixel detail, exposure 2^U(-3,3)",
    )
)
