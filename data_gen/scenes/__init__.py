"""Scene families: one module each, registered with :func:`register_scene`.

A family builds a Mitsuba scene dictionary from a ``numpy.random.Generator`` (its variant seed),
so one family yields many distinct images while cross-validation folds stay by family. Each
declares only what it needs: resolution, spp ladder top, max depth, its algorithms, and whether it
holds a participating medium (then the volumetric path tracer is its reference).
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from collections.abc import Callable

import numpy as np


@dataclasses.dataclass(frozen=True)
class SceneSpec:
    """What a scene family needs to be rendered.

    ``build(rng)`` returns a Mitsuba scene dict whose ``sensor`` has no film or sampler and which
    has no integrator: the renderer adds those per image.
    """

    name: str
    build: Callable[[np.random.Generator], dict]
    algorithms: tuple[str, ...]
    resolution: tuple[int, int] = (128, 128)
    ladder_top: int = 64
    max_depth: int = 8
    medium: bool = False
    summary: str = ""

    @property
    def reference_algorithm(self) -> str:
        """Independent-sampler path tracing (volumetric where the scene holds a medium)."""
        return "volpath_independent" if self.medium else "path_independent"


_REGISTRY: dict[str, SceneSpec] = {}


def register_scene(spec: SceneSpec) -> SceneSpec:
    """Add a scene family to the registry (called at import of its module)."""
    if spec.name in _REGISTRY:
        raise ValueError(f"scene {spec.name!r} registered twice")
    _REGISTRY[spec.name] = spec
    return spec


def _load_all() -> None:
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}")


def list_scenes() -> list[str]:
    """Names of all scene families, sorted."""
    _load_all()
    return sorted(_REGISTRY)


def get_scene(name: str) -> SceneSpec:
    """The :class:`SceneSpec` of a family; ``KeyError`` lists the known ones."""
    _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown scene {name!r}; known scenes: {', '.join(sorted(_REGISTRY))}") from None
