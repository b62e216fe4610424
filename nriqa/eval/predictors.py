"""Learned scorers as evaluation predictors: shipped weights, checkpoints and cross-validation runs.

Each is a :class:`nriqa.eval.baselines.Predictor` over a :class:`nriqa.inference.scorer.Scorer`,
so evaluation compares them with the baselines row by row; :func:`build_predictors` turns the
command line's ``--model``, ``--checkpoint``, ``--crossval`` and ``--baselines`` into the list.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import torch

from nriqa.eval.baselines import Item, Prediction, Predictor, baseline_names, create_baseline
from nriqa.eval.dataset import EvaluationError


class ScorerPredictor(Predictor):
    """A learned scorer as a :class:`Predictor`: ``scorer(ldr, hdr=False)`` gives the map and the score.

    ``scorer`` is any callable ``(3, H, W) LDR -> result`` with ``.map (H, W)``, ``.score`` and
    ``.quantity`` (``"ssim"``: SSIM scale, higher = better; ``"mae"``: raw, lower = better), such as
    :class:`nriqa.inference.scorer.Scorer`.
    """

    fitted = False

    def __init__(self, name: str, scorer) -> None:
        self.name = name
        self.scorer = scorer
        quantity = getattr(scorer, "quantity", "ssim")
        self.scale = "ssim" if quantity == "ssim" else "raw"
        self.higher_is_better = quantity == "ssim"

    def scorer_for(self, item: Item):
        """The scorer that scores ``item``."""
        return self.scorer

    def predict(self, item: Item) -> Prediction:
        scorer = self.scorer_for(item)
        extra = {}
        if getattr(scorer, "needs_twin", False):
            extra["twin"] = item.twin
        if getattr(scorer, "needs_albedo", False):
            extra["albedo"] = item.albedo
        if any(v is None for v in extra.values()):  # a scorer cannot score an image without the inputs it takes
            return Prediction(math.nan, None)
        result = scorer(item.ldr, hdr=False, **extra)
        return Prediction(float(result.score), torch.as_tensor(result.map).float())


def split_joined(arg: str | Path) -> list[str]:
    """The runs an argument joins with ``+``; a path that exists is one run even if its name holds ``+``."""
    return [str(arg)] if Path(arg).exists() else str(arg).split("+")


def checkpoints_scorer(ckpts: list[str | Path], window: int | None = None):
    """The Scorer of one checkpoint, or of the mean of several checkpoints' maps (:class:`MapMean`)."""
    from nriqa.inference.scorer import Scorer
    from nriqa.models.map_mean import MapMean
    from nriqa.training.checkpoint import load_net_from_checkpoint

    if len(ckpts) == 1:
        return Scorer.from_checkpoint(ckpts[0], window=window)
    return Scorer(MapMean([load_net_from_checkpoint(p) for p in ckpts], window).eval(), window=window)


def fold_checkpoints(run: str | Path) -> dict[str, Path]:
    """Each fold's ``last.ckpt`` of a cross-validation run (``nriqa-crossval``), by the scene it held out.

    Raises:
        EvaluationError: the run has no finished fold.
    """
    run = Path(run)
    ckpts = {p.parents[1].name: p for p in sorted(run.glob("folds/*/checkpoints/last.ckpt"))}
    if not ckpts:
        raise EvaluationError(f"{run}: no folds/<scene>/checkpoints/last.ckpt; run nriqa-crossval first")
    return ckpts


class CrossvalPredictor(ScorerPredictor):
    """A cross-validation run (``nriqa-crossval``) as one predictor.

    Each image is scored by the fold that held its scene out, with that fold's ``last.ckpt`` (the
    end of training, so no checkpoint was chosen by the held-out scene's loss; runs made before
    :mod:`nriqa.training.last_checkpoint` under Lightning >= 2.6 hold a copy of the best one there). ``window``: as
    :class:`nriqa.inference.scorer.Scorer`'s (``None``: what each checkpoint's network states).
    ``run_dir`` may join several runs of one recipe with ``+`` (e.g. two seeds): each scene is then
    scored by the mean of their folds' maps (:class:`nriqa.models.map_mean.MapMean`).
    """

    def __init__(self, run_dir: str | Path, window: int | None = None) -> None:
        runs = [Path(p) for p in split_joined(run_dir)]
        self.run_dir = Path(run_dir)  # as given: several runs joined with "+" are named together in errors
        folds = []
        for run in runs:
            folds.append(fold_checkpoints(run))
        scenes = sorted(set.intersection(*(set(f) for f in folds)))
        if not scenes:
            raise EvaluationError(f"{run_dir}: the runs hold out no scene in common")
        self.scorers = {scene: checkpoints_scorer([f[scene] for f in folds], window) for scene in scenes}
        super().__init__("+".join(run.name for run in runs) + "-cv", next(iter(self.scorers.values())))

    def scorer_for(self, item: Item):
        scene = item.record.scene
        if scene not in self.scorers:
            folds = ", ".join(self.scorers)
            raise EvaluationError(f"{self.run_dir}: no fold holds scene {scene} out (folds: {folds})")
        return self.scorers[scene]


def blended(scorer):
    """A copy of ``scorer`` that reads its windows overlapping and blended (the same network)."""
    out = copy.copy(scorer)
    out.overlap = True
    return out


def checkpoint_names(paths: list[str]) -> list[str]:
    """Short distinct row labels for checkpoints: the fewest trailing path parts that tell them apart.

    ``runs/a/checkpoints/last.ckpt`` and ``runs/b/checkpoints/last.ckpt`` become ``a/last`` and ``b/last``
    (folders named ``checkpoints`` are skipped).
    """
    parts = [[q for q in Path(p).with_suffix("").parts if q != "checkpoints"] for p in paths]
    for k in range(1, max((len(q) for q in parts), default=1) + 1):
        names = ["/".join(q[-k:]) for q in parts]
        if len(set(names)) == len(names):
            return names
    return [f"{n}#{i}" for i, n in enumerate(names)]


def _baseline_list(baselines: str) -> list[str]:
    if baselines == "all":
        return baseline_names()
    if baselines == "none":
        return []
    return [b.strip() for b in baselines.split(",") if b.strip()]


def build_predictors(
    models: list[str],
    checkpoints: list[str],
    baselines: str,
    crossval: list[str] = (),
    window: int | None = None,
    overlap: bool = False,
) -> list[Predictor]:
    """Learned scorers (cross-validation runs, shipped ``models``, ``checkpoints``) then the baselines.

    ``baselines`` is ``all``, ``none`` or a comma list of :func:`nriqa.eval.baselines.baseline_names`.
    ``window`` applies to checkpoints and cross-validation folds (``None``: what their networks
    state); shipped weights keep the window their spec states. A checkpoint may join several with
    ``+`` (runs of one recipe with different seeds): it is then scored by the mean of their maps.
    ``overlap``: every shipped model and checkpoint read in windows is scored a second time with
    overlapping, blended windows (``Scorer(overlap=True)``), as a row named ``NAME-overlap``.

    Raises:
        EvaluationError: nothing to evaluate, or two predictors with the same name.
        ValueError: an unknown baseline or shipped weights name; CheckpointError for a bad checkpoint.
    """
    predictors: list[Predictor] = [CrossvalPredictor(run, window) for run in crossval]
    if models or checkpoints:
        from nriqa.inference.scorer import Scorer

        predictors += [ScorerPredictor(name, Scorer.from_pretrained(name)) for name in models]
        joined = [split_joined(c) for c in checkpoints]
        paths = list(dict.fromkeys(p for parts in joined for p in parts))
        short = dict(zip(paths, checkpoint_names(paths)))
        for parts in joined:
            name = "+".join(short[p] for p in parts)
            predictors.append(ScorerPredictor(name, checkpoints_scorer(parts, window)))
        if overlap:
            predictors += [
                ScorerPredictor(f"{p.name}-overlap", blended(p.scorer))
                for p in list(predictors)
                if not isinstance(p, CrossvalPredictor) and p.scorer.window
            ]
    predictors += [create_baseline(n) for n in _baseline_list(baselines)]
    if not predictors:
        raise EvaluationError("nothing to evaluate: give --model, --checkpoint or --baselines")
    names = [p.name for p in predictors]
    if len(set(names)) != len(names):
        raise EvaluationError(f"predictor names repeat ({', '.join(names)}); give each --model once")
    return predictors
