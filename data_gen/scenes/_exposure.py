"""Exposure of a scene variant: every emitter scaled by one factor ``2^U(-stops, stops)``.

The issue-15 families draw this factor first from the variant's generator, so a seed fixes it and
a family's variants range from dark to blown out (mean radiance over a factor ``4^stops``).
"""

from __future__ import annotations

import numpy as np

# The property that carries an emitter's strength, by Mitsuba emitter type.
STRENGTH = {
    "area": "radiance",
    "constant": "radiance",
    "point": "intensity",
    "spot": "intensity",
    "directional": "irradiance",
    "envmap": "scale",
    "projector": "scale",
}
# Emitters whose strength property defaults to 1 (the others must set theirs).
DEFAULT_ONE = ("envmap", "projector")
# Mitsuba emitters this module cannot scale: met at the top level of a scene, they are refused.
UNSCALABLE = ("directionalarea", "sunsky")


def exposure(rng: np.random.Generator, stops: float = 3.0) -> float:
    """A gain ``2^u`` with ``u ~ U(-stops, stops)`` (one draw from ``rng``)."""
    if stops < 0:
        raise ValueError(f"stops={stops}: must be >= 0")
    return float(2.0 ** rng.uniform(-stops, stops))


def scaled(value, gain: float):
    """An emitter strength (a float, an rgb dict or a bitmap texture holding its array) times ``gain``; a copy."""
    if isinstance(value, dict) and value.get("type") == "rgb":
        return {**value, "value": [float(v) * gain for v in value["value"]]}
    if isinstance(value, dict) and value.get("type") == "bitmap" and "bitmap" in value:
        import mitsuba as mi

        data = np.asarray(value["bitmap"], dtype=np.float32) * np.float32(gain)
        return {**value, "bitmap": mi.Bitmap(np.ascontiguousarray(data))}
    if isinstance(value, (int, float)):
        return float(value) * gain
    raise ValueError(
        f"cannot scale emitter strength {value!r}: give a float, an rgb dict or a bitmap texture of an array"
    )


def _scale_emitter(emitter: dict, gain: float) -> dict:
    kind = emitter.get("type")
    if kind not in STRENGTH:
        raise ValueError(f"cannot scale emitter of type {kind!r}; known: {', '.join(STRENGTH)}")
    key = STRENGTH[kind]
    default = 1.0 if kind in DEFAULT_ONE else None
    if key not in emitter and default is None:
        raise ValueError(f"{kind} emitter without {key!r}: set it explicitly so that it can be scaled")
    return {**emitter, key: scaled(emitter.get(key, default), gain)}


def scale_emitters(scene: dict, gain: float) -> dict:
    """A copy of a Mitsuba scene dict with every emitter's strength times ``gain``.

    Emitters are the top-level entries whose type is an emitter and the ``emitter`` of shapes.
    ``ValueError`` for an emitter type it cannot scale, so that no light is silently left out.
    """
    out = {}
    for key, value in scene.items():
        if isinstance(value, dict) and value.get("type") in (*STRENGTH, *UNSCALABLE):
            value = _scale_emitter(value, gain)
        elif isinstance(value, dict) and "emitter" in value:
            value = {**value, "emitter": _scale_emitter(value["emitter"], gain)}
        out[key] = value
    return out


def emitter_strengths(scene: dict) -> dict[str, float]:
    """Mean strength of each emitter of a scene dict, by entry name (what :func:`scale_emitters` scales)."""
    found = {}
    for key, value in scene.items():
        emitter = value if isinstance(value, dict) and value.get("type") in STRENGTH else None
        if emitter is None and isinstance(value, dict) and "emitter" in value:
            emitter = value["emitter"]
        if emitter is not None:
            strength = emitter.get(STRENGTH[emitter["type"]], 1.0)
            if isinstance(strength, dict) and strength.get("type") == "bitmap":
                found[key] = float(np.mean(np.asarray(strength["bitmap"], dtype=np.float64)))
            else:
                found[key] = float(np.mean(strength["value"])) if isinstance(strength, dict) else float(strength)
    return found
