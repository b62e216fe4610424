"""Calibrate a scorer's score interval on evaluation rows, and measure how often it covers the truth.

The rows are those of ``nriqa-evaluate``'s ``images.csv`` (one per image and predictor: ``mapped``
against ``true``). Three commands, one predictor at a time::

    # fit on images the weights never learnt; write the interval into the weights' card
    python -m nriqa.eval.coverage fit A/images.csv B/images.csv --predictor unet_fast --weights unet_fast
    # how often the card's interval holds the true mean SSIM on other renders (pooled, per band, per scene)
    python -m nriqa.eval.coverage check C/images.csv --predictor unet_fast --weights unet_fast --out reports/cov
    # leave one scene family out: fit on the others, cover it (the honest in-house figure)
    python -m nriqa.eval.coverage cv A/images.csv B/images.csv --predictor unet_fast

``--exclude-scene`` drops a scene's rows (e.g. one whose reference is suspect). ``--ldr`` makes ``fit`` and
``check`` use the card's interval for LDR input (``score_interval_ldr``: fit it on rows of ``nriqa-evaluate
--display ...`` runs), which the Scorer applies to images it takes as LDR. Tables are printed and,
with ``--out``, written as ``coverage.{csv,md}``. Fitting and the interval itself:
:class:`nriqa.inference.interval.ScoreInterval`.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from nriqa.errors import NriqaError
from nriqa.eval.paired import read_rows
from nriqa.inference.interval import EDGES, ScoreInterval
from nriqa.io.atomic import write_text_atomic
from nriqa.io.tables import markdown_table, write_csv

COLUMNS = ["group", "n", "coverage", "below", "above", "width", "bias"]


class CoverageError(NriqaError):
    """Rows that cannot be used: no rows of the predictor, no interval to check."""


def select(rows: list[dict], predictor: str, exclude: list[str] = ()) -> list[dict]:
    """The predictor's rows with a finite prediction and truth, scenes in ``exclude`` left out."""
    names = sorted({r["predictor"] for r in rows})
    if predictor not in names:
        raise CoverageError(f"no rows of predictor {predictor!r}; the rows have: {', '.join(names)}")
    out = [
        r
        for r in rows
        if r["predictor"] == predictor
        and r["scene"] not in exclude
        and np.isfinite(float(r["mapped"]))
        and np.isfinite(float(r["true"]))
    ]
    if not out:
        raise CoverageError(f"no finite rows of predictor {predictor!r} left")
    return out


def _arrays(rows: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    return np.array([float(r["mapped"]) for r in rows]), np.array([float(r["true"]) for r in rows])


def summary(group: str, interval: ScoreInterval, predicted: np.ndarray, true: np.ndarray) -> dict:
    """One row of :data:`COLUMNS`: coverage, the shares below and above, mean width and bias."""
    lo, hi = interval(predicted)
    return _row(group, predicted, true, lo, hi)


def coverage_width(true: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[float, float]:
    """Share of images whose ``true`` score lies in ``[low, high]``, and the mean width, over the images
    with finite values (NaN, NaN if none): the ``coverage`` and ``width`` of every table here and of
    ``nriqa-evaluate``'s."""
    has = np.isfinite(low) & np.isfinite(high) & np.isfinite(true)
    if not has.any():
        return math.nan, math.nan
    t, lo, hi = true[has], low[has], high[has]
    return float(((lo <= t) & (t <= hi)).mean()), float((hi - lo).mean())


def _row(group: str, predicted: np.ndarray, true: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> dict:
    cover, width = coverage_width(true, lo, hi)
    return {
        "group": group,
        "n": int(predicted.size),
        "coverage": cover,
        "below": float((true < lo).mean()),
        "above": float((true > hi).mean()),
        "width": width,
        "bias": float((predicted - true).mean()),
    }


def check(rows: list[dict], interval: ScoreInterval) -> list[dict]:
    """Coverage pooled, per band of the predicted score, and per scene, of ``rows`` (one predictor)."""
    p, t = _arrays(rows)
    table = [summary("all", interval, p, t)]
    edges, band = interval.edges, interval.band(p)
    for k in range(len(edges) - 1):
        m = band == k
        if m.any():
            table.append(summary(f"score {edges[k]:.2f}-{edges[k + 1]:.2f}", interval, p[m], t[m]))
    scenes = np.array([r["scene"] for r in rows])
    for scene in sorted(set(scenes)):
        m = scenes == scene
        table.append(summary(f"scene {scene}", interval, p[m], t[m]))
    return table


def leave_one_out(rows: list[dict], **fit_kwargs) -> list[dict]:
    """Fit on all scenes but one, cover that one; pooled over the held-out images, then per scene."""
    scenes = np.array([r["scene"] for r in rows])
    p, t = _arrays(rows)
    lo, hi = np.empty_like(p), np.empty_like(p)
    for scene in sorted(set(scenes)):
        m = scenes == scene
        lo[m], hi[m] = ScoreInterval.fit(p[~m], t[~m], **fit_kwargs)(p[m])
    table = [_row("all (each scene held out)", p, t, lo, hi)]
    for scene in sorted(set(scenes)):
        m = scenes == scene
        table.append(_row(f"scene {scene}", p[m], t[m], lo[m], hi[m]))
    return table


def add_interval_ends(rows: list[dict], predictors: list, *, tonemapped: bool) -> None:
    """Give every row ``low`` and ``high``: the ends of its predictor's calibrated interval around ``mapped``.

    For predictors whose scorer carries an interval (``scorer.interval``; shipped weights with a
    ``score_interval`` on their card); NaN for the others. ``tonemapped``: the images went through the
    package's tone map, as EXR renders do (the HDR calibration), rather than another display (the LDR one).
    """
    for p in predictors:
        scorer = getattr(p, "scorer", None)
        own = [r for r in rows if r["predictor"] == p.name]
        if scorer is None or getattr(scorer, "interval", None) is None:
            for r in own:
                r["low"] = r["high"] = float("nan")
            continue
        mapped = np.array([float(r["mapped"]) for r in own], dtype=np.float64)
        low, high = scorer.interval_ends(mapped, [tonemapped] * len(own))
        for r, lo, hi in zip(own, low, high):
            r["low"], r["high"] = float(lo), float(hi)


def _load_interval(args: argparse.Namespace) -> ScoreInterval:
    import json

    from nriqa.inference.pretrained import load_card

    if args.interval:
        try:
            entry = json.loads(Path(args.interval).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise CoverageError(
                f"cannot read the interval {args.interval} ({exc}); give a file 'fit --out' wrote"
            ) from None
        return ScoreInterval.from_dict(entry)
    card, _ = load_card(args.weights, args.dir)
    key = _card_key(args)
    if key not in card:
        raise CoverageError(f"the card of {args.weights!r} has no {key}; fit one first ('fit --weights')")
    return ScoreInterval.from_dict(card[key])


def _card_key(args: argparse.Namespace) -> str:
    return "score_interval_ldr" if args.ldr else "score_interval"


def _write(out: str | None, title: str, table: list[dict]) -> None:
    print(markdown_table(table, COLUMNS), end="")
    if out:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        write_csv(folder / "coverage.csv", table, COLUMNS)
        write_text_atomic(folder / "coverage.md", f"# {title}\n\n" + markdown_table(table, COLUMNS))
        print(f"wrote {folder / 'coverage.md'}")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m nriqa.eval.coverage", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, text in (
        ("fit", "fit the interval; write it to a file (--out) or into a weights' card (--weights)"),
        ("check", "coverage of an interval (--interval FILE or the card of --weights) on the rows"),
        ("cv", "leave one scene out: fit on the others, cover it"),
    ):
        p = sub.add_parser(name, help=text)
        p.add_argument("images", nargs="+", help="images.csv files of nriqa-evaluate runs")
        p.add_argument("--predictor", required=True, help="the predictor's name in the rows, e.g. unet_fast")
        p.add_argument("--exclude-scene", action="append", default=[], metavar="SCENE", help="leave its rows out")
        if name in ("fit", "cv"):
            p.add_argument("--level", type=float, default=0.9, help="two-sided level (default 0.9)")
            p.add_argument("--min-count", type=int, default=30, help="fewest images in a band (default 30)")
        if name == "fit":
            p.add_argument("--source", default="", help="what the calibration images are (kept with the interval)")
            p.add_argument("--out", default=None, help="write the interval as JSON here")
        else:
            p.add_argument("--out", default=None, help="write coverage.{csv,md} into this folder")
        if name in ("fit", "check"):
            p.add_argument("--weights", default=None, help="shipped weights whose card holds (or gets) the interval")
            p.add_argument("--dir", default=None, help="folder of the weights (default: the shipped ones)")
            p.add_argument(
                "--ldr",
                action="store_true",
                help="the card's interval for LDR input (score_interval_ldr) instead of score_interval",
            )
        if name == "check":
            p.add_argument("--interval", default=None, help="a JSON file 'fit --out' wrote")
    return ap


def main(argv: list[str] | None = None) -> int:
    import json

    from nriqa.inference.pretrained import update_card

    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        rows = select([r for f in args.images for r in read_rows(f)], args.predictor, args.exclude_scene)
        if args.cmd == "fit":
            if not args.out and not args.weights:
                raise CoverageError("say where the interval goes: --out FILE.json or --weights NAME")
            p, t = _arrays(rows)
            interval = ScoreInterval.fit(p, t, level=args.level, min_count=args.min_count, source=args.source)
            entry = interval.to_dict()
            if args.out:
                write_text_atomic(Path(args.out), json.dumps(entry, indent=2) + "\n")
                print(f"wrote {args.out}")
            if args.weights:
                print(f"wrote {update_card(args.weights, {_card_key(args): entry}, args.dir)}")
            print(json.dumps(entry))
        elif args.cmd == "check":
            if bool(args.interval) == bool(args.weights):
                raise CoverageError("give the interval to check: --interval FILE.json or --weights NAME (one)")
            _write(args.out, f"Coverage of {args.predictor}'s score interval", check(rows, _load_interval(args)))
        else:
            table = leave_one_out(rows, level=args.level, min_count=args.min_count, edges=EDGES)
            _write(args.out, f"Coverage of {args.predictor}'s score interval, each scene held out", table)
    except NriqaError as exc:
        print(f"{ap.prog}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
