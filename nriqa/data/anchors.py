"""Which training images learn the starting network's map instead of their target (a fine-tune's anchors).

A fine-tune on a few new images drifts on everything else; anchored images pin it there: they are drawn
and cut like any other, but the training module replaces their SSIM target by the starting network's own
map (:class:`nriqa.training.module.NRIQAModule`'s teacher). An image is anchored when its scene family is
one of ``scenes`` (``data.anchor_scenes``: keep the families the start learnt from many scenes while
others teach it) or when it belongs to one of the dataset roots ``roots`` (``data.anchor_data``: keep the
start's reading of one set, e.g. whole-view renders, while another set of the same families, e.g. zoomed
crops, teaches it).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence

from nriqa.data.images import ImagePair
from nriqa.io.manifest import Record


def _root_key(path: str | os.PathLike) -> str:
    return os.path.normpath(os.path.abspath(path))


@dataclasses.dataclass(frozen=True)
class Anchors:
    """Anchored scene families and dataset roots; empty (the default): every image learns its target."""

    scenes: frozenset[str] = frozenset()
    roots: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.scenes or self.roots)

    def __call__(self, record: Record) -> bool:
        """Whether ``record`` (its path prefixed with its root, as :func:`nriqa.io.manifest.read_datasets`
        gives it) is anchored."""
        if record.scene in self.scenes:
            return True
        path = _root_key(record.path)
        return any(path.startswith(_root_key(root) + os.sep) for root in self.roots)

    def describe(self) -> dict[str, list[str]]:
        """The settings, for a checkpoint's hyper-parameters."""
        out = {"anchor_scenes": sorted(self.scenes)}
        if self.roots:
            out["anchor_data"] = list(self.roots)
        return out


NO_ANCHORS = Anchors()


def make_anchors(
    pairs: list[ImagePair], scenes: Sequence[str] = (), roots: Sequence[str | os.PathLike] = ()
) -> Anchors:
    """The anchors of the training ``pairs``, checked: each family one of theirs, each root one they were
    read from, and at least one image left to learn from its target.

    Raises:
        ValueError: one line saying which setting is wrong and what it names.
    """
    anchors = Anchors(frozenset(str(s) for s in scenes or ()), tuple(str(r) for r in roots or ()))
    known = {p.record.scene for p in pairs}
    unknown = sorted(anchors.scenes - known)
    if unknown:
        raise ValueError(
            f"data.anchor_scenes: {', '.join(unknown)} not among the training families ({', '.join(sorted(known))})"
        )
    for root in anchors.roots:
        if not any(Anchors(roots=(root,))(p.record) for p in pairs):
            raise ValueError(f"data.anchor_data: {root} holds none of the training images; name one of paths.data_dir")
    if anchors and all(anchors(p.record) for p in pairs):
        what = "data.anchor_scenes names every training family" if not anchors.roots else "every training image is anchored"
        raise ValueError(f"{what}: leave at least one image to learn from its target")
    return anchors
