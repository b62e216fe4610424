"""Building blocks shared by the scene modules: cameras, shapes, materials, generated textures.

Everything is made in code (no downloaded assets). Functions take the variant's
``numpy.random.Generator`` where they vary.
"""

from __future__ import annotations

import numpy as np

from data_gen.scenes._meshes import mesh_from_arrays


def _t():
    import mitsuba as mi

    return mi.ScalarTransform4f()


def camera(origin, target, fov: float, up=(0, 1, 0)) -> dict:
    """A perspective sensor looking from ``origin`` at ``target`` (film and sampler added later)."""
    return {
        "type": "perspective",
        "fov": float(fov),
        "to_world": _t().look_at(origin=list(map(float, origin)), target=list(map(float, target)), up=list(up)),
    }


def thin_lens(origin, target, fov: float, aperture_radius: float, focus_distance: float, up=(0, 1, 0)) -> dict:
    """A thin-lens sensor (depth of field): sharp at ``focus_distance``, lens radius ``aperture_radius``."""
    return {
        **camera(origin, target, fov, up),
        "type": "thinlens",
        "aperture_radius": float(aperture_radius),
        "focus_distance": float(focus_distance),
    }


def jitter(rng: np.random.Generator, base, scale) -> list[float]:
    """``base`` plus a uniform offset in ``[-scale, scale]`` per coordinate."""
    base = np.asarray(base, dtype=float)
    return (base + rng.uniform(-1, 1, base.shape) * np.asarray(scale, dtype=float)).tolist()


def rgb(value) -> dict:
    return {"type": "rgb", "value": [float(v) for v in value]}


def diffuse(color) -> dict:
    """A two-sided diffuse BSDF (so walls need no care about their orientation)."""
    return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": rgb(color)}}


def textured(texture: dict) -> dict:
    """A two-sided diffuse BSDF whose reflectance is ``texture``."""
    return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": texture}}


PATH_FAMILY = ("path_independent", "path_multijitter", "path_ldsampler")
VOLPATH_FAMILY = ("volpath_independent", "volpath_multijitter", "volpath_ldsampler")


def random_color(rng: np.random.Generator, lo: float = 0.15, hi: float = 0.85) -> list[float]:
    return rng.uniform(lo, hi, 3).tolist()


METALS = ("Au", "Cu", "Al", "Ag", "Cr")  # Mitsuba's conductor presets
MATERIALS = ("diffuse", "plastic", "roughplastic", "roughconductor", "dielectric")


def random_material(rng: np.random.Generator, kinds: tuple[str, ...] = MATERIALS) -> dict:
    """A BSDF of one of ``kinds`` drawn from ``rng``, its colour, roughness, metal or index of refraction drawn too."""
    kind = kinds[int(rng.integers(len(kinds)))]
    if kind == "diffuse":
        return diffuse(random_color(rng))
    if kind == "plastic":
        return {"type": "plastic", "diffuse_reflectance": rgb(random_color(rng))}
    if kind == "roughplastic":
        return {"type": kind, "diffuse_reflectance": rgb(random_color(rng)), "alpha": float(rng.uniform(0.05, 0.3))}
    if kind == "roughconductor":
        return {"type": kind, "material": str(rng.choice(METALS)), "alpha": float(rng.uniform(0.02, 0.3))}
    if kind == "dielectric":
        return {"type": kind, "int_ior": float(rng.uniform(1.3, 1.6))}
    raise ValueError(f"unknown material kind {kind!r}; known: {', '.join(MATERIALS)}")


SHAPES = ("sphere", "cube", "cylinder")


def standing_shape(kind: str, x: float, z: float, size: float, bsdf: dict, turn: float = 0.0, height: float = 0.0):
    """A ``sphere``/``cube``/``cylinder`` of half-width ``size`` resting on the floor y = 0 at ``(x, z)``.

    ``turn``: degrees about the vertical axis (cube, cylinder); ``height``: the cylinder's (it stands up).
    """
    if kind == "sphere":
        return {"type": "sphere", "center": [x, size, z], "radius": size, "bsdf": bsdf}
    to_world = _t().translate([x, 0.0, z]).rotate([0, 1, 0], turn)
    if kind == "cube":
        return {"type": "cube", "to_world": to_world.translate([0, size, 0]).scale(size), "bsdf": bsdf}
    if kind == "cylinder":  # Mitsuba's runs along z from 0 to 1: stood up along y
        return {
            "type": "cylinder",
            "to_world": to_world.rotate([1, 0, 0], -90).scale([size, size, height]),
            "bsdf": bsdf,
        }
    raise ValueError(f"unknown shape {kind!r}; known: {', '.join(SHAPES)}")


def rectangle(to_world, bsdf: dict | None = None, emitter: dict | None = None) -> dict:
    shape: dict = {"type": "rectangle", "to_world": to_world}
    if bsdf is not None:
        shape["bsdf"] = bsdf
    if emitter is not None:
        shape["emitter"] = emitter
    return shape


def area_light(radiance) -> dict:
    return {"type": "area", "radiance": rgb(radiance)}


def floor(y: float, size: float, bsdf: dict) -> dict:
    """A horizontal square facing up at height ``y``."""
    return rectangle(_t().translate([0, y, 0]).rotate([1, 0, 0], -90).scale(size), bsdf)


def wall(to_world, bsdf: dict) -> dict:
    return rectangle(to_world, bsdf)


def wall_x(x: float, z0: float, z1: float, y0: float, y1: float, bsdf: dict) -> dict:
    """A rectangle in the plane x = const spanning [z0, z1] x [y0, y1]: a room's side wall, or a piece of one."""
    return rectangle(
        _t()
        .translate([x, (y0 + y1) / 2, (z0 + z1) / 2])
        .rotate([0, 1, 0], -90)
        .scale([(z1 - z0) / 2, (y1 - y0) / 2, 1]),
        bsdf,
    )


def wall_x_with_opening(
    x: float, half_depth: float, height: float, z0: float, z1: float, y0: float, y1: float, bsdf: dict
) -> dict:
    """The wall x = const of a room (z in [-half_depth, half_depth], y in [0, height]) with an opening
    [z0, z1] x [y0, y1]: four rectangles, ``east_below``, ``east_above``, ``east_left``, ``east_right``."""
    d, h = half_depth, height
    return {
        "east_below": wall_x(x, -d, d, 0, y0, bsdf),
        "east_above": wall_x(x, -d, d, y1, h, bsdf),
        "east_left": wall_x(x, -d, z0, y0, y1, bsdf),
        "east_right": wall_x(x, z1, d, y0, y1, bsdf),
    }


def room(rng: np.random.Generator, half_width: float, half_depth: float, height: float, wall: dict) -> dict:
    """A room's floor (a random colour), ceiling, back and front walls (``wall``) and west wall (a random colour).

    The room spans x in [-half_width, half_width], z in [-half_depth, half_depth], y in [0, height]; the east
    wall (x = +half_width) is left to the scene, which cuts its openings in it.
    """
    w, d, h = half_width, half_depth, height
    return {
        "floor": rectangle(_t().rotate([1, 0, 0], -90).scale([w, d, 1]), diffuse(random_color(rng, 0.2, 0.6))),
        "ceiling": rectangle(_t().translate([0, h, 0]).rotate([1, 0, 0], 90).scale([w, d, 1]), wall),
        "back": rectangle(_t().translate([0, h / 2, -d]).scale([w, h / 2, 1]), wall),
        "front": rectangle(_t().translate([0, h / 2, d]).scale([w, h / 2, 1]), wall),
        "west": wall_x(-w, -d, d, 0, h, diffuse(random_color(rng, 0.2, 0.8))),
    }


def transform():
    """An identity ``ScalarTransform4f`` to chain translate/rotate/scale on."""
    return _t()


def checkerboard(rng: np.random.Generator, scale: float) -> dict:
    """Mitsuba's procedural checkerboard with two random colours, ``scale`` tiles per unit uv."""
    return {
        "type": "checkerboard",
        "color0": rgb(random_color(rng, 0.05, 0.4)),
        "color1": rgb(random_color(rng, 0.5, 0.9)),
        "to_uv": _t().scale([scale, scale, 1]),
    }


def noise_bitmap(rng: np.random.Generator, size: int = 64, octaves: int = 4) -> dict:
    """A bitmap texture of smooth value noise (sum of upsampled random grids), made in numpy."""
    import mitsuba as mi
    from scipy.ndimage import zoom

    img = np.zeros((size, size, 3), dtype=np.float64)
    for octave in range(octaves):
        cells = 2 ** (octave + 2)
        grid = rng.uniform(0, 1, (cells, cells, 3))
        img += zoom(grid, (size / cells, size / cells, 1), order=1, mode="grid-wrap", grid_mode=True) / 2**octave
    img = img / img.max()
    tint = np.asarray(random_color(rng, 0.3, 1.0))
    data = np.ascontiguousarray((0.05 + 0.85 * img * tint).astype(np.float32))
    return {"type": "bitmap", "bitmap": mi.Bitmap(data), "raw": True, "filter_type": "bilinear"}


def torus_mesh(name: str, bsdf: dict, major: float = 1.0, minor: float = 0.35, to_world=None, segments=(64, 32)):
    """A torus triangle mesh with smooth normals, built with numpy (no asset file).

    Returns a ``mitsuba.Mesh`` object, which ``mitsuba.load_dict`` accepts as a scene child.
    """
    nu, nv = segments
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    pos = np.stack(
        [(major + minor * np.cos(vv)) * np.cos(uu), minor * np.sin(vv), (major + minor * np.cos(vv)) * np.sin(uu)], -1
    )
    nrm = np.stack([np.cos(vv) * np.cos(uu), np.sin(vv), np.cos(vv) * np.sin(uu)], -1)
    i = np.arange(nu)[:, None]
    j = np.arange(nv)[None, :]
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    pos, nrm = pos.reshape(-1, 3), nrm.reshape(-1, 3)
    if to_world is not None:
        m = np.array(to_world.matrix, dtype=np.float64)
        pos = pos @ m[:3, :3].T + m[:3, 3]
        nrm = nrm @ np.linalg.inv(m[:3, :3])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return mesh_from_arrays(name, pos, faces, bsdf, nrm)
