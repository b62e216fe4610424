"""Rendering algorithms: an integrator and a sampler, each a family of Monte Carlo noise.

A scene lists the algorithms that converge to its reference (checked by the convergence test);
``reference_algorithm`` is the path tracer with the independent sampler (thesis ch. 4).
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Algorithm:
    """An integrator/sampler pair; ``square_spp`` samplers only take sample counts that are 4^k."""

    name: str
    integrator: str
    sampler: str
    square_spp: bool = False

    def accepts(self, spp: int) -> bool:
        """Whether the sampler renders exactly ``spp`` samples (Mitsuba rounds others up)."""
        if not self.square_spp:
            return spp >= 1
        root = int(round(spp**0.5))
        return root * root == spp and spp & (spp - 1) == 0

    def integrator_dict(self, max_depth: int, samples_per_pass: int | None = None) -> dict:
        """The Mitsuba integrator dictionary."""
        spec: dict = {"type": self.integrator, "max_depth": max_depth}
        if samples_per_pass is not None:
            spec["samples_per_pass"] = samples_per_pass
        return spec

    def sampler_dict(self, spp: int) -> dict:
        """The Mitsuba sampler dictionary for ``spp`` samples per pixel."""
        return {"type": self.sampler, "sample_count": spp}


_ALGORITHMS = [
    Algorithm("path_independent", "path", "independent"),
    Algorithm("path_multijitter", "path", "multijitter", square_spp=True),
    Algorithm("path_ldsampler", "path", "ldsampler", square_spp=True),
    Algorithm("ptracer_independent", "ptracer", "independent"),
    Algorithm("volpath_independent", "volpath", "independent"),
    Algorithm("volpath_multijitter", "volpath", "multijitter", square_spp=True),
    Algorithm("volpath_ldsampler", "volpath", "ldsampler", square_spp=True),
]
ALGORITHMS: dict[str, Algorithm] = {a.name: a for a in _ALGORITHMS}


def get_algorithm(name: str) -> Algorithm:
    """Look up an algorithm by name; ``KeyError`` message lists the valid ones."""
    try:
        return ALGORITHMS[name]
    except KeyError:
        raise KeyError(f"unknown algorithm {name!r}; known: {', '.join(ALGORITHMS)}") from None
