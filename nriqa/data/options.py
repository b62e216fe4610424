"""Checks of the ``data.*`` training options: a share (a probability), a whole number with a lower bound, a
range ``[low, high]`` of two numbers within bounds, and a list of names (scene families; also for the other
commands' lists of names, ``crossval.scenes`` and ``nriqa-data scenes=``).

A checked data option is checked twice, where :class:`nriqa.data.datamodule.NRIQADataModule` reads it (at config
time, before anything is loaded) and where :class:`nriqa.data.patches.TrainPatches` takes it (for the class
used alone). Both call these, so a bad value gets the same one line wherever it is caught, naming its key, what
was given and what to give: a ``ValueError`` that the command-line tools print as one line and exit non-zero.
Each check takes the option's full key (``data.cutmix_p``), so the training loop's counts (``trainer.max_epochs``,
``seed``) and ``nriqa-data``'s whole numbers go through the same checks and read the same way.

    >>> check_share(0.25, "data.cutmix_p", "pasting")
    0.25
    >>> check_whole(16.0, "data.albedo_min_spp", 0, "samples per pixel")
    16
    >>> check_whole("many", "data.ladder_span", 1, "doublings")
    Traceback (most recent call last):
    ...
    ValueError: data.ladder_span=many: give a whole number of doublings >= 1
    >>> check_range([0.3, 0.8], "data.pixel_filter_sigma", "pixels", 0, 4, low_open=True)
    (0.3, 0.8)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["as_number", "check_names", "check_range", "check_share", "check_whole"]


def as_number(value) -> float:
    """``value`` as a float; NaN where it is a boolean or not a number at all (so every range test fails). The other
    commands' checks of a number read their values through it too."""
    if isinstance(value, bool):
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def check_share(p, key: str, what: str) -> float:
    """``p`` as a float in [0, 1]; else a one-line ``ValueError`` naming ``key`` and ``what`` 0 switches off."""
    value = as_number(p)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"{key}={p} is not a probability; use a value in [0, 1] (0 switches {what} off)")
    return value


def check_whole(value, key: str, low: int | None = None, unit: str = "", note: str = "") -> int:
    """``value`` as an int if it is a whole number (>= ``low`` unless that is ``None``); else a one-line
    ``ValueError`` naming ``key``, the ``unit`` it counts and ``note`` (e.g. what its lowest value means, or the
    option that sets it)."""
    number = as_number(value)
    if not (number.is_integer() and (low is None or number >= low)):
        counted = f" of {unit}" if unit else ""
        bound = "" if low is None else f" >= {low}"
        raise ValueError(f"{key}={value}: give a whole number{counted}{bound}{note}")
    return int(number)


def check_range(
    pair, key: str, unit: str, low: float, high: float = math.inf, low_open: bool = False
) -> tuple[float, float]:
    """``pair`` as ``(lo, hi)`` floats if it is two numbers with ``low <= lo <= hi <= high`` (``low < lo`` where
    ``low_open``); else a one-line ``ValueError`` naming ``key``, the bounds and the ``unit``."""
    values = [] if isinstance(pair, (str, bytes)) else pair
    try:
        lo, hi = (as_number(v) for v in values)
    except (TypeError, ValueError):  # not iterable, or not two values
        lo = hi = math.nan
    if not ((lo > low if low_open else lo >= low) and lo <= hi <= high):
        bounds = f"{low} {'<' if low_open else '<='} low <= high" + ("" if math.isinf(high) else f" <= {high}")
        raise ValueError(f"{key}={pair}: give [low, high] with {bounds} {unit}")
    return lo, hi


def check_names(value, key: str) -> list[str] | None:
    """``value`` as a list of names: ``None`` stays ``None`` (all), one bare name is a list of one; anything else
    (a number, a mapping) is a one-line ``ValueError`` naming the full ``key`` (e.g. ``crossval.scenes``)."""
    if value is None:
        return None
    if isinstance(value, str):
        return [value]
    if isinstance(value, Sequence):  # a list, a tuple or Hydra's ListConfig
        return [str(v) for v in value]
    raise ValueError(f"{key}={value}: give a list of names, e.g. {key}=[a,b]")
