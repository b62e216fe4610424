"""Sample counts as rendered: samplers that round the count they are asked for up to a power of four.

Mitsuba 3's ``ldsampler`` and ``multijitter`` (and ``stratified``) need a square power of two: asked for 2, 8,
32, 128 or 512 samples per pixel they warn and render 4, 16, 64, 256 or 1024. An external folder named by the
count asked for then holds pairs of rungs rendered at the same count, and "more samples" from one rung to the
next is not true at every step (``../shared/external``'s ``path_ldsampler`` ladders are such). ``nriqa-evaluate
--square-spp ALGORITHMS`` counts those algorithms' images at the count rendered, in every table.
"""

from __future__ import annotations

import fnmatch


def square_spp(spp: int) -> int:
    """The count a square power-of-two sampler renders when asked for ``spp``: the next power of four."""
    if spp < 1:
        raise ValueError(f"spp={spp}: a sample count is at least 1")
    count = 1
    while count < spp:
        count *= 4
    return count


def count_as_rendered(rows: list[dict], algorithms: str) -> list[dict]:
    """``rows`` with ``spp`` set to :func:`square_spp` for algorithms matching ``algorithms`` (comma-separated
    globs; empty: none), and the count asked for kept as ``spp_asked``."""
    patterns = [p.strip() for p in algorithms.split(",") if p.strip()]
    out = []
    for row in rows:
        if any(fnmatch.fnmatchcase(row["algorithm"], p) for p in patterns):
            row = {**row, "spp": square_spp(int(row["spp"])), "spp_asked": row["spp"]}
        out.append(row)
    return out
