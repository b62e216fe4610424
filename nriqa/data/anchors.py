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
import functools
import os

from nriqa.data.images import ImagePair
from nriqa.io.manifest import Record


def _path_key(path: str | os.PathLike) -> str:
    return os.path.normpath(os.path.abspath(path))


@dataclasses.dataclass(frozen=True)
class Anchors:
    """Anchored scene families and dataset roots; empty (the default): every image learns its target."""

    scenes: frozenset[str] = frozenset()
    roots: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.scenes or self.roots)

    @functools.cached_property
    def _root_prefixes(self) -> tuple[str, ...]:
        """Each root as an absolute, normalised directory prefix, worked out once (images are tested per draw)."""
        return tuple(_path_key(root) + os.sep for root in self.roots)

    def __call__(self, record: Record) -> bool:
        """Whether ``record`` (its path prefixed with its root, as :func:`nriqa.io.manifest.read_datasets`
        gives it) is anchored."""
        if record.scene in self.scenes:
            return True
        if not self.roots:
            return False
        path = _path_key(record.path)
        return any(path.startswith(prefix) for prefix in self._root_prefixes)

    def describe(self) -> dict[str, list[str]]:
        """The settings, for a checkpoint's hyper-parameters."""
        out = {"anchor_scenes": sorted(self.scenes)}
        if self.roots:
            out["anchor_data"] = list(self.roots)
        return out


NO_ANCHORS = Anchors()


def check_anchors(anchors: Anchors, pairs: list[ImagePair], converged: bool = False) -> Anchors:
    """``anchors``, checked against the training ``pairs``: each family one of theirs, each root one they were
    read from, and at least one image left to learn from its target (unless ``converged``: converged patches,
    :mod:`nriqa.data.converged`, learn their target on anchored images too).

    Raises:
        ValueError: one line saying which setting is wrong and what it names.
    """
    known = {p.record.scene for p in pairs}
    unknown = sorted(anchors.scenes - known)
    if unknown:
        raise ValueError(
            f"data.anchor_scenes: {', '.join(unknown)} not among the training families ({', '.join(sorted(known))})"
        )
    for root in anchors.roots:
        one_root = Anchors(roots=(root,))
        if not any(one_root(p.record) for p in pairs):
            raise ValueError(f"data.anchor_data: {root} holds none of the training images; name one of paths.data_dir")
    if anchors and not converged and all(anchors(p.record) for p in pairs):
        what = "data.anchor_scenes names every training family" if not anchors.roots else "every training image is anchored"
        raise ValueError(f"{what}: leave at least one image to learn from its target (or set data.converged_p)")
    return anchors
