"""Pebbles: a beach or path of thousands of small stones, each a few pixels across or less, in sun and sky.

Dense geometric detail that is neither a texture nor thin: every stone is a flat-shaded, lumpy
solid with a colour of its own, lit on one side and shadowing its neighbours, so the converged
image is a field of small bright and dark facets that a render's noise must not be confused with.
The camera looks along the ground (near stones several pixels wide, far ones under a pixel) or
straight down onto it; the sun is low (long shadows), high, or hidden behind cloud (sky only).
Exposure varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._meshes import VERTEX_COLOR, mesh_from_arrays
from data_gen.scenes._parts import PATH_FAMILY, camera, floor, jitter, rgb, textured
from data_gen.scenes._photos import photo_texture

# A unit icosahedron: 12 vertices, 20 faces, wound outwards.
_P = (1 + 5**0.5) / 2
ICOSA_VERTICES = np.array(
    [[-1, _P, 0], [1, _P, 0], [-1, -_P, 0], [1, -_P, 0], [0, -1, _P], [0, 1, _P],
     [0, -1, -_P], [0, 1, -_P], [_P, 0, -1], [_P, 0, 1], [-_P, 0, -1], [-_P, 0, 1]],
    dtype=np.float64,
) / np.sqrt(1 + _P**2)  # fmt: skip
ICOSA_FACES = np.array(
    [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
     [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
     [8, 6, 7], [9, 8, 1]],
)  # fmt: skip

# Stone colours: grey granite, sandstone, slate, white quartz.
STONES = np.array([[0.35, 0.34, 0.32], [0.50, 0.38, 0.24], [0.16, 0.17, 0.19], [0.70, 0.68, 0.64]])


def _rotations(rng: np.random.Generator, count: int) -> np.ndarray:
    """``(count, 3, 3)`` random rotations (QR of Gaussian matrices, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(count, 3, 3)))
    return q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]


def stone_colors(rng: np.random.Generator, count: int) -> np.ndarray:
    """``(count, 3)`` reflectances: a mix of two or three of :data:`STONES`, each stone a little off its kind."""
    kinds = rng.choice(len(STONES), size=int(rng.integers(2, 4)), replace=False)
    base = STONES[rng.choice(kinds, size=count)]
    tone = rng.uniform(0.6, 1.4, (count, 1)) * rng.uniform(0.9, 1.1, (count, 3))
    return np.clip(base * tone, 0.02, 0.9)


def stones_mesh(name: str, rng: np.random.Generator, count: int, half: float, sizes, bsdf: dict):
    """``count`` lumpy stones (squashed, jittered icosahedra) on the ground over ``[-half, half]^2``, one mesh.

    Stone ``i`` is about ``sizes[i]`` across, flatter than wide, sunk a third into the ground, and coloured
    on its own (:data:`VERTEX_COLOR`); flat shaded, so each facet shows.
    """
    sizes = np.asarray(sizes, dtype=np.float64)
    shape = np.stack([np.ones(count), rng.uniform(0.35, 0.8, count), rng.uniform(0.6, 1.0, count)], 1)
    lumps = ICOSA_VERTICES[None] * rng.uniform(0.8, 1.2, (count, len(ICOSA_VERTICES), 1))
    local = lumps * shape[:, None] * (sizes[:, None, None] / 2)
    turn = rng.uniform(0, 2 * np.pi, count)  # about the vertical, so stones stay flat side down
    c, s = np.cos(turn), np.sin(turn)
    yaw = np.zeros((count, 3, 3))
    yaw[:, 0, 0], yaw[:, 0, 2], yaw[:, 1, 1], yaw[:, 2, 0], yaw[:, 2, 2] = c, s, 1, -s, c
    tilt = _rotations(rng, count) * 0.15 + np.eye(3) * 0.85  # a little off level (not a rotation, a lean)
    where = np.stack([rng.uniform(-half, half, count), sizes * shape[:, 1] * 0.15, rng.uniform(-half, half, count)], 1)
    pos = np.einsum("nij,nvj->nvi", yaw @ tilt, local) + where[:, None]
    faces = (ICOSA_FACES[None] + len(ICOSA_VERTICES) * np.arange(count)[:, None, None]).reshape(-1, 3)
    colors = np.repeat(stone_colors(rng, count), len(ICOSA_VERTICES), axis=0)
    return mesh_from_arrays(name, pos.reshape(-1, 3), faces, bsdf, colors=colors)


def _stone_bsdf(rng: np.random.Generator) -> dict:
    """Dry (diffuse) or wet (the diffuse stone under a little rough white gloss)."""
    matte = {"type": "diffuse", "reflectance": VERTEX_COLOR}
    if rng.uniform() < 0.65:
        return matte
    gloss = {"type": "roughconductor", "material": "none", "alpha": float(rng.uniform(0.05, 0.3))}
    return {"type": "blendbsdf", "weight": float(rng.uniform(0.05, 0.25)), "bsdf_0": matte, "bsdf_1": gloss}


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    half = 2.0
    if rng.uniform() < 0.3:  # straight down onto the stones
        sensor = camera(jitter(rng, [0, 1.2, 0.05], [0.3, 0.4, 0.05]), jitter(rng, [0, 0, 0], [0.2, 0, 0.2]), 40)
    else:  # along the ground, to a horizon of sub-pixel stones
        eye, target = jitter(rng, [0, 0.45, 1.9], [0.4, 0.25, 0.1]), jitter(rng, [0, 0.0, 0], [0.3, 0.05, 0.3])
        sensor = camera(eye, target, rng.uniform(35, 60))
    size = rng.uniform(0.03, 0.09) * rng.lognormal(0.0, 0.35)  # the typical stone of this variant
    count = int(rng.integers(6000, 14000))
    light = rng.uniform()
    if light < 0.25:  # overcast: the sky alone
        sun_strength, sky = 0.0, rng.uniform(0.8, 2.0)
    elif light < 0.6:  # low sun, long shadows
        sun_strength, sky = rng.uniform(3, 6), rng.uniform(0.1, 0.4)
    else:  # high sun
        sun_strength, sky = rng.uniform(2, 5), rng.uniform(0.2, 0.6)
    low = light < 0.6
    direction = jitter(rng, [0.6, -0.3, -0.6] if low else [0.2, -1.0, -0.3], [0.3, 0.08, 0.3])
    scene = {
        "type": "scene",
        "sensor": sensor,
        "ground": floor(0.0, 2 * half + 4, textured(photo_texture(rng, str(rng.choice(["gravel", "grass"])), tiles=8))),
        "stones": stones_mesh(
            "stones", rng, count, half, size * rng.lognormal(0.0, 0.4, count).clip(0.3, 3), _stone_bsdf(rng)
        ),
        "sky": {"type": "constant", "radiance": rgb(np.array([0.55, 0.7, 1.0]) * sky)},
    }
    if sun_strength > 0:
        scene["sun"] = {
            "type": "directional",
            "direction": direction,
            "irradiance": rgb(np.array([1.0, 0.93, 0.8]) * sun_strength),
        }
    if rng.uniform() < 0.4:  # a few large rocks among the stones
        rocks = int(rng.integers(3, 12))
        scene["rocks"] = stones_mesh("rocks", rng, rocks, half * 0.8, rng.uniform(0.2, 0.5, rocks), _stone_bsdf(rng))
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="pebbles",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=6,
        summary="thousands of small stones on the ground in sun, low sun or overcast sky: exposure 2^U(-3,3)",
    )
)
