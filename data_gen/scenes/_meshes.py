"""Triangle meshes built in numpy (no asset files): a generic constructor, thin rods, leaves, a bumpy height field.

Each returns a ``mitsuba.Mesh``, which ``mitsuba.load_dict`` accepts as a scene child.
"""

from __future__ import annotations

import numpy as np


def mesh_from_arrays(
    name: str,
    positions: np.ndarray,
    faces: np.ndarray,
    bsdf: dict,
    normals: np.ndarray | None = None,
    colors: np.ndarray | None = None,
):
    """A Mitsuba mesh from ``(V, 3)`` positions, ``(F, 3)`` vertex indices and optional ``(V, 3)`` normals.

    ``colors`` (``(V, 3)``) become the mesh attribute ``vertex_color``, which a BSDF reads through a
    ``{"type": "mesh_attribute", "name": "vertex_color"}`` texture (:data:`VERTEX_COLOR`).
    """
    import mitsuba as mi

    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(name, len(positions), len(faces), props=props, has_vertex_normals=normals is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.asarray(positions, dtype=np.float32).ravel()
    params["faces"] = np.asarray(faces, dtype=np.uint32).ravel()
    if normals is not None:
        params["vertex_normals"] = np.asarray(normals, dtype=np.float32).ravel()
    params.update()
    if colors is not None:
        mesh.add_attribute("vertex_color", 3, np.asarray(colors, dtype=np.float32).ravel().tolist())
    return mesh


VERTEX_COLOR = {"type": "mesh_attribute", "name": "vertex_color"}


def rods_mesh(name: str, starts, ends, radius: float, bsdf: dict, sides: int = 6):
    """Closed ``sides``-gonal prisms of ``radius`` from each ``starts[i]`` to ``ends[i]`` (``(N, 3)``), one mesh.

    Flat shaded (no vertex normals): thin wires, grilles and fences, the high-frequency geometry that
    a render's noise must not be confused with.
    """
    starts, ends = np.asarray(starts, dtype=np.float64), np.asarray(ends, dtype=np.float64)
    axis = ends - starts
    length = np.linalg.norm(axis, axis=1, keepdims=True)
    if starts.shape != ends.shape or starts.ndim != 2 or starts.shape[1] != 3 or not (length > 0).all():
        raise ValueError("rods_mesh: starts and ends must be (N, 3) with distinct end points")
    axis = axis / length
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(axis, u)
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = radius * (np.cos(ang)[None, :, None] * u[:, None] + np.sin(ang)[None, :, None] * v[:, None])  # (N, S, 3)
    pos = np.concatenate([starts[:, None] + ring, ends[:, None] + ring], axis=1)  # (N, 2S, 3)
    return mesh_from_arrays(name, pos.reshape(-1, 3), prism_faces(sides, len(starts)), bsdf)


def prism_faces(sides: int, count: int, clockwise: bool = False) -> np.ndarray:
    """The triangles, facing outward, of ``count`` closed ``sides``-gonal prisms: ``(count * 4 (sides - 1), 3)``.

    Prism ``i``'s vertices are ``2 * sides`` consecutive ones from ``2 * sides * i``: a ring, then the same ring
    moved along the prism's axis. The ring runs counter-clockwise seen from the moved end (about the axis, by
    the right hand), or clockwise with ``clockwise``; the winding follows, so one-sided BSDFs see the outside.
    """
    k = np.arange(sides)
    k1 = (k + 1) % sides
    side = np.concatenate([np.stack([k, k1, k1 + sides], -1), np.stack([k, k1 + sides, k + sides], -1)])
    caps = np.concatenate(
        [
            np.stack([np.zeros(sides - 2, int), k[2:], k[1:-1]], -1),
            np.stack([np.full(sides - 2, sides), k[1:-1] + sides, k[2:] + sides], -1),
        ]
    )
    one = np.concatenate([side, caps])
    if clockwise:
        one = one[:, [0, 2, 1]]
    return (one[None] + 2 * sides * np.arange(count)[:, None, None]).reshape(-1, 3)


def leaf_outline(length: float, width: float, teeth: int, points: int = 7) -> np.ndarray:
    """A leaf's outline in its own plane, ``(2 * points, 2)``: base at (0, 0), tip at (0, ``length``).

    Pointed at both ends (half-width ``width * sin(pi t)^0.7`` at ``t`` along the midrib), its edge
    notched ``teeth`` times a side (0: smooth); counter-clockwise from the base.
    """
    t = np.linspace(0, 1, points + 1)[1:-1]
    half = width * np.sin(np.pi * t) ** 0.7
    if teeth:
        half = half * (1 - 0.25 * (np.sin(np.pi * teeth * t) ** 2))
    right = np.stack([half, length * t], 1)
    left = np.stack([-half, length * t], 1)[::-1]
    return np.concatenate([[[0.0, 0.0]], right, [[0.0, length]], left])


def leaves_mesh(
    name: str, bases, normals, ups, outline: np.ndarray, scales, bsdf: dict, fold: float = 0.3, colors=None
):
    """Flat-shaded leaves, one mesh: leaf ``i`` grows from ``bases[i]`` along ``ups[i]``, facing ``normals[i]``.

    Each is ``outline`` (:func:`leaf_outline`) scaled by ``scales[i]``, fanned into triangles about the
    midpoint of its midrib and folded up along the midrib by ``fold`` (radians) so it is not a flat card;
    ``colors[i]`` (optional ``(N, 3)``) colours leaf ``i`` (:data:`VERTEX_COLOR`).
    """
    bases, normals, ups = (np.asarray(a, dtype=np.float64) for a in (bases, normals, ups))
    if bases.ndim != 2 or bases.shape[1] != 3 or normals.shape != bases.shape or ups.shape != bases.shape:
        raise ValueError("leaves_mesh: bases, normals and ups must be (N, 3) arrays of one N")
    scales = np.broadcast_to(np.asarray(scales, dtype=np.float64), len(bases))
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    up = ups - (ups * n).sum(1, keepdims=True) * n
    norm = np.linalg.norm(up, axis=1, keepdims=True)
    if not (norm > 1e-9).all():
        raise ValueError("leaves_mesh: each leaf's up must not lie along its normal")
    up /= norm
    side = np.cross(up, n)
    x, y = outline[:, 0], outline[:, 1]
    lift = np.abs(x) * np.tan(fold)  # the two halves rise from the midrib
    centre = np.array([[0.0, outline[:, 1].max() / 2, 0.0]])
    local = np.concatenate([centre, np.stack([x, y, lift], 1)])  # (P+1, 3): side, up, normal
    pos = bases[:, None] + scales[:, None, None] * (
        local[None, :, :1] * side[:, None] + local[None, :, 1:2] * up[:, None] + local[None, :, 2:] * n[:, None]
    )
    ring = np.arange(1, len(outline) + 1)
    one = np.stack([np.zeros_like(ring), ring, np.roll(ring, -1)], 1)
    faces = (one[None] + len(local) * np.arange(len(bases))[:, None, None]).reshape(-1, 3)
    if colors is not None:
        colors = np.repeat(np.asarray(colors, dtype=np.float64), len(local), axis=0)
    return mesh_from_arrays(name, pos.reshape(-1, 3), faces, bsdf, colors=colors)


def heightfield_mesh(name: str, heights: np.ndarray, size: float, bsdf: dict, to_world=None):
    """A ``size`` x ``size`` grid in the xz plane centred at the origin with y = ``heights`` ``(N, N)``.

    Flat shaded, so every bump shows; ``to_world`` (a ``ScalarTransform4f``) places it.
    """
    heights = np.asarray(heights, dtype=np.float64)
    n = heights.shape[0]
    if heights.ndim != 2 or heights.shape[1] != n or n < 2:
        raise ValueError("heightfield_mesh: heights must be a square (N, N) array with N >= 2")
    g = np.linspace(-size / 2, size / 2, n)
    xx, zz = np.meshgrid(g, g, indexing="ij")
    pos = np.stack([xx, heights, zz], -1).reshape(-1, 3)
    if to_world is not None:
        m = np.array(to_world.matrix, dtype=np.float64)
        pos = pos @ m[:3, :3].T + m[:3, 3]
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
    faces = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)])
    return mesh_from_arrays(name, pos, faces, bsdf)
