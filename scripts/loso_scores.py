"""Keep a leave-one-scene-out plan's per-image scores in the repository, one CSV per held-out family.

A fold is scored by ``nriqa-evaluate DATA/SET --crossval FOLD --scenes FAMILY`` on several sets, one
``images.csv`` each, under ``SCORES/<family>/<set>/images.csv``. Those folders live on the machine that ran
the folds and go with it; this merges each family's sets into ``OUT/<plan>/<family>.csv`` (default
``docs/results/loso``) with the scorer renamed to the plan and each id and variant prefixed by its set
(``s72_v71/...``, ``s72_v71:71``), so the same variant number in two sets stays two ladders. Then::

    python scripts/loso_scores.py /work/logs/s93/LLscore --plan LL
    python -m nriqa.eval.scorecard docs/results/loso/LL/*.csv --by scene

A family whose folder holds no ``images.csv`` yet (its fold still training) is skipped and named. A family
scored on only some of the sets another family was scored on (a set not yet grown to it, a scoring that failed)
is held back and named with the sets it lacks, and the run ends non-zero: merging it would quietly read a part
for the whole. ``--partial`` writes such a family from the sets it has. A file already written is replaced
atomically with the sets found now.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from nriqa.eval.scorecard import NEED
from nriqa.io.tables import read_csv, write_csv

ROOT = Path(__file__).resolve().parents[1]


def scored_sets(family_dir: Path) -> list[Path]:
    """The set folders of one family that hold an ``images.csv``, by name."""
    return sorted(p for p in family_dir.iterdir() if (p / "images.csv").is_file())


def lacking(sets: dict[str, set[str]]) -> dict[str, list[str]]:
    """For each family whose sets are a strict part of another family's, the sets it lacks (from the largest such
    family). Families scored on sets of their own (``blinds`` on its own two) lack nothing."""
    out = {}
    for family, own in sets.items():
        wider = [other for other in sets.values() if own < other]
        if own and wider:
            out[family] = sorted(max(wider, key=len) - own)
    return out


def family_rows(family_dir: Path, plan: str) -> list[dict]:
    """Every image of one family's scoring sets, renamed to ``plan`` and prefixed by its set."""
    rows: list[dict] = []
    for set_dir in scored_sets(family_dir):
        path = set_dir / "images.csv"
        for row in read_csv(path, NEED, "an nriqa-evaluate images.csv"):
            row["predictor"] = plan
            row["id"] = f"{set_dir.name}/{row['id']}"
            row["variant"] = f"{set_dir.name}:{row['variant']}"
            rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scores", type=Path, help="folder of <family>/<set>/images.csv")
    parser.add_argument("--plan", required=True, help="the plan's name: the folder under OUT and the scorer's name")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "loso")
    parser.add_argument(
        "--partial", action="store_true", help="write a family scored on fewer sets than another from those it has"
    )
    args = parser.parse_args(argv)
    if not args.scores.is_dir():
        print(f"error: {args.scores} is not a folder; give the folder of <family>/<set>/images.csv", file=sys.stderr)
        return 2
    if not args.plan or "/" in args.plan or args.plan.startswith("."):
        print(f"error: --plan {args.plan!r} is not a folder name; give e.g. LL", file=sys.stderr)
        return 2
    families = sorted(p for p in args.scores.iterdir() if p.is_dir())
    short = lacking({f.name: {s.name for s in scored_sets(f)} for f in families})
    written = held = 0
    for family_dir in families:
        if family_dir.name in short and not args.partial:
            print(
                f"{family_dir.name}: not scored on {', '.join(short[family_dir.name])} (other families were); "
                "held back: score those sets, or pass --partial to write the sets it has"
            )
            held += 1
            continue
        try:
            rows = family_rows(family_dir, args.plan)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if not rows:
            print(f"{family_dir.name}: no images.csv yet, skipped")
            continue
        target = args.out / args.plan / f"{family_dir.name}.csv"
        target.parent.mkdir(parents=True, exist_ok=True)
        write_csv(target, rows)
        written += 1
        print(f"{family_dir.name}: {len(rows)} images -> {target}")
    if not written and not held:
        print(f"error: no family under {args.scores} has an images.csv; nothing written", file=sys.stderr)
        return 2
    return 1 if held else 0


if __name__ == "__main__":
    sys.exit(main())
