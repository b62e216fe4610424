"""Evaluate no-reference predictors against the true SSIM: tables, scatter plots, map figures.

Thesis tables 5.4 and 5.8, fig. 5.9.
``nriqa-evaluate DATA --out DIR [--model NAME] [--checkpoint PATH] [--baselines all] [--scenes S ...]``

DATA is a dataset root with a manifest (:mod:`nriqa.io.manifest`) or an external folder of renders
(:mod:`nriqa.io.external`), loaded by :mod:`nriqa.eval.dataset`. Every ``test`` image is scored by
every predictor -- shipped weights, checkpoints and cross-validation runs through
:mod:`nriqa.eval.predictors`, and the baselines of :mod:`nriqa.eval.baselines`.

* True score: the mean of :func:`nriqa.core.ssim.ssim_map` of the tone-mapped image against its
  tone-mapped reference; true map: that SSIM map. ``--display srgb+2:8`` (a
  :class:`nriqa.core.display.Display`) shows linear EXR renders through that pipeline instead, the
  image and its reference alike, and every predictor reads and the truth is measured after it.
* Image level, per scene and pooled over scenes: PCC, SROCC, Kendall tau of the predicted vs the
  true score (:mod:`nriqa.core.correlation`), taken on the score signed so that higher = better, and
  the MAE of the predicted vs the true score. Predictors on the SSIM scale enter the MAE as they
  are; raw scores through a monotone map (:mod:`nriqa.eval.baselines.mapping`) fitted on the other scenes.
* Pixel level: PCC of predicted vs true maps over a fixed subset of :data:`PIXELS_PER_MAP` pixels
  per image (:func:`nriqa.core.sampling.metric_samples`).
* Leave-one-scene-out: every fitted part (NIQE's model, BRISQUE's regressor, the monotone maps)
  is fitted on the scenes other than the one it is evaluated on.

Writes ``comparison.{csv,md}`` (rows = predictors), ``per_scene.{csv,md}``, ``images.csv``,
``monotone.{csv,md}`` (whether SSIM-scale predictions rise with spp, :mod:`nriqa.eval.monotone`),
``by_spp.{csv,md}`` (MAE and bias per band of spp, :mod:`nriqa.eval.by_spp`),
``scatter.png`` and ``maps_<predictor>_<scene>.png`` (noisy | predicted | true | reference)
(:mod:`nriqa.eval.plots`); with ``--base NAME``, ``paired.{csv,md}``: every other predictor's MAE
against that one's on the same images, with a cluster-bootstrap interval (:mod:`nriqa.eval.paired`).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import torch

from nriqa.core.correlation import pcc
from nriqa.core.display import Display
from nriqa.core.sampling import metric_samples
from nriqa.eval.baselines import Item, Prediction, Predictor, baseline_names
from nriqa.eval.baselines.mapping import MonotoneMap
from nriqa.eval.by_spp import COLUMNS as SPP_COLUMNS
from nriqa.eval.by_spp import by_spp
from nriqa.eval.coverage import add_interval_ends, coverage_width
from nriqa.eval.dataset import Dataset, EvaluationError, load_dataset, records_of
from nriqa.eval.monotone import LADDER_COLUMNS, SUMMARY_COLUMNS, monotonicity
from nriqa.eval.paired import paired_table, write_paired
from nriqa.eval.plots import figure_items, plot_maps, plot_scatter
from nriqa.eval.predictors import build_predictors
from nriqa.eval.sample_counts import count_as_rendered
from nriqa.io.atomic import write_text_atomic
from nriqa.io.exr import ImageReadError
from nriqa.io.external import DEFAULT_PATTERN, DEFAULT_REFERENCE, ExternalError
from nriqa.io.manifest import ManifestError
from nriqa.io.tables import markdown_table, write_csv
from nriqa.training.checkpoint import CheckpointError
from nriqa.training.metrics import correlations

PIXELS_PER_MAP = 1024
COMPARISON_COLUMNS = [
    "predictor",
    "scale",
    "fitted",
    "n",
    "pcc",
    "srocc",
    "tau",
    "mae",
    "bias",
    "pixel_pcc",
    "scene_pcc",
    "scene_srocc",
    "coverage",
    "width",
]
SCENE_COLUMNS = ["predictor", "scene", "n", "pcc", "srocc", "tau", "mae", "bias", "pixel_pcc", "coverage", "width"]
IMAGE_COLUMNS = [
    "predictor",
    "id",
    "scene",
    "variant",
    "algorithm",
    "spp",
    "true",
    "predicted",
    "mapped",
    "low",
    "high",
]


def signed(p: Predictor, x):
    """``x`` signed so that higher means better for predictor ``p``."""
    return x if p.higher_is_better else -x


def pixel_samples(predicted: torch.Tensor, true: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The :data:`PIXELS_PER_MAP` fixed pixels of a predicted ``(H, W)`` map and of the true one, ``(N,)`` each."""
    return metric_samples(predicted[None, None], true[None, None], PIXELS_PER_MAP)


def _correlations(pred: np.ndarray, true: np.ndarray) -> dict[str, float]:
    ok = np.isfinite(pred) & np.isfinite(true)
    return correlations(torch.from_numpy(pred[ok]), torch.from_numpy(true[ok]), undefined=math.nan)


class _Scores:
    """One predictor's predictions for one held-out scene: fitted on the others, cached when not fitted."""

    def __init__(self, p: Predictor, train: list[Item], train_refs: list, cache: dict) -> None:
        self.p, self.cache = p, cache
        self.usable = not p.fitted or bool(train)
        if p.fitted and train:
            p.fit(train, train_refs)

    def __call__(self, item: Item) -> Prediction:
        if not self.usable:
            return Prediction(math.nan)
        if self.p.fitted:
            return self.p.predict(item)
        key = (id(self.p), item.record.id)
        if key not in self.cache:
            self.cache[key] = self.p.predict(item)
        return self.cache[key]


def run_predictors(data: Dataset, predictors: list[Predictor], scenes: list[str]) -> tuple[list[dict], dict, dict]:
    """Score the images of ``scenes`` with every predictor, leave-one-scene-out for fitted parts.

    Returns:
        ``(rows, pixels, maps)``: one row per (predictor, image) with ``true``, ``predicted`` (raw)
        and ``mapped`` (SSIM scale); ``pixels[(predictor, scene)] = (pred, true)`` pixel samples
        (signed so higher = better); ``maps[(predictor, id)]`` the predicted maps of SSIM-scale predictors.
    """
    rows, pixels, maps = [], {}, {}
    cache: dict[tuple[int, str], Prediction] = {}
    for scene in scenes:
        test = [it for it in data.items if it.record.scene == scene]
        train = [it for it in data.items if it.record.scene != scene]
        train_refs = [data.refs[p] for p in sorted({it.record.reference for it in train})]
        for p in predictors:
            predict = _Scores(p, train, train_refs, cache)
            preds = [predict(it) for it in test]
            raw = np.array([pr.score for pr in preds], dtype=float)
            if p.scale == "ssim":
                mapped = raw
            elif train and predict.usable:
                fitted = np.array([predict(it).score for it in train])
                mapped = MonotoneMap().fit(fitted, np.array([it.true for it in train]))(raw)
            else:
                mapped = np.full_like(raw, math.nan)
            pix_pred, pix_true = [], []
            for it, pr, r, m in zip(test, preds, raw, mapped):
                rec = it.record
                rows.append(
                    {
                        "predictor": p.name,
                        "id": rec.id,
                        "scene": rec.scene,
                        "variant": rec.variant,
                        "algorithm": rec.algorithm,
                        "spp": rec.spp,
                        "true": it.true,
                        "predicted": float(r),
                        "mapped": float(m),
                    }
                )
                if pr.map is not None:
                    a, b = pixel_samples(signed(p, pr.map), data.true_maps[rec.id])
                    pix_pred.append(a)
                    pix_true.append(b)
                    if p.scale == "ssim":
                        maps[(p.name, rec.id)] = pr.map
            if pix_pred:
                pixels[(p.name, scene)] = (torch.cat(pix_pred), torch.cat(pix_true))
    return rows, pixels, maps


def summarise(
    rows: list[dict], pixels: dict, predictors: list[Predictor], scenes: list[str]
) -> tuple[list[dict], list[dict]]:
    """``(comparison, per_scene)`` tables: per predictor pooled over scenes, and per predictor and scene."""
    comparison, per_scene = [], []
    for p in predictors:
        own = [r for r in rows if r["predictor"] == p.name]
        scene_rows = []
        for scene in scenes:
            sel = [r for r in own if r["scene"] == scene]
            scene_rows.append({"predictor": p.name, "scene": scene, **_stats(p, sel, [pixels.get((p.name, scene))])})
        per_scene.extend(scene_rows)
        pooled = _stats(p, own, [pixels.get((p.name, s)) for s in scenes])
        comparison.append(
            {
                "predictor": p.name,
                "scale": p.scale,
                "fitted": "loso" if p.fitted else "",
                **pooled,
                "scene_pcc": _nanmean([r["pcc"] for r in scene_rows]),
                "scene_srocc": _nanmean([r["srocc"] for r in scene_rows]),
            }
        )
    return comparison, per_scene


def _nanmean(values: list[float]) -> float:
    values = [v for v in values if math.isfinite(v)]
    return float(np.mean(values)) if values else math.nan


def _stats(p: Predictor, rows: list[dict], pixel_parts: list) -> dict:
    pred = np.array([r["predicted"] for r in rows], dtype=float)
    mapped = np.array([r["mapped"] for r in rows], dtype=float)
    true = np.array([r["true"] for r in rows], dtype=float)
    out = {"n": int(np.isfinite(pred).sum()), **_correlations(signed(p, pred), true)}
    err = mapped - true
    err = err[np.isfinite(err)]
    out["mae"] = float(np.abs(err).mean()) if err.size else math.nan
    out["bias"] = float(err.mean()) if err.size else math.nan  # > 0: reads images too good
    parts = [x for x in pixel_parts if x is not None]
    low = np.array([r.get("low", math.nan) for r in rows], dtype=float)
    high = np.array([r.get("high", math.nan) for r in rows], dtype=float)
    out["coverage"], out["width"] = coverage_width(true, low, high)
    out["pixel_pcc"] = math.nan
    if parts:
        a, b = torch.cat([x[0] for x in parts]).double(), torch.cat([x[1] for x in parts]).double()
        out["pixel_pcc"] = pcc(a, b) if a.numel() >= 2 else math.nan
    return out


def _write_tables(
    out: Path,
    root: Path,
    rows: list[dict],
    comparison: list[dict],
    per_scene: list[dict],
    n_images: int,
    scenes: list[str],
    monotone: tuple[list[dict], list[dict]] | None = None,
    display: Display | None = None,
) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "comparison.csv", comparison, COMPARISON_COLUMNS)
    write_csv(out / "per_scene.csv", per_scene, SCENE_COLUMNS)
    write_csv(out / "images.csv", rows, IMAGE_COLUMNS)
    bands = by_spp(rows, [c["predictor"] for c in comparison])
    write_csv(out / "by_spp.csv", bands, SPP_COLUMNS)
    shown = f"Shown through the display `{display}` (image and reference alike). " if display else ""
    header = (
        f"# Evaluation on {root}\n\n{n_images} test images, scenes: {', '.join(scenes)}. {shown}Image level: predicted "
        "vs true mean SSIM (correlations of the score signed so that higher = better; MAE on the SSIM scale, raw "
        "scores through a monotone map fitted on the other scenes; bias: mean of predicted minus true, > 0 reads "
        "the images too good). Pixel level: PCC of the maps. `loso`: fitted leave-one-scene-out. `coverage`: share "
        "of images whose true mean SSIM lies in the scorer's calibrated interval, `width` its mean width (scorers "
        "whose weights carry one; nriqa.eval.coverage).\n\n"
    )
    write_text_atomic(out / "comparison.md", header + markdown_table(comparison, COMPARISON_COLUMNS))
    write_text_atomic(out / "per_scene.md", header + markdown_table(per_scene, SCENE_COLUMNS))
    write_text_atomic(
        out / "by_spp.md",
        header
        + "By band of samples per pixel (`true`: the band's mean true SSIM).\n\n"
        + markdown_table(bands, SPP_COLUMNS),
    )
    if monotone is not None:
        per_ladder, summary = monotone
        write_csv(out / "monotone.csv", per_ladder, LADDER_COLUMNS)
        write_text_atomic(
            out / "monotone.md",
            "# Monotone in samples?\n\nPer (scene, variant, algorithm) ladder: the largest rung-to-rung fall of "
            "the predicted mean SSIM, and the lowest prediction where the true SSIM is >= 0.98. A ladder passes "
            "with no fall above 0.01 and no such prediction below 0.96 (nriqa.eval.monotone).\n\n"
            + markdown_table(summary, SUMMARY_COLUMNS)
            + "\n"
            + markdown_table(per_ladder, LADDER_COLUMNS),
        )


def _write_figures(
    out: Path, data: Dataset, rows: list[dict], maps: dict, predictors: list[Predictor], scenes: list[str]
) -> None:
    plot_scatter(out / "scatter.png", rows, predictors)
    for p in predictors:
        if p.scale != "ssim":
            continue
        for scene in scenes:
            chosen = [it for it in figure_items(data.items, scene) if (p.name, it.record.id) in maps]
            if chosen:
                plot_maps(out / f"maps_{p.name.replace('/', '_')}_{scene}.png", data, chosen, maps, p.name)


def evaluate(
    data_dir: str | Path,
    out: str | Path,
    predictors: list[Predictor],
    scenes: list[str] | None = None,
    algorithms: str = "*",
    pattern: str = DEFAULT_PATTERN,
    reference: str = DEFAULT_REFERENCE,
    figures: bool = True,
    display: Display | None = None,
    base: str | None = None,
    square: str = "",
) -> tuple[list[dict], list[dict]]:
    """Run the whole evaluation and write its tables and figures into ``out``; returns ``(comparison, per_scene)``.

    ``display``: show linear renders through it (:mod:`nriqa.eval.dataset`); ``None`` or the plain
    tone map load images as prediction does. ``base``: the name of one of ``predictors``; every
    other is compared with it image by image (``paired.{csv,md}``). ``square``: comma-separated globs of
    algorithms whose sampler rounds its count up to a power of four; their images are counted at the count
    rendered (:mod:`nriqa.eval.sample_counts`).
    """
    names = [p.name for p in predictors]
    if base is not None and base not in names:
        raise EvaluationError(f"--base {base}: not one of the predictors ({', '.join(names)}); name one of them")
    if base is not None and len(names) < 2:
        raise EvaluationError(f"--base {base}: nothing to compare it with; add another --model or --checkpoint")
    display = None if display == Display() else display
    root, records = records_of(data_dir, pattern, reference)
    data = load_dataset(root, records, algorithms, display=display)
    present = sorted({it.record.scene for it in data.items})
    unknown = [s for s in scenes or [] if s not in present]
    if unknown:
        raise EvaluationError(f"unknown scene(s) {', '.join(unknown)}; the dataset has: {', '.join(present)}")
    eval_scenes = scenes or present
    rows, pixels, maps = run_predictors(data, predictors, eval_scenes)
    rows = count_as_rendered(rows, square)
    add_interval_ends(rows, predictors, tonemapped=display is None)
    comparison, per_scene = summarise(rows, pixels, predictors, eval_scenes)
    n_images = len([r for r in rows if r["predictor"] == predictors[0].name])
    ssim_names = [p.name for p in predictors if p.scale == "ssim"]
    monotone = monotonicity(rows, ssim_names) if ssim_names else None
    _write_tables(Path(out), root, rows, comparison, per_scene, n_images, eval_scenes, monotone, display)
    if base is not None:
        write_paired(Path(out), paired_table(rows, base, names))
    if figures:
        _write_figures(Path(out), data, rows, maps, predictors, eval_scenes)
    return comparison, per_scene


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("data", help="dataset root (with manifest.json) or an external folder of renders")
    parser.add_argument("--out", required=True, help="output folder for tables and figures")
    parser.add_argument("--model", action="append", default=[], help="shipped weights name (repeatable)")
    parser.add_argument(
        "--checkpoint",
        action="append",
        default=[],
        help="training checkpoint (repeatable); A.ckpt+B.ckpt scores with the mean of their maps (runs of one recipe)",
    )
    parser.add_argument(
        "--crossval",
        action="append",
        default=[],
        help="cross-validation run dir (reports/crossval/NAME): each scene scored by the fold that "
        "held it out (repeatable)",
    )
    parser.add_argument(
        "--window",
        type=int,
        default=None,
        help="checkpoints and --crossval folds: read images larger than this in independent pieces of this "
        "side (0: whole), as shipped unet_fast does with 64 (default: what each checkpoint states)",
    )
    parser.add_argument(
        "--overlap",
        action="store_true",
        help="also score every shipped model and checkpoint read in windows (unet_fast) with overlapping, blended "
        "windows, as a row NAME-overlap (Scorer(overlap=True))",
    )
    parser.add_argument(
        "--baselines", default="all", help=f"'all', 'none' or a comma list of {', '.join(baseline_names())}"
    )
    parser.add_argument("--scenes", nargs="+", help="evaluate only these scenes (e.g. the held-out scene of a fold)")
    parser.add_argument(
        "--algorithms", default="*", help="comma-separated globs of algorithms to evaluate (default all)"
    )
    parser.add_argument(
        "--pattern", default=DEFAULT_PATTERN, help="external folders: name pattern (see nriqa.io.external)"
    )
    parser.add_argument(
        "--reference", default=DEFAULT_REFERENCE, help="external folders: reference glob or highest:ALGO"
    )
    parser.add_argument(
        "--display",
        default=None,
        help="show linear EXR renders through this display pipeline, image and reference alike, before "
        "scoring and measuring: CURVE[+-STOPS][:BITS], CURVE tonemap|srgb|gamma22, stops from the "
        "reference's key exposure, e.g. srgb, srgb+2, gamma22-1:8 (default: the package tone map)",
    )
    parser.add_argument(
        "--base",
        default=None,
        help="a predictor's name (e.g. unet_fast): compare every other with it image by image, paired.{csv,md}",
    )
    parser.add_argument(
        "--square-spp",
        default="",
        metavar="ALGORITHMS",
        help="comma-separated globs of algorithms whose sampler rounds the count up to a power of four (Mitsuba's "
        "ldsampler, multijitter): count their images at the count rendered, e.g. 2 and 4 as 4 (default: none)",
    )
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch CPU threads (default 1: per-image work is small, more threads mostly contend)",
    )
    return parser


def main(argv: list[str] | None = None) -> None:
    args = _parser().parse_args(argv)
    scenes = [s for arg in args.scenes or [] for s in arg.split(",") if s]
    threads = torch.get_num_threads()
    torch.set_num_threads(max(1, args.threads))
    try:
        display = Display.parse(args.display) if args.display is not None else None
        predictors = build_predictors(
            args.model, args.checkpoint, args.baselines, args.crossval, args.window, args.overlap
        )
        comparison, _ = evaluate(
            args.data,
            args.out,
            predictors,
            scenes,
            args.algorithms,
            args.pattern,
            args.reference,
            not args.no_figures,
            display,
            args.base,
            args.square_spp,
        )
    except (EvaluationError, ExternalError, ManifestError, ImageReadError, CheckpointError) as exc:
        sys.exit(f"error: {exc}")
    except ValueError as exc:  # unknown baseline / shipped weights, scorer input errors: all one-line messages
        sys.exit(f"error: {exc}")
    finally:
        torch.set_num_threads(threads)
    print(markdown_table(comparison, COMPARISON_COLUMNS), end="")
    print(f"wrote {Path(args.out) / 'comparison.md'}")


if __name__ == "__main__":
    main()
