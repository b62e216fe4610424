"""Ladders: the same view rendered at several sample counts, and training draws that pair two of its rungs.

A scorer is used to rank the renders of one scene as samples accrue (stop a render, compare two budgets),
and that is where it fails on dark, sparse renders: trained on images one at a time, it reads 4 spp of a
room lit from a turned lamp as better than 8 spp, each within its absolute error budget, the order wrong.
A ladder is the set of a dataset's images that share a reference, an algorithm and a role (the images and
their independent twins are two ladders); its rungs differ only in sample count. :func:`ladder_partners`
finds, for each training image, the other rungs of its ladder within ``span`` doublings of its sample
count; :class:`nriqa.data.patches.TrainPatches` (``ladder_pairs``) makes every odd item the same cut,
display and jitter as the item before it, taken from one of those rungs, so the training module can ask
the difference of the two predicted means to be the difference of the two true ones
(:class:`nriqa.training.module.NRIQAModule`'s ``ladder_weight``).

    >>> from nriqa.io.manifest import Record
    >>> def rec(spp, algorithm="path"):
    ...     return Record(f"s/{algorithm}/{spp}", "s", 0, algorithm, "test", spp, 0, "p", "s/reference.exr", 8, 8, 0.0, "b")
    >>> ladder_partners([rec(2), rec(4), rec(8), rec(64), rec(4, "bdpt")], span=2)
    [[1, 2], [0, 2], [0, 1], [], []]
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from nriqa.data.options import check_whole
from nriqa.io.manifest import Record

__all__ = ["check_span", "ladder_key", "ladder_partners", "pick_partner"]


def ladder_key(record: Record) -> tuple:
    """What the rungs of one ladder share: reference (its root included), algorithm, role, film filter and size."""
    return (record.reference, record.algorithm, record.role, record.pixel_filter, record.width, record.height)


def check_span(span: int) -> int:
    """``span`` as an int if it is a whole number >= 1; else a one-line ``ValueError`` naming ``data.ladder_span``."""
    return check_whole(span, "data.ladder_span", 1, "doublings")


def ladder_partners(records: Sequence[Record], span: int = 2) -> list[list[int]]:
    """For each record, the indices of the other rungs of its ladder whose sample count is within ``span``
    doublings of its own (``2 ** -span <= spp_j / spp_i <= 2 ** span``), in index order; ``[]`` where it has none.
    """
    span = check_span(span)
    ladders: dict[tuple, list[int]] = {}
    for i, r in enumerate(records):
        ladders.setdefault(ladder_key(r), []).append(i)
    out: list[list[int]] = [[] for _ in records]
    for members in ladders.values():
        for i in members:
            si = records[i].spp
            out[i] = [
                j
                for j in members
                if j != i and records[j].spp != si and abs(math.log2(records[j].spp / si)) <= span + 1e-9
            ]
    return out


def pick_partner(partners: Sequence[int], own: int, generator: torch.Generator) -> int:
    """One of ``partners`` drawn uniformly with ``generator``; ``own`` where there is none (the pair is one image
    twice, its difference zero)."""
    if not partners:
        return own
    return int(partners[int(torch.randint(0, len(partners), (1,), generator=generator))])
