"""Calibrate a scorer's score interval on evaluation rows, and measure how often it covers the truth.

The rows are those of ``nriqa-evaluate``'s ``images.csv`` (one per image and predictor: ``mapped``
against ``true``). Three commands, one predictor at a time::

    # fit on images the weights never learnt; write the interval into the weights' card
    python -m nriqa.eval.coverage fit A/images.csv B/images.csv --predictor unet_fast --weights unet_fast
    # how often the card's interval holds the true mean SSIM on other renders (pooled, per band, per scene)
    python -m nriqa.eval.coverage check C/images.csv --predictor unet_fast --weights unet_fast --out reports/cov
    # leave one scene family out: fit on the others, cover it (the honest in-house figure)
    python -m nriqa.eval.coverage cv A/images.csv B/images.csv --predictor unet_fast
    # along each ladder of renders, stop on the score or on the interval's low end: where does each end?
    python -m nriqa.eval.coverage stops C/images.csv --predictor unet_fast --weights unet_fast --targets 0.9,0.95

``--exclude-scene`` drops a scene's rows (e.g. one whose reference is suspect). ``--ldr`` makes ``fit`` and
``check`` use the card's interval for LDR input (``score_interval_ldr``: fit it on rows of ``nriqa-evaluate
--display ...`` runs), which the Scorer applies to images it takes as LDR. ``--loop uniform|adaptive`` takes
the ``rows.csv`` of ``benchmarks/adaptive_interval.py`` instead (every step of render loops of that kind;
``--predictor single`` or ``two-buffer``, the latter the halves' score carried to the whole image) and the
card's interval for that kind of loop (``score_interval_loop_<kind>``), whose low end the loops' sure stops
use (``fit``, ``check`` and ``cv``). Tables are printed and, with ``--out``, written as ``coverage.{csv,md}``
(``stops.{csv,md}``). Fitting and the interval itself: :class:`nriqa.inference.interval.ScoreInterval`.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from nriqa.errors import NriqaError
from nriqa.eval.paired import read_rows
from nriqa.inference.interval import EDGES, LOOP_KINDS, ScoreInterval, loop_card_key
from nriqa.io.atomic import write_text_atomic
from nriqa.io.tables import markdown_table, read_csv, write_csv

COLUMNS = ["group", "n", "coverage", "below", "above", "width", "bias"]
STOP_COLUMNS = ["target", "rule", "ladders", "stopped", "at or above", "true at the stop", "spp over the truth's"]


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


def read_loop_rows(path: str | Path, kind: str) -> list[dict]:
    """The rows of loops of ``kind`` in a ``rows.csv`` of ``benchmarks/adaptive_interval.py``, as evaluation rows
    (``predictor`` the benchmark's scorer label, ``scene`` the family, ``mapped`` the loop's score)."""
    need = {"scorer", "loop", "family", "score", "true"}
    try:
        rows = read_csv(path, need, "a rows.csv of benchmarks/adaptive_interval.py")
    except ValueError as exc:
        raise CoverageError(str(exc)) from None
    return [dict(r, predictor=r["scorer"], scene=r["family"], mapped=r["score"]) for r in rows if r["loop"] == kind]


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


def ladder_stops(rows: list[dict], interval: ScoreInterval, targets: list[float]) -> list[dict]:
    """Where a stop on the score, and one on the interval's low end, end along ladders of renders.

    A ladder is the images of one (file, scene, variant, algorithm) of ``rows`` (one predictor; ``file``: the
    ``_file`` key, if any) ordered by spp, as a render loop would meet them. Per target, over the ladders whose
    true SSIM reaches it at some rung: the ``score`` rule stops at the first rung whose score reaches the target,
    the ``low end`` rule (``render_until(sure=True)``) at the first whose interval's low end does. Per rule:
    the ladders where it stops at all (``stopped``), those whose true SSIM at the stop is at or above the target,
    its mean, and the geometric mean of the stop's spp over that of the first rung truly at the target.
    """
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r.get("_file", 0), r["scene"], r["variant"], r.get("algorithm", "")), []).append(r)
    table = []
    for target in targets:
        ends: dict[str, list[tuple[float, float]]] = {"score": [], "low end": []}
        reach = 0
        for rungs in groups.values():
            rungs = sorted(rungs, key=lambda r: float(r["spp"]))
            spp = np.array([float(r["spp"]) for r in rungs])
            p, t = _arrays(rungs)
            if not (t >= target).any():
                continue
            reach += 1
            first_true = spp[np.argmax(t >= target)]
            for rule, ok in (("score", p >= target), ("low end", interval(p)[0] >= target)):
                if ok.any():
                    k = int(np.argmax(ok))
                    ends[rule].append((t[k], spp[k] / first_true))
        for rule, got in ends.items():
            true = np.array([g[0] for g in got])
            table.append(
                {
                    "target": target,
                    "rule": rule,
                    "ladders": reach,
                    "stopped": len(got),
                    "at or above": f"{int((true >= target).sum())}/{len(got)}",
                    "true at the stop": float(true.mean()) if got else math.nan,
                    "spp over the truth's": float(np.exp(np.mean(np.log([g[1] for g in got])))) if got else math.nan,
                }
            )
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
    if getattr(args, "loop", None):
        return loop_card_key(args.loop)
    return "score_interval_ldr" if args.ldr else "score_interval"


def _write(out: str | None, title: str, table: list[dict], columns=COLUMNS, stem: str = "coverage") -> None:
    print(markdown_table(table, columns), end="")
    if out:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        write_csv(folder / f"{stem}.csv", table, columns)
        write_text_atomic(folder / f"{stem}.md", f"# {title}\n\n" + markdown_table(table, columns))
        print(f"wrote {folder / f'{stem}.md'}")


def save_interval(entry: dict, out: str | None, card: tuple[str, str, str | None] | None) -> None:
    """Write a fitted interval's ``entry`` to the JSON file ``out`` and/or into a card, ``(weights, key, dir)``;
    print where, then the entry."""
    import json

    from nriqa.inference.pretrained import update_card

    if out:
        write_text_atomic(Path(out), json.dumps(entry, indent=2) + "\n")
        print(f"wrote {out}")
    if card:
        weights, key, folder = card
        print(f"wrote {update_card(weights, {key: entry}, folder)}")
    print(json.dumps(entry))


def _targets(text: str) -> list[float]:
    try:
        targets = [float(x) for x in text.split(",")]
    except ValueError:
        targets = []
    if not targets or not all(0.0 < t < 1.0 for t in targets):
        raise CoverageError(f"--targets must be SSIMs in (0, 1), comma-separated; got {text!r}")
    return targets


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m nriqa.eval.coverage", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, text in (
        ("fit", "fit the interval; write it to a file (--out) or into a weights' card (--weights)"),
        ("check", "coverage of an interval (--interval FILE or the card of --weights) on the rows"),
        ("cv", "leave one scene out: fit on the others, cover it"),
        ("stops", "along each ladder of renders, stop on the score or on the interval's low end; where they end"),
    ):
        p = sub.add_parser(name, help=text)
        p.add_argument("images", nargs="+", help="images.csv files of nriqa-evaluate runs (with --loop: rows.csv)")
        p.add_argument("--predictor", required=True, help="the predictor's name in the rows, e.g. unet_fast")
        p.add_argument("--exclude-scene", action="append", default=[], metavar="SCENE", help="leave its rows out")
        if name != "stops":
            p.add_argument(
                "--loop",
                choices=LOOP_KINDS,
                default=None,
                help="rows of render loops of this kind (adaptive_interval.py's rows.csv); its card key",
            )
        if name in ("fit", "cv"):
            p.add_argument("--level", type=float, default=0.9, help="two-sided level (default 0.9)")
            p.add_argument("--min-count", type=int, default=30, help="fewest images in a band (default 30)")
        if name == "fit":
            p.add_argument("--source", default="", help="what the calibration images are (kept with the interval)")
            p.add_argument("--out", default=None, help="write the interval as JSON here")
        else:
            p.add_argument("--out", default=None, help="write coverage.{csv,md} into this folder")
        if name in ("fit", "check", "stops"):
            p.add_argument("--weights", default=None, help="shipped weights whose card holds (or gets) the interval")
            p.add_argument("--dir", default=None, help="folder of the weights (default: the shipped ones)")
            p.add_argument(
                "--ldr",
                action="store_true",
                help="the card's interval for LDR input (score_interval_ldr) instead of score_interval",
            )
        if name in ("check", "stops"):
            p.add_argument("--interval", default=None, help="a JSON file 'fit --out' wrote")
        if name == "stops":
            p.add_argument("--targets", default="0.9,0.95,0.98", help="target SSIMs, comma-separated")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        loop = getattr(args, "loop", None)
        if loop and getattr(args, "ldr", False):
            raise CoverageError("--loop and --ldr are two different intervals; give one")
        read = (lambda f: read_loop_rows(f, loop)) if loop else read_rows
        rows = [dict(r, _file=i) for i, f in enumerate(args.images) for r in read(f)]
        rows = select(rows, args.predictor, args.exclude_scene)
        if args.cmd == "fit":
            if not args.out and not args.weights:
                raise CoverageError("say where the interval goes: --out FILE.json or --weights NAME")
            p, t = _arrays(rows)
            interval = ScoreInterval.fit(p, t, level=args.level, min_count=args.min_count, source=args.source)
            save_interval(interval.to_dict(), args.out, args.weights and (args.weights, _card_key(args), args.dir))
        elif args.cmd in ("check", "stops"):
            if bool(args.interval) == bool(args.weights):
                raise CoverageError("give the interval to check: --interval FILE.json or --weights NAME (one)")
            if args.cmd == "check":
                title = f"Coverage of {args.predictor}'s score interval"
                _write(args.out, title, check(rows, _load_interval(args)))
            else:
                targets = _targets(args.targets)
                title = f"Stops along ladders: {args.predictor}'s score, and its interval's low end"
                table = ladder_stops(rows, _load_interval(args), targets)
                _write(args.out, title, table, STOP_COLUMNS, "stops")
        else:
            table = leave_one_out(rows, level=args.level, min_count=args.min_count, edges=EDGES)
            _write(args.out, f"Coverage of {args.predictor}'s score interval, each scene held out", table)
    except NriqaError as exc:
        print(f"{ap.prog}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
