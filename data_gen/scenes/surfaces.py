"""Surfaces no other family shows: mirrors, thin glass panes, principled, bumpy, cut-out and blended materials.

Objects and standing panels on a floor, lit by one large soft box and a dim sky. Each object draws
one of Mitsuba's surface models that the other families leave out: the ``principled`` BSDF
(metallic, roughness, clear coat, sheen drawn per object), smooth mirrors (``conductor``), thin
window glass (``thindielectric`` panes), a bump-mapped diffuse or rough plastic (``bumpmap`` over
smooth noise: fine shading detail that is not in the texture), a cut-out panel (``mask`` with a
thresholded noise opacity: holes the light falls through) and a blend of diffuse and metal
(``blendbsdf`` weighted by noise). The floor is bumpy or principled. Exposure varies by 2^U(-3,3)
per variant.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes import SceneSpec, register_scene
from data_gen.scenes._exposure import exposure, scale_emitters
from data_gen.scenes._parts import (
    METALS,
    PATH_FAMILY,
    SHAPES,
    area_light,
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

SURFACES = ("principled", "mirror", "thin_glass", "bumped", "cutout", "blend")
PANELS = ("thin_glass", "cutout")  # drawn as standing panels; the others as balls, blocks and pillars


def _grey_noise(rng: np.random.Generator, tiles: float) -> dict:
    """Smooth value noise in one channel (a height, an opacity or a weight), ``tiles`` repeats per uv unit."""
    import mitsuba as mi

    texture = noise_bitmap(rng)
    grey = np.asarray(texture["bitmap"], dtype=np.float32).mean(axis=2, keepdims=True)
    grey = (grey - grey.min()) / max(float(grey.max() - grey.min()), 1e-6)
    return {**texture, "bitmap": mi.Bitmap(np.ascontiguousarray(grey)), "to_uv": transform().scale([tiles, tiles, 1])}


def surface(rng: np.random.Generator, kind: str) -> dict:
    """A BSDF of surface model ``kind`` (one of :data:`SURFACES`), its parameters drawn from ``rng``."""
    if kind == "principled":
        return {
            "type": "principled",
            "base_color": rgb(random_color(rng, 0.1, 0.9)),
            "metallic": float(rng.uniform(0, 1)),
            "roughness": float(rng.uniform(0.05, 0.8)),
            "clearcoat": float(rng.uniform(0, 1)) if rng.uniform() < 0.5 else 0.0,
            "sheen": float(rng.uniform(0, 1)) if rng.uniform() < 0.3 else 0.0,
        }
    if kind == "mirror":
        return {"type": "conductor", "material": str(rng.choice(METALS))}
    if kind == "thin_glass":
        return {"type": "thindielectric", "int_ior": float(rng.uniform(1.4, 1.6))}
    if kind == "bumped":
        return {
            "type": "bumpmap",
            "arbitrary": _grey_noise(rng, float(rng.uniform(2, 6))),
            "scale": float(rng.uniform(0.2, 1.0)),
            "bsdf": random_material(rng, ("diffuse", "roughplastic")),
        }
    if kind == "cutout":
        import mitsuba as mi

        holes = _grey_noise(rng, float(rng.uniform(1, 3)))
        level = float(rng.uniform(0.35, 0.6))
        opaque = (np.asarray(holes["bitmap"], dtype=np.float32) > level).astype(np.float32)
        return {
            "type": "mask",
            "opacity": {**holes, "bitmap": mi.Bitmap(np.ascontiguousarray(opaque)), "filter_type": "nearest"},
            "bsdf": diffuse(random_color(rng, 0.2, 0.9)),
        }
    if kind == "blend":
        return {
            "type": "blendbsdf",
            "weight": _grey_noise(rng, float(rng.uniform(1, 4))),
            "bsdf_0": random_material(rng, ("diffuse",)),
            "bsdf_1": random_material(rng, ("roughconductor",)),
        }
    raise ValueError(f"unknown surface {kind!r}; known: {', '.join(SURFACES)}")


def _panel(rng: np.random.Generator, bsdf: dict) -> dict:
    """A standing rectangle (half-width and half-height 0.3-0.7) turned about the vertical axis."""
    w, h = float(rng.uniform(0.3, 0.7)), float(rng.uniform(0.3, 0.7))
    at = [float(rng.uniform(-1.4, 1.4)), h, float(rng.uniform(-1.6, 0.4))]
    return rectangle(transform().translate(at).rotate([0, 1, 0], float(rng.uniform(-60, 60))).scale([w, h, 1]), bsdf)


def build(rng: np.random.Generator) -> dict:
    gain = exposure(rng)
    t = transform
    box = jitter(rng, [0, 2.6, 0.5], [1.8, 0.3, 1.0])
    scene = {
        "type": "scene",
        "sensor": camera(
            jitter(rng, [0, 1.3, 3.2], [0.8, 0.3, 0.3]),
            jitter(rng, [0, 0.5, -0.6], [0.3, 0.2, 0.3]),
            rng.uniform(45, 60),
        ),
        "floor": floor(0.0, 4.0, surface(rng, str(rng.choice(("bumped", "principled"))))),
        "back": rectangle(t().translate([0, 2.0, -2.5]).scale([4, 2, 1]), diffuse(random_color(rng, 0.3, 0.9))),
        "softbox": rectangle(
            t()
            .look_at(
                origin=box,
                target=jitter(rng, [0, 0, -0.5], [0.5, 0, 0.5]),
                up=[0, 0, -1] if abs(box[0]) < 0.5 else [0, 1, 0],
            )
            .scale(float(rng.uniform(0.4, 1.0))),
            emitter=area_light(np.asarray(random_color(rng, 0.8, 1.0)) * rng.uniform(4, 10)),
        ),
        "sky": {"type": "constant", "radiance": rgb(np.asarray(random_color(rng, 0.5, 1.0)) * rng.uniform(0.02, 0.15))},
    }
    for k in range(int(rng.integers(4, 9))):
        kind = SURFACES[int(rng.integers(len(SURFACES)))]
        bsdf = surface(rng, kind)
        if kind in PANELS:
            scene[f"object{k}"] = _panel(rng, bsdf)
            continue
        shape = SHAPES[int(rng.integers(len(SHAPES)))]
        x, z, size = float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-1.8, 0.6)), float(rng.uniform(0.15, 0.4))
        turn, height = float(rng.uniform(0, 90)), float(rng.uniform(0.4, 1.2))
        scene[f"object{k}"] = standing_shape(shape, x, z, size if shape != "cylinder" else size / 2, bsdf, turn, height)
    return scale_emitters(scene, gain)


SPEC = register_scene(
    SceneSpec(
        name="surfaces",
        build=build,
        algorithms=PATH_FAMILY,
        max_depth=10,
        summary="mirrors, thin glass, principled, bump-mapped, cut-out and blended surfaces; exposure 2^U(-3,3)",
        # rungs above these failed the v2 checks (docs/results/dataset_v2.md)
        rung_limits={"path_ldsampler": 256, "path_multijitter": 256},
    )
)
