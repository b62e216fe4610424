"""Foliage: bushes of small leaves under a canopy of large ones, in dappled sun and sky.

Thousands of overlapping leaves a few pixels across, each a folded, notched polygon coloured on its
own, and the sun broken by the canopy into a ground of sharp-edged spots: clutter that lighting cuts
into small bright and dark patches, which a render's noise must not be confused with. A third of the
variants look up through the canopy against the sky (backlit leaves, a sky that clips). Real
triangles, not alpha cut-outs: Mitsuba's shadow rays treat a ``mask`` BSDF's transparent texels as
opaque, so cut-out cards would shadow the ground with their whole rectangle. Held back at stops
79-81 (no shipped network learnt it); the default learnt it at stop 82 and ``v2`` renders it since.
Exposure varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._meshes import VERTEX_COLOR, leaf_outline, leaves_mesh, rods_mesh
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

GREEN = np.array([0.10, 0.30, 0.05])
AUTUMN = np.array([0.45, 0.22, 0.04])


def leaf_colors(rng: np.random.Generator, count: int, base: np.ndarray) -> np.ndarray:
    """``(count, 3)`` reflectances about ``base``: each leaf brighter or darker and its hue a little off."""
    tone = rng.uniform(0.5, 1.6, (count, 1)) * rng.uniform(0.8, 1.25, (count, 3))
    return np.clip(base[None] * tone, 0.01, 0.9)


def _random_dirs(rng: np.random.Generator, count: int) -> np.ndarray:
    d = rng.normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _leaf_bsdf(rng: np.random.Generator) -> dict:
    """Two-sided (a leaf is seen from both faces), diffuse or waxy, reflectance per leaf from its vertices.

    Waxy: a blend of the diffuse leaf and a little rough white gloss (``roughplastic`` cannot read a
    per-vertex colour: it needs the texture's mean).
    """
    matte = {"type": "diffuse", "reflectance": VERTEX_COLOR}
    if rng.uniform() < 0.6:
        return {"type": "twosided", "bsdf": matte}
    gloss = {"type": "roughconductor", "material": "none", "alpha": float(rng.uniform(0.1, 0.4))}
    waxy = {"type": "blendbsdf", "weight": float(rng.uniform(0.05, 0.2)), "bsdf_0": matte, "bsdf_1": gloss}
    return {"type": "twosided", "bsdf": waxy}


def canopy(rng: np.random.Generator, name: str, height: float, count: int, base: np.ndarray):
    """Large leaves over a 6 x 6 square at about ``height``, mostly facing up: the sun's dappling screen."""
    bases = np.stack([rng.uniform(-3, 3, count), height + rng.uniform(-0.3, 0.3, count), rng.uniform(-3, 3, count)], 1)
    normals = np.array([[0.0, 1.0, 0.0]]) + 0.6 * _random_dirs(rng, count)
    outline = leaf_outline(1.0, rng.uniform(0.25, 0.45), int(rng.integers(0, 6)))
    return leaves_mesh(
        name,
        bases,
        normals,
        _random_dirs(rng, count),
        outline,
        rng.uniform(0.15, 0.35, count),
        _leaf_bsdf(rng),
        fold=rng.uniform(0.1, 0.5),
        colors=leaf_colors(rng, count, base),
    )


def bush(rng: np.random.Generator, name: str, centre, radius: float, count: int, base: np.ndarray) -> list:
    """Small leaves in a ball of ``radius`` standing on the ground at ``centre`` (x, z), facing outwards, on stems."""
    middle = np.array([centre[0], 0.8 * radius, centre[1]])
    where = _random_dirs(rng, count) * radius * np.cbrt(rng.uniform(0.2, 1, (count, 1)))
    bases = middle + where
    bases[:, 1] = np.maximum(bases[:, 1], 0.02)
    outline = leaf_outline(1.0, rng.uniform(0.2, 0.5), int(rng.integers(0, 5)))
    leaves = leaves_mesh(
        name,
        bases,
        where + 0.8 * radius * _random_dirs(rng, count),
        _random_dirs(rng, count),
        outline,
        rng.uniform(0.04, 0.12, count),
        _leaf_bsdf(rng),
        fold=rng.uniform(0.1, 0.5),
        colors=leaf_colors(rng, count, base),
    )
    stems = int(rng.integers(3, 7))
    feet = (
        middle + np.stack([rng.uniform(-0.2, 0.2, stems), np.zeros(stems), rng.uniform(-0.2, 0.2, stems)], 1) * radius
    )
    feet[:, 1] = 0.0
    tops = middle + _random_dirs(rng, stems) * 0.6 * radius
    tops[:, 1] = np.abs(tops[:, 1] - middle[1]) + middle[1]  # stems rise
    bark = diffuse(np.array([0.25, 0.17, 0.1]) * rng.uniform(0.5, 1.5))
    return [leaves, rods_mesh(f"{name}_stems", feet, tops, radius * rng.uniform(0.03, 0.06), bark, sides=5)]


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    base = GREEN if rng.uniform() < 0.7 else AUTUMN
    height = rng.uniform(1.8, 2.6)
    looking_up = rng.uniform() < 1 / 3
    if looking_up:  # backlit leaves against a sky that clips
        sensor = camera(
            jitter(rng, [0, 0.6, 1.6], [0.5, 0.2, 0.3]),
            jitter(rng, [0, height, -0.8], [0.5, 0.2, 0.5]),
            rng.uniform(45, 65),
        )
        sky = rng.uniform(0.6, 1.5)
    else:
        sensor = camera(
            jitter(rng, [0, 0.9, 2.2], [0.6, 0.3, 0.3]), jitter(rng, [0, 0.2, 0], [0.2, 0.1, 0.2]), rng.uniform(35, 55)
        )
        sky = rng.uniform(0.1, 0.5)
    scene = {
        "type": "scene",
        "sensor": sensor,
        "ground": floor(0.0, 6.0, textured(photo_texture(rng, str(rng.choice(["grass", "gravel"])), tiles=6))),
        "sun": {
            "type": "directional",
            "direction": jitter(rng, [0.3, -1.0, -0.4], [0.5, 0.2, 0.5]),
            "irradiance": rgb(np.array([1.0, 0.95, 0.85]) * rng.uniform(2, 5)),
        },
        "sky": {"type": "constant", "radiance": rgb(np.array([0.5, 0.7, 1.0]) * sky)},
        "canopy": canopy(rng, "canopy", height, int(rng.integers(500, 1500)), base),
    }
    for k in range(int(rng.integers(1, 4))):
        centre = jitter(rng, [0, 0], [1.0, 1.0])
        parts = bush(rng, f"bush{k}", centre, rng.uniform(0.25, 0.6), int(rng.integers(150, 600)), base)
        scene.update({f"bush{k}_{j}": part for j, part in enumerate(parts)})
    scene["back"] = rectangle(
        transform().translate([0, 1.5, -3.0]).scale([6, 1.5, 1]), diffuse(random_color(rng, 0.2, 0.6))
    )
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="foliage",
        build=build,
        algorithms=(*PATH_FAMILY, "ptracer_independent"),
        max_depth=6,
        summary="bushes of small leaves under a canopy in dappled sun, a third looking up: exposure 2^U(-3,3)",
    )
)
