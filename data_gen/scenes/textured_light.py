"""Light that carries a pattern: a projector throwing a picture, a lit screen, sun through slats.

The other families light with uniform emitters; here the light itself is textured, so the
illumination has edges and detail that no surface texture explains. Each variant draws one to
three of: a ``projector`` throwing a photograph or a noise pattern onto the walls and objects; a
``screen``, a rectangle whose area light shows a photograph (seen or just off the frame); a sun
(``directional``) shining through a slatted roof whose striped shadows fall across the room. A
dim sky fills the rest. Exposure varies by 2^U(-3,3) per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters, scaled
from data_gen.scenes._parts import (
    PATH_FAMILY,
    SHAPES,
    camera,
    diffuse,
    floor,
    jitter,
    noise_bitmap,
    random_color,
    random_material,
    rectangle,
    rgb,
    standing_shape,
    transform,
)
from data_gen.scenes._photos import PHOTOS, photo_texture

LIGHTS = ("projector", "screen", "sun")


def _pattern(rng: np.random.Generator) -> dict:
    """A photograph (two times in three) or smooth noise, as a linear RGB bitmap texture."""
    if rng.uniform() < 2 / 3:
        return photo_texture(rng, str(rng.choice(PHOTOS)))
    return noise_bitmap(rng)


def _projector(rng: np.random.Generator) -> dict:
    return {
        "type": "projector",
        "irradiance": _pattern(rng),
        "fov": float(rng.uniform(20, 45)),
        "scale": float(rng.uniform(15, 30)),
        "to_world": transform().look_at(
            origin=jitter(rng, [0, 1.6, 2.0], [1.5, 0.6, 0.5]),
            target=jitter(rng, [0, 0.8, -2.0], [1.0, 0.5, 0.2]),
            up=[0, 1, 0],
        ),
    }


def _screen(rng: np.random.Generator) -> dict:
    """A 4:3 panel on the back or a side wall, its radiance a photograph."""
    t = transform()
    width = float(rng.uniform(0.5, 1.0))
    if rng.uniform() < 0.5:  # on the back wall, facing the camera
        t = t.translate(jitter(rng, [0, 1.3, -2.45], [1.2, 0.4, 0.0]))
    else:  # on the left or right wall, facing into the room
        side = float(rng.choice([-1.0, 1.0]))
        t = t.translate([side * 2.45, float(rng.uniform(0.9, 1.6)), float(rng.uniform(-1.8, 0.0))]).rotate(
            [0, 1, 0], -90 * side
        )
    radiance = scaled(_pattern(rng), float(rng.uniform(2, 6)))
    return rectangle(t.scale([width, 0.75 * width, 1]), emitter={"type": "area", "radiance": radiance})


def _slats(rng: np.random.Generator, scene: dict) -> None:
    """A roof of parallel slats over the room and a sun shining down through it."""
    count, gap = int(rng.integers(5, 10)), float(rng.uniform(0.15, 0.4))
    turn = float(rng.uniform(0, 180))
    for k in range(count):
        offset = (k - (count - 1) / 2) * 2 * gap
        scene[f"slat{k}"] = {
            "type": "cube",
            "to_world": transform()
            .rotate([0, 1, 0], turn)
            .translate([offset, 3.0, 0])
            .scale([gap * float(rng.uniform(0.4, 0.7)), 0.03, 3.5]),
            "bsdf": diffuse(random_color(rng, 0.2, 0.6)),
        }
    elevation, azimuth = np.radians(rng.uniform(35, 70)), np.radians(rng.uniform(0, 360))
    direction = [
        float(np.cos(elevation) * np.cos(azimuth)),
        -float(np.sin(elevation)),
        float(np.cos(elevation) * np.sin(azimuth)),
    ]
    scene["sun"] = {
        "type": "directional",
        "direction": direction,
        "irradiance": rgb(np.asarray(random_color(rng, 0.8, 1.0)) * rng.uniform(2, 5)),
    }


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [0, 1.3, 3.2], [0.8, 0.3, 0.3]),
            jitter(rng, [0, 0.8, -1.0], [0.4, 0.2, 0.3]),
            rng.uniform(45, 65),
        ),
        "floor": floor(0.0, 2.5, random_material(rng, ("diffuse", "roughplastic"))),
        "back": rectangle(t().translate([0, 1.5, -2.5]).scale([2.5, 1.5, 1]), diffuse(random_color(rng, 0.5, 0.9))),
        "left": rectangle(
            t().translate([-2.5, 1.5, 0]).rotate([0, 1, 0], 90).scale([2.5, 1.5, 1]),
            diffuse(random_color(rng, 0.4, 0.9)),
        ),
        "right": rectangle(
            t().translate([2.5, 1.5, 0]).rotate([0, 1, 0], -90).scale([2.5, 1.5, 1]),
            diffuse(random_color(rng, 0.4, 0.9)),
        ),
        "sky": {"type": "constant", "radiance": rgb(np.asarray(random_color(rng, 0.5, 1.0)) * rng.uniform(0.01, 0.1))},
    }
    lights = [LIGHTS[i] for i in sorted(rng.choice(len(LIGHTS), size=int(rng.integers(1, 4)), replace=False))]
    for k, kind in enumerate(lights):
        if kind == "projector":
            scene[f"projector{k}"] = _projector(rng)
        elif kind == "screen":
            scene[f"screen{k}"] = _screen(rng)
        else:
            _slats(rng, scene)
    for k in range(int(rng.integers(2, 6))):
        kind = SHAPES[int(rng.integers(len(SHAPES)))]
        x, z, size = float(rng.uniform(-1.6, 1.6)), float(rng.uniform(-2.0, 0.5)), float(rng.uniform(0.15, 0.4))
        bsdf = random_material(rng, ("diffuse", "plastic", "roughplastic", "roughconductor"))
        turn, height = float(rng.uniform(0, 90)), float(rng.uniform(0.4, 1.4))
        scene[f"object{k}"] = standing_shape(kind, x, z, size if kind != "cylinder" else size / 2, bsdf, turn, height)
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="textured_light",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=8,
        summary="light with a pattern: a projector, a screen showing a photo, sun through slats; exposure 2^U(-3,3)",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 64},
    )
)
