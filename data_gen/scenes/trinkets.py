"""Trinkets: a tray or floor strewn with thousands of small glossy beads, polished coins and metal pins.

Dense detail that sparkles: every bead is a smooth, glossy sphere a pixel or two across with a
highlight smaller than a pixel, every coin a polished disc that catches a light or does not, every
pin a thin metal rod. The converged image is a field of isolated bright points on coloured dots,
which a scorer can take for fireflies; a render's noise must not be confused with them, nor they
with noise. Lit by one to three small lamps over a dim room, or by the sun and the sky; the camera
looks straight down or along the surface. Exposure varies by 2^U(-3, 3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._meshes import VERTEX_COLOR, mesh_from_arrays, prism_faces, rods_mesh
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
    textured,
    transform,
)
from data_gen.scenes._photos import photo_texture
from data_gen.scenes.pebbles import ICOSA_FACES, ICOSA_VERTICES


def icosphere() -> tuple[np.ndarray, np.ndarray]:
    """A unit sphere: the icosahedron with every face split in four (42 vertices, 80 faces), wound outwards."""
    vertices = [tuple(v) for v in ICOSA_VERTICES]
    index = {v: i for i, v in enumerate(vertices)}
    faces = []

    def middle(a: int, b: int) -> int:
        m = np.asarray(vertices[a]) + np.asarray(vertices[b])
        key = tuple(m / np.linalg.norm(m))
        if key not in index:
            index[key] = len(vertices)
            vertices.append(key)
        return index[key]

    for a, b, c in ICOSA_FACES:
        ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
        faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    return np.asarray(vertices), np.asarray(faces)


def beads_mesh(name: str, rng: np.random.Generator, centres: np.ndarray, radii: np.ndarray, bsdf: dict):
    """Smooth spheres (vertex normals) of ``radii`` at ``centres``, each coloured on its own, one mesh."""
    unit, faces = icosphere()
    pos = centres[:, None] + unit[None] * radii[:, None, None]
    normals = np.broadcast_to(unit, pos.shape)
    colors = np.repeat(bead_colors(rng, len(centres)), len(unit), axis=0)
    all_faces = (faces[None] + len(unit) * np.arange(len(centres))[:, None, None]).reshape(-1, 3)
    return mesh_from_arrays(name, pos.reshape(-1, 3), all_faces, bsdf, normals=normals.reshape(-1, 3), colors=colors)


def bead_colors(rng: np.random.Generator, count: int) -> np.ndarray:
    """``(count, 3)`` reflectances from a palette of two to five saturated colours, each bead a little off its own."""
    palette = np.asarray([random_color(rng, 0.05, 0.85) for _ in range(int(rng.integers(2, 6)))])
    return np.clip(palette[rng.integers(0, len(palette), count)] * rng.uniform(0.8, 1.2, (count, 3)), 0.02, 0.9)


def coins_mesh(
    name: str, rng: np.random.Generator, centres: np.ndarray, radii: np.ndarray, bsdf: dict, sides: int = 10
):
    """Flat discs (closed ``sides``-gonal prisms, ``radius`` / 6 thick) lying on the surface, each a little tilted."""
    count = len(centres)
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([np.cos(ang), np.zeros(sides), np.sin(ang)], 1)  # (S, 3), in the plane y = 0
    thick = np.array([0.0, 1.0, 0.0])
    unit = np.concatenate([ring, ring + thick * 0.16])  # a disc of radius 1, 0.16 thick
    tilt = rng.normal(0.0, 0.12, (count, 2))  # small rotations about x and z
    cx, sx, cz, sz = np.cos(tilt[:, 0]), np.sin(tilt[:, 0]), np.cos(tilt[:, 1]), np.sin(tilt[:, 1])
    rot = np.zeros((count, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1] = cz, -sz
    rot[:, 1, 0], rot[:, 1, 1], rot[:, 1, 2] = sz * cx, cz * cx, -sx
    rot[:, 2, 0], rot[:, 2, 1], rot[:, 2, 2] = sz * sx, cz * sx, cx
    pos = np.einsum("nij,vj->nvi", rot, unit) * radii[:, None, None] + centres[:, None]
    # the ring runs from +x towards +z: clockwise seen from above (+y), the end it is moved to
    return mesh_from_arrays(name, pos.reshape(-1, 3), prism_faces(sides, count, clockwise=True), bsdf)


def _scatter(rng: np.random.Generator, count: int, half: float) -> np.ndarray:
    """``(count, 2)`` positions in ``[-half, half]^2``, clumped: a third uniform, the rest around a few heaps."""
    heaps = rng.uniform(-half * 0.7, half * 0.7, (int(rng.integers(2, 6)), 2))
    spread = rng.uniform(0.15, 0.5) * half
    around = heaps[rng.integers(0, len(heaps), count)] + rng.normal(0.0, spread, (count, 2))
    where = np.where(rng.uniform(size=(count, 1)) < 0.33, rng.uniform(-half, half, (count, 2)), around)
    return np.clip(where, -half, half)


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    half = float(rng.uniform(0.8, 1.6))
    size = rng.uniform(0.012, 0.035) * half  # the typical bead radius of this variant
    if rng.uniform() < 0.35:  # straight down onto the tray
        sensor = camera(jitter(rng, [0, 1.1 * half, 0.05], [0.2, 0.3, 0.05]), jitter(rng, [0, 0, 0], [0.2, 0, 0.2]), 45)
    else:  # along the surface, the far trinkets under a pixel
        eye = jitter(rng, [0, 0.75 * half, 1.1 * half], [0.3 * half, 0.15 * half, 0.1])
        sensor = camera(eye, jitter(rng, [0, 0, -0.1 * half], [0.2, 0.02, 0.2]), rng.uniform(30, 45))

    beads = int(rng.integers(2000, 7000))
    xz = _scatter(rng, beads, half)
    radii = size * rng.lognormal(0.0, 0.25, beads).clip(0.5, 2.0)
    bead_bsdf = {  # coloured plastic under a sharp white gloss (Mitsuba's plastic BSDFs take no per-vertex colour)
        "type": "blendbsdf",
        "weight": float(rng.uniform(0.08, 0.3)),
        "bsdf_0": {"type": "diffuse", "reflectance": VERTEX_COLOR},
        "bsdf_1": {"type": "roughconductor", "material": "none", "alpha": float(rng.uniform(0.02, 0.12))},
    }
    ground = rng.uniform()
    if ground < 0.4:
        under = diffuse(random_color(rng, 0.02, 0.2))  # dark cloth
    elif ground < 0.7:
        under = textured(photo_texture(rng, str(rng.choice(["brick", "gravel", "coffee", "page"])), tiles=4))
    else:
        under = diffuse(random_color(rng, 0.3, 0.8))
    scene = {
        "type": "scene",
        "sensor": sensor,
        "ground": floor(0.0, 2 * half + 6, under),
        "beads": beads_mesh("beads", rng, np.stack([xz[:, 0], radii, xz[:, 1]], 1), radii, bead_bsdf),
    }
    coins = int(rng.integers(100, 1200))
    cxz = _scatter(rng, coins, half)
    cr = size * rng.uniform(1.5, 3.0) * rng.uniform(0.8, 1.2, coins)
    scene["coins"] = coins_mesh(
        "coins",
        rng,
        np.stack([cxz[:, 0], np.full(coins, 0.002), cxz[:, 1]], 1),
        cr,
        {"type": "roughconductor", "material": str(rng.choice(METALS)), "alpha": float(rng.uniform(0.03, 0.25))},
    )
    pins = int(rng.integers(0, 600))
    if pins:
        start = _scatter(rng, pins, half)
        turn = rng.uniform(0, 2 * np.pi, pins)
        length = size * rng.uniform(4, 10) * rng.uniform(0.8, 1.2, pins)
        lift = size * 0.3
        starts = np.stack([start[:, 0], np.full(pins, lift), start[:, 1]], 1)
        ends = starts + np.stack([np.cos(turn) * length, np.zeros(pins), np.sin(turn) * length], 1)
        scene["pins"] = rods_mesh(
            "pins", starts, ends, size * 0.25, {"type": "roughconductor", "material": "Cr", "alpha": 0.08}, sides=5
        )

    if rng.uniform() < 0.6:  # small lamps over a dim room
        scene["room"] = {"type": "constant", "radiance": rgb([rng.uniform(0.01, 0.15)] * 3)}
        for i in range(int(rng.integers(1, 4))):
            where = jitter(rng, [0, 1.6 * half, 0], [1.2 * half, 0.6 * half, 1.2 * half])
            lamp = rng.uniform(0.05, 0.25) * half
            power = rng.uniform(8, 30) / max(lamp / half, 0.1) ** 2 * 0.05
            scene[f"lamp{i}"] = rectangle(
                transform().translate(where).rotate([1, 0, 0], 90).scale(lamp),
                emitter=area_light(np.array([1.0, rng.uniform(0.85, 1.0), rng.uniform(0.7, 1.0)]) * power),
            )
    else:  # sun and sky
        scene["sky"] = {"type": "constant", "radiance": rgb(np.array([0.55, 0.7, 1.0]) * rng.uniform(0.2, 0.8))}
        scene["sun"] = {
            "type": "directional",
            "direction": jitter(rng, [0.3, -1.0, -0.4], [0.5, 0.3, 0.5]),
            "irradiance": rgb(np.array([1.0, 0.93, 0.8]) * rng.uniform(2, 5)),
        }
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="trinkets",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=6,
        summary="thousands of glossy beads, polished coins and pins under small lamps or the sun: exposure 2^U(-3,3)",
    )
)
