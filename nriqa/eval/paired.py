"""Does one scorer err less than another on the same images? The paired cluster bootstrap.

Two scorers' MAEs on one test set differ by a few thousandths, about what two seeds of one recipe
differ by, and two separate intervals cannot tell such a difference from noise. Compared image by
image it can be told: for every test image scored by both, ``|candidate - truth| - |base - truth|``,
and its mean over the images. The images of one scene variant are not independent (one camera, one
light, one ladder of the same noise), so the interval resamples whole *clusters* -- every
``(scene, variant)`` -- with replacement: :data:`RESAMPLES` draws, ``numpy.random.default_rng(seed)``,
the percentile interval at 95 %. A candidate that errs less has a negative difference whose upper
end is below 0 too.

From the rows of :func:`nriqa.eval.evaluate.run_predictors` (or an ``images.csv`` it wrote), every
predictor on the SSIM scale against a ``base`` one: ``nriqa-evaluate ... --base NAME`` writes
``paired.{csv,md}``; ``python -m nriqa.eval.paired reports/eval/images.csv --base NAME`` re-reads
an earlier evaluation.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from nriqa.core.correlation import check_bootstrap, percentile_bounds
from nriqa.errors import NriqaError
from nriqa.io.atomic import write_text_atomic
from nriqa.io.tables import markdown_table, read_csv, write_csv

RESAMPLES = 2000
LEVEL = 0.95
COLUMNS = ["predictor", "base", "n", "clusters", "mae", "base_mae", "diff", "low", "high", "better"]


class PairedError(NriqaError):
    """Rows that cannot be paired: a predictor missing, no image scored by both."""


def _errors(rows: list[dict], name: str) -> dict[str, tuple[tuple, float]]:
    """``id -> ((scene, variant), |mapped - true|)`` of ``name``'s finite rows."""
    out = {}
    for r in rows:
        if r["predictor"] != name:
            continue
        err = float(r["mapped"]) - float(r["true"])
        if math.isfinite(err):
            out[str(r["id"])] = ((str(r["scene"]), str(r["variant"])), abs(err))
    return out


def paired_difference(
    rows: list[dict], base: str, candidate: str, *, resamples: int = RESAMPLES, level: float = LEVEL, seed: int = 0
) -> dict:
    """The paired difference in MAE of ``candidate`` minus ``base`` over the images both scored.

    Returns a row of :data:`COLUMNS`: ``n`` images, ``clusters`` (scene, variant) groups, both MAEs,
    ``diff`` (candidate - base), ``low``/``high`` its cluster-bootstrap interval, and ``better``
    (the interval wholly below 0). Deterministic for a ``seed``.
    """
    try:
        check_bootstrap(resamples, level, "paired_difference")
    except ValueError as exc:
        raise PairedError(str(exc)) from None
    names = {r["predictor"] for r in rows}
    for name in (base, candidate):
        if name not in names:
            raise PairedError(f"no rows of predictor {name!r}; the rows have: {', '.join(sorted(names))}")
    a, b = _errors(rows, candidate), _errors(rows, base)
    ids = sorted(set(a) & set(b))
    if not ids:
        raise PairedError(f"no image scored (finitely) by both {candidate!r} and {base!r}")
    keys = sorted({a[i][0] for i in ids})
    index = {k: j for j, k in enumerate(keys)}
    cluster = np.array([index[a[i][0]] for i in ids])
    ea = np.array([a[i][1] for i in ids])
    eb = np.array([b[i][1] for i in ids])
    sums = np.bincount(cluster, weights=ea - eb, minlength=len(keys))
    counts = np.bincount(cluster, minlength=len(keys)).astype(float)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, len(keys), size=(resamples, len(keys)))
    low, high = percentile_bounds(sums[draws].sum(axis=1) / counts[draws].sum(axis=1), level)
    return {
        "predictor": candidate,
        "base": base,
        "n": len(ids),
        "clusters": len(keys),
        "mae": float(ea.mean()),
        "base_mae": float(eb.mean()),
        "diff": float((ea - eb).mean()),
        "low": float(low),
        "high": float(high),
        "better": bool(high < 0.0),
    }


def paired_table(rows: list[dict], base: str, candidates: list[str], **kwargs) -> list[dict]:
    """:func:`paired_difference` of every candidate other than ``base`` against it."""
    return [paired_difference(rows, base, c, **kwargs) for c in candidates if c != base]


def write_paired(out: Path, table: list[dict]) -> None:
    """``paired.csv`` and ``paired.md`` in ``out``."""
    write_csv(out / "paired.csv", table, COLUMNS)
    write_text_atomic(
        out / "paired.md",
        "# Paired error against a base scorer\n\nPer predictor, over the test images both scored: `mae` and "
        "`base_mae` (on the SSIM scale), `diff` = the mean of |predictor - truth| - |base - truth|, and its "
        f"{LEVEL:.0%} cluster-bootstrap interval [`low`, `high`] ({RESAMPLES} resamples of the (scene, variant) "
        "clusters, seed 0). `better`: the interval lies wholly below 0 (nriqa.eval.paired).\n\n"
        + markdown_table(table, COLUMNS, digits=5),
    )


def read_rows(path: str | Path) -> list[dict]:
    """The rows of an ``images.csv`` written by ``nriqa-evaluate``."""
    need = {"predictor", "id", "scene", "variant", "true", "mapped"}
    try:
        rows = read_csv(path, need, "an nriqa-evaluate images.csv")
    except ValueError as exc:
        raise PairedError(str(exc)) from None
    for r in rows:
        for key in ("true", "mapped"):
            try:
                r[key] = float(r[key]) if r[key] != "" else math.nan
            except ValueError:
                raise PairedError(f"{path}: {key} value {r[key]!r} of image {r['id']} is not a number") from None
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("images", help="images.csv of an nriqa-evaluate run that scored the base and the candidates")
    parser.add_argument("--base", required=True, help="the predictor the others are compared with")
    parser.add_argument("--out", default=None, help="write paired.{csv,md} here (default: beside images.csv)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the resampling (default 0)")
    args = parser.parse_args(argv)
    try:
        rows = read_rows(args.images)
        names = list(dict.fromkeys(r["predictor"] for r in rows))
        table = paired_table(rows, args.base, names, seed=args.seed)
        if not table:
            raise PairedError(f"{args.images}: no predictor other than {args.base!r} to compare")
        out = Path(args.out) if args.out else Path(args.images).parent
        out.mkdir(parents=True, exist_ok=True)
        write_paired(out, table)
    except PairedError as exc:
        sys.exit(f"error: {exc}")
    print(markdown_table(table, COLUMNS, digits=5), end="")
    print(f"wrote {out / 'paired.md'}")


if __name__ == "__main__":
    main()
