"""Leave-one-scene-out folds: which noisy images train and which validate (thesis ch. 5).

A scene family is the fold unit: every variant of a held-out scene is kept out of training, so no
camera, light or texture of the validation images was ever seen while training.
"""

from __future__ import annotations

from nriqa.errors import NriqaError
from nriqa.io.manifest import Record, scenes_of

NOISY_ROLES = ("test", "twin")


class FoldError(NriqaError):
    """A fold that cannot be built (unknown scene, nothing to train on); the message says why."""


def noisy_records(records: list[Record]) -> list[Record]:
    """The images a model learns from: every ``test`` and ``twin`` record, in manifest order."""
    return [r for r in records if r.role in NOISY_ROLES]


def only_scenes(records: list[Record], scenes: list[str] | None) -> list[Record]:
    """The records of the scene families ``scenes`` (``None``: all), e.g. to hold some families back.

    Raises:
        FoldError: a name is not a scene of ``records`` (the message lists the scenes).
    """
    if scenes is None:
        return records
    available = scenes_of(noisy_records(records))
    unknown = [s for s in scenes if s not in available]
    if unknown:
        raise FoldError(f"unknown scenes {unknown} in data.scenes; the dataset has: {', '.join(available)}")
    keep = set(scenes)
    return [r for r in records if r.scene in keep]


def split_by_scene(records: list[Record], val_scene: str | None) -> tuple[list[Record], list[Record]]:
    """Split the noisy records of a dataset into ``(train, val)`` with ``val_scene`` held out.

    Args:
        records: all records of a manifest (references included; they are dropped here).
        val_scene: the scene family to hold out, or ``None`` to train on every scene (no val).

    Returns:
        ``(train, val)`` lists of noisy records; ``val`` is empty when ``val_scene`` is None.

    Raises:
        FoldError: ``val_scene`` is not in the dataset (the message lists the scenes), or no
            noisy image is left to train on.
    """
    noisy = noisy_records(records)
    if not noisy:
        raise FoldError("the dataset has no noisy (test/twin) images to train on; render some first")
    scenes = scenes_of(noisy)
    if val_scene is not None and val_scene not in scenes:
        raise FoldError(f"unknown val_scene {val_scene!r}; the dataset has scenes: {', '.join(scenes)}")
    train = [r for r in noisy if r.scene != val_scene]
    val = [r for r in noisy if r.scene == val_scene]
    if not train:
        raise FoldError(f"holding out {val_scene!r} leaves nothing to train on; the dataset has only that scene")
    return train, val
