"""Calibrate and check the spread interval (:mod:`nriqa.inference.spread`) on rendered datasets.

    python -m nriqa.eval.spread fit DATA [DATA ...] --weights unet_fast [--level 0.9] [--source TEXT]
        [--out FILE.json] [--write]
    python -m nriqa.eval.spread check DATA [DATA ...] --weights unet_fast [--interval FILE.json] [--out DIR]
    python -m nriqa.eval.spread cv DATA [DATA ...] --weights unet_fast [--level 0.9]

Every test image of each dataset (a root with ``manifest.json``, e.g. ``nriqa-data`` output the weights never
learnt) is scored by the weights as shipped, through the package tone map, with its spread over the eight flips
and turns; its true mean SSIM is measured against the dataset's reference as ``nriqa-evaluate`` does. ``fit``
calibrates a :class:`~nriqa.inference.spread.SpreadInterval` on them (``--write``: into the weights' card as
``score_interval_spread``); ``check`` measures its coverage beside the card's ``score_interval``, pooled and per
family; ``cv`` fits it with each family held out in turn and covers that family. With ``--display`` (repeatable)
the images are shown through those displays and scored as LDR input, for ``score_interval_spread_ldr`` beside
``score_interval_ldr``. ``--pattern`` (and ``--reference``) read folders without a manifest as ``nriqa-evaluate``
does (the external test set). Bad input is one line, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from nriqa.errors import NriqaError
from nriqa.eval.coverage import COLUMNS, _row, _write, save_interval
from nriqa.inference.interval import ScoreInterval
from nriqa.inference.spread import SpreadInterval

if TYPE_CHECKING:
    from nriqa.inference.scorer import Scorer

BATCH = 64  # images of one size scored together


class SpreadError(NriqaError):
    """Datasets or options the spread calibration cannot use."""


def scored(
    roots: list[str],
    scorer: Scorer,
    pattern: str | None = None,
    reference: str | None = None,
    displays: list[str] = (),
    name: str = "the weights",
) -> dict[str, np.ndarray]:
    """``family``, ``true``, ``score``, ``spread`` (and the card interval's ``low``, ``high``) of every test image.

    A root without ``manifest.json`` is read as an external folder of renders by ``pattern`` and ``reference``
    (:mod:`nriqa.io.external`), as ``nriqa-evaluate`` reads one. With ``displays`` (``nriqa-evaluate --display``
    specs) every image is shown through each of them, image and reference alike, and scored as LDR input; the card
    interval compared is then ``score_interval_ldr``. ``scorer``: built with ``spread=True`` and its card's
    intervals (``Scorer.from_pretrained``); ``name``: the weights' name, for the error line."""
    from nriqa.core.display import Display
    from nriqa.eval.dataset import load_dataset, records_of
    from nriqa.io.external import DEFAULT_PATTERN, DEFAULT_REFERENCE

    card_interval = scorer.ldr_interval if displays else scorer.interval
    if card_interval is None:
        key = "score_interval_ldr" if displays else "score_interval"
        raise SpreadError(f"{name} carry no {key} to compare with; fit one first (python -m nriqa.eval.coverage fit)")
    try:
        shows = [Display.parse(d) for d in displays] or [None]
    except ValueError as exc:
        raise SpreadError(f"--display: {exc}") from None
    cols: dict[str, list] = {k: [] for k in ("family", "true", "score", "spread", "low", "high")}
    for root in roots:
        if not (Path(root) / "manifest.json").is_file() and pattern is None:
            raise SpreadError(f"{root}: no manifest.json; give a dataset rendered by nriqa-data, or --pattern")
        found = records_of(root, pattern or DEFAULT_PATTERN, reference or DEFAULT_REFERENCE)
        items = [item for show in shows for item in load_dataset(*found, twins=False, display=show).items]
        for start in range(0, len(items), BATCH):
            chunk = items[start : start + BATCH]
            by_shape: dict[tuple, list] = {}
            for item in chunk:
                by_shape.setdefault(tuple(item.ldr.shape), []).append(item)
            for group in by_shape.values():
                res = scorer(torch.stack([i.ldr for i in group]), hdr=False)
                score, spread = res.score.cpu().numpy(), res.spread.cpu().numpy()
                low, high = card_interval(score.astype(np.float64))  # the card's, as for this kind of input
                for i, item in enumerate(group):
                    for key, value in zip(cols, (item.record.scene, item.true, score[i], spread[i], low[i], high[i])):
                        cols[key].append(value)
    out = {k: np.asarray(v) for k, v in cols.items()}
    keep = np.isfinite(out["true"]) & np.isfinite(out["score"])
    if not keep.any():
        raise SpreadError("no test image with a true score in " + ", ".join(roots))
    return {k: v[keep] for k, v in out.items()}


def _groups(family: np.ndarray, pooled: str) -> list[tuple[str, np.ndarray]]:
    """The rows' groups for a coverage table: all of them (named ``pooled``), then each family's."""
    return [(pooled, np.ones(family.size, bool))] + [(f"family {f}", family == f) for f in sorted(set(family))]


def check(rows: dict[str, np.ndarray], spread_iv: SpreadInterval, card_iv_name: str = "score_interval") -> list[dict]:
    """Coverage of the spread interval and of the card's tone-map interval, pooled and per family."""
    table = []
    lo, hi = spread_iv(rows["score"], rows["spread"])
    for group, m in _groups(rows["family"], "all"):
        for name, a, b in (("spread", lo, hi), (card_iv_name, rows["low"], rows["high"])):
            table.append(_row(f"{group}: {name}", rows["score"][m], rows["true"][m], a[m], b[m]))
    return table


def leave_one_out(rows: dict[str, np.ndarray], level: float, min_count: int = 30) -> list[dict]:
    """Each family's coverage by a spread interval (and a banded one) fitted on the other families."""
    fam, p, t, s = rows["family"], rows["score"], rows["true"], rows["spread"]
    lo, hi, blo, bhi = (np.empty_like(p) for _ in range(4))
    for f in sorted(set(fam)):
        m = fam == f
        lo[m], hi[m] = SpreadInterval.fit(p[~m], t[~m], s[~m], level=level)(p[m], s[m])
        blo[m], bhi[m] = ScoreInterval.fit(p[~m], t[~m], level=level, min_count=min_count)(p[m])
    table = []
    for group, m in _groups(fam, "all (each family held out)"):
        table.append(_row(f"{group}: spread", p[m], t[m], lo[m], hi[m]))
        table.append(_row(f"{group}: banded", p[m], t[m], blo[m], bhi[m]))
    return table


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m nriqa.eval.spread", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for cmd in ("fit", "check", "cv"):
        p = sub.add_parser(cmd)
        p.add_argument("data", nargs="+", help="dataset roots (manifest.json, references)")
        p.add_argument("--weights", default="unet_fast", help="shipped weights (default unet_fast)")
        p.add_argument("--dir", default=None, help="folder of the weights (default: the shipped ones)")
        p.add_argument("--pattern", default=None, help="external folders: name pattern, as nriqa-evaluate's")
        p.add_argument("--reference", default=None, help="external folders: reference glob, as nriqa-evaluate's")
        p.add_argument(
            "--display",
            action="append",
            default=[],
            metavar="D",
            help="score every image through this display as LDR input (repeat; nriqa-evaluate's specs, e.g. srgb+2); "
            "fit --write then writes score_interval_spread_ldr",
        )
        if cmd in ("fit", "cv"):
            p.add_argument("--level", type=float, default=0.9, help="two-sided level (default 0.9)")
        if cmd == "fit":
            p.add_argument("--source", default="", help="what the calibration images are (kept with the interval)")
            p.add_argument("--out", default=None, help="write the interval as JSON here")
            p.add_argument("--write", action="store_true", help="write it into the card (score_interval_spread)")
        else:
            p.add_argument("--out", default=None, help="write spread.{csv,md} into this folder")
        if cmd == "cv":
            p.add_argument("--min-count", type=int, default=30, help="the banded interval's fewest images a band")
        if cmd == "check":
            p.add_argument("--interval", default=None, help="a JSON file 'fit --out' wrote (default: the card's)")
    return ap


def main(argv: list[str] | None = None) -> int:
    from nriqa.inference.scorer import Scorer

    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        if args.cmd == "fit" and not (args.out or args.write):
            raise SpreadError("say where the interval goes: --out FILE.json or --write (the card)")
        scorer = Scorer.from_pretrained(args.weights, dir=args.dir, spread=True)
        rows = scored(args.data, scorer, args.pattern, args.reference, args.display, f"weights {args.weights!r}")
        key = "score_interval_spread_ldr" if args.display else "score_interval_spread"
        if args.cmd == "fit":
            iv = SpreadInterval.fit(rows["score"], rows["true"], rows["spread"], level=args.level, source=args.source)
            save_interval(iv.to_dict(), args.out, args.write and (args.weights, key, args.dir))
        elif args.cmd == "check":
            if args.interval:
                entry = json.loads(Path(args.interval).read_text())
                spread_iv = SpreadInterval.from_dict(entry)
            else:
                spread_iv = scorer.spread_ldr_interval if args.display else scorer.spread_interval
                if spread_iv is None:
                    raise SpreadError(f"weights {args.weights!r} carry no {key}; give --interval")
            card_key = "score_interval_ldr" if args.display else "score_interval"
            title = f"Coverage of {args.weights}'s spread interval beside its {card_key}"
            _write(args.out, title, check(rows, spread_iv, card_key), COLUMNS, "spread")
        else:
            title = f"Coverage of {args.weights}'s spread interval, each family held out"
            _write(args.out, title, leave_one_out(rows, args.level, args.min_count), COLUMNS, "spread")
    except (NriqaError, OSError, json.JSONDecodeError) as exc:
        print(f"{ap.prog}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
