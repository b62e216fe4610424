"""A rule's figures for each scorer, recomputed from the ``images.csv`` of one or more evaluations.

The rules that decide whether a new weights file ships (docs/results/evaluation.md) compare it with
the shipped one on fresh test sets, on a handful of figures that ``nriqa-evaluate`` writes spread
over several tables, one test set at a time. This module puts them on one line per scorer, for one
set or several pooled, all on the SSIM scale (the ``mapped`` column) against the true mean SSIM:

* ``srocc``, ``mae``, ``bias`` (mean of predicted minus true) over every image;
* ``low_n``, ``low_mae``, ``low_bias``: the same at few samples (spp <= :data:`LOW_SPP`), where
  issue 15's dark renders were read too good;
* ``scene_srocc_mean`` / ``scene_srocc_worst``: the SROCC within each (scene, variant) -- one camera,
  one light, its ladder of sample counts -- over the groups of at least :data:`MIN_GROUP` images;
* ``ladders`` / ``ladders_falling``: ladders, and those whose prediction falls by more than
  :data:`nriqa.eval.monotone.MAX_DROP` from one rung to the next; ``low_where_converged``;
* ``families_off``: the scene families whose bias over all their images exceeds :data:`FAMILY_BIAS`
  in size, and with ``--base NAME``, ``newly_off``: those of them the base scorer keeps within it.

Pooled sets keep their (scene, variant) groups apart: the same variant number in two sets is two
groups. ``python -m nriqa.eval.scorecard A/images.csv B/images.csv --base unet_fast --out DIR``
writes ``scorecard.{csv,md}`` to ``DIR`` and prints the table; ``--without FAMILY`` leaves a family out
(a rule that asks the other families to hold while one is learnt); ``--by scene`` or ``--by algorithm``
adds a row per scorer and scene family or sampling algorithm after the pooled ones, with the group in a
``group`` column (the pooled rows read ``all``): where a scorer's error lives.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from nriqa.core.correlation import srocc
from nriqa.errors import NriqaError
from nriqa.eval.monotone import MAX_DROP, monotonicity
from nriqa.io.atomic import write_text_atomic
from nriqa.io.tables import markdown_table, read_csv, write_csv

LOW_SPP = 8
MIN_GROUP = 3
FAMILY_BIAS = 0.02
COLUMNS = [
    "predictor",
    "n",
    "srocc",
    "mae",
    "bias",
    "low_n",
    "low_mae",
    "low_bias",
    "scene_srocc_mean",
    "scene_srocc_worst",
    "ladders",
    "ladders_falling",
    "low_where_converged",
    "families_off",
    "newly_off",
]
BY = ("scene", "algorithm")
NEED = {"predictor", "id", "scene", "variant", "algorithm", "spp", "true", "mapped"}


class ScorecardError(NriqaError):
    """Rows that cannot be scored: a file unreadable or malformed, a base scorer missing."""


def read_rows(paths: list[str | Path]) -> list[dict]:
    """The rows of the ``images.csv`` files, pooled; ``true``, ``mapped`` and ``spp`` as numbers.

    With more than one file, each row's ``id`` and ``variant`` are prefixed with the file's index
    (``"1:"``) so that two sets never share an image or a (scene, variant) group.
    """
    if not paths:
        raise ScorecardError("no images.csv given; pass the images.csv of one or more nriqa-evaluate runs")
    rows = []
    for k, path in enumerate(paths):
        try:
            own = read_csv(path, NEED, "an nriqa-evaluate images.csv")
        except ValueError as exc:
            raise ScorecardError(str(exc)) from None
        for r in own:
            try:
                r["true"] = float(r["true"]) if r["true"] != "" else math.nan
                r["mapped"] = float(r["mapped"]) if r["mapped"] != "" else math.nan
                r["spp"] = int(float(r["spp"]))
            except ValueError:
                raise ScorecardError(f"{path}: image {r['id']} has a value that is not a number") from None
            if len(paths) > 1:
                r["id"], r["variant"] = f"{k}:{r['id']}", f"{k}:{r['variant']}"
        rows.extend(own)
    return rows


def _srocc(pred: list[float], true: list[float]) -> float:
    return srocc(np.array(pred), np.array(true)) if len(pred) >= 2 else math.nan


def _scored(rows: list[dict], name: str | None = None) -> list[dict]:
    """The rows with a finite reading on the SSIM scale and a finite truth (of predictor ``name`` if given)."""
    return [
        r
        for r in rows
        if (name is None or r["predictor"] == name) and math.isfinite(r["mapped"]) and math.isfinite(r["true"])
    ]


def _families(own: list[dict]) -> dict[str, float]:
    """Each scene family's bias over its finite rows."""
    errors: dict[str, list[float]] = defaultdict(list)
    for r in own:
        errors[r["scene"]].append(r["mapped"] - r["true"])
    return {scene: float(np.mean(e)) for scene, e in sorted(errors.items())}


def _off(families: dict[str, float]) -> dict[str, float]:
    return {scene: b for scene, b in families.items() if abs(b) > FAMILY_BIAS}


def card(rows: list[dict], name: str) -> dict:
    """One scorer's row of :data:`COLUMNS` (``newly_off`` left empty) from its finite rows in ``rows``."""
    own = _scored(rows, name)
    if not own:
        raise ScorecardError(f"no finite rows of predictor {name!r}")
    err = np.array([r["mapped"] - r["true"] for r in own])
    low = np.array([r["mapped"] - r["true"] for r in own if r["spp"] <= LOW_SPP])
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in own:
        groups[(r["scene"], r["variant"])].append(r)
    within = [_srocc([r["mapped"] for r in g], [r["true"] for r in g]) for g in groups.values() if len(g) >= MIN_GROUP]
    ladder_rows = [dict(r, predicted=r["mapped"]) for r in own]
    _, summary = monotonicity(ladder_rows, [name])
    ladders = summary[0]
    off = _off(_families(own))
    return {
        "predictor": name,
        "n": len(own),
        "srocc": _srocc([r["mapped"] for r in own], [r["true"] for r in own]),
        "mae": float(np.abs(err).mean()),
        "bias": float(err.mean()),
        "low_n": len(low),
        "low_mae": float(np.abs(low).mean()) if len(low) else math.nan,
        "low_bias": float(low.mean()) if len(low) else math.nan,
        "scene_srocc_mean": float(np.mean(within)) if within else math.nan,
        "scene_srocc_worst": float(np.min(within)) if within else math.nan,
        "ladders": ladders["ladders"],
        "ladders_falling": ladders["ladders_with_drop"],
        "low_where_converged": ladders["low_where_converged"],
        "families_off": " ".join(f"{s}:{b:+.3f}" for s, b in off.items()),
        "newly_off": "",
    }


def on_ssim_scale(rows: list[dict]) -> list[str]:
    """The predictors with a reading on the SSIM scale, in order of appearance: not raw-scale baselines
    such as ``wavelet_sigma``, whose ``mapped`` column ``nriqa-evaluate`` leaves empty."""
    return list(dict.fromkeys(r["predictor"] for r in _scored(rows)))


def scorecard(rows: list[dict], predictors: list[str] | None = None, base: str | None = None) -> list[dict]:
    """A :func:`card` per predictor (default: every one in ``rows`` that reads on the SSIM scale, in order
    of appearance; :func:`on_ssim_scale`).

    With ``base``, each other card's ``newly_off`` lists its families off by more than
    :data:`FAMILY_BIAS` where the base scorer's bias is within it.
    """
    names = list(dict.fromkeys(r["predictor"] for r in rows))
    for name in [*(predictors or []), *([base] if base else [])]:
        if name not in names:
            raise ScorecardError(f"no rows of predictor {name!r}; the rows have: {', '.join(names)}")
    chosen = predictors or on_ssim_scale(rows)
    if not chosen:
        raise ScorecardError("no predictor in these rows reads on the SSIM scale (the mapped column is empty)")
    cards = [card(rows, n) for n in chosen]
    if base:
        base_off = _off(_families(_scored(rows, base)))
        for c in cards:
            if c["predictor"] != base:
                mine = [f.split(":")[0] for f in c["families_off"].split()]
                c["newly_off"] = " ".join(f for f in mine if f not in base_off)
    return cards


def by_group(rows: list[dict], cards: list[dict], by: str) -> list[dict]:
    """``cards`` (the pooled ones, :func:`scorecard`) with ``group`` ``"all"``, then per scorer a :func:`card` for each
    value of column ``by`` (one of :data:`BY`) among its finite rows, in sorted order, with that value as ``group``."""
    if by not in BY:
        raise ScorecardError(f"cannot group by {by!r}; choose one of: {', '.join(BY)}")
    out = [{"group": "all", **c} for c in cards]
    for c in cards:
        own = _scored(rows, c["predictor"])
        for value in sorted({r[by] for r in own}):
            out.append({"group": value, **card([r for r in own if r[by] == value], c["predictor"])})
    return out


def columns(cards: list[dict]) -> list[str]:
    """:data:`COLUMNS`, with ``group`` after ``predictor`` when the cards are grouped (:func:`by_group`)."""
    return [COLUMNS[0], "group", *COLUMNS[1:]] if cards and "group" in cards[0] else COLUMNS


def write_scorecard(out: Path, cards: list[dict], sources: list[str]) -> None:
    """``scorecard.csv`` and ``scorecard.md`` in ``out``."""
    write_csv(out / "scorecard.csv", cards, columns(cards))
    write_text_atomic(
        out / "scorecard.md",
        "# Scorecard\n\nOn the SSIM scale against the true mean SSIM (nriqa.eval.scorecard), pooled over: "
        + ", ".join(f"`{s}`" for s in sources)
        + f". `low_*`: images of at most {LOW_SPP} spp; `scene_srocc_*`: within each (scene, variant) of at least "
        f"{MIN_GROUP} images; `ladders_falling`: ladders whose prediction falls by more than {MAX_DROP}; "
        f"`families_off`: families whose bias exceeds {FAMILY_BIAS} in size.\n\n"
        + markdown_table(cards, columns(cards), digits=4),
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("images", nargs="+", help="images.csv of one or more nriqa-evaluate runs (pooled)")
    parser.add_argument("--predictor", action="append", default=None, help="a scorer to report (repeat; default all)")
    parser.add_argument("--base", default=None, help="the scorer whose families off the others are compared with")
    parser.add_argument("--out", default=None, help="write scorecard.{csv,md} here (default: print only)")
    parser.add_argument(
        "--without", action="append", default=[], metavar="FAMILY", help="leave a scene family's images out (repeat)"
    )
    parser.add_argument(
        "--by", choices=BY, default=None, help="add a row per scorer and scene family or sampling algorithm"
    )
    args = parser.parse_args(argv)
    try:
        rows = [r for r in read_rows(args.images) if r["scene"] not in args.without]
        cards = scorecard(rows, args.predictor, args.base)
        if args.by:
            cards = by_group(rows, cards, args.by)
        if not args.predictor:
            scaled = on_ssim_scale(rows)
            raw = [n for n in dict.fromkeys(r["predictor"] for r in rows) if n not in scaled]
            if raw:
                print(f"left out (no reading on the SSIM scale): {', '.join(raw)}", file=sys.stderr)
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            write_scorecard(Path(args.out), cards, args.images)
    except ScorecardError as exc:
        sys.exit(f"error: {exc}")
    print(markdown_table(cards, columns(cards), digits=4), end="")
    if args.out:
        print(f"wrote {Path(args.out) / 'scorecard.md'}")


if __name__ == "__main__":
    main()
