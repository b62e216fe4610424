"""Is a scorer monotone in samples? Ladders of predicted scores, rung by rung.

A render that gets more samples gets better, so a scorer a render loop can trust must not say
otherwise: along one *ladder* -- the images of one (scene, variant, algorithm) ordered by spp --
the predicted mean SSIM should not fall from one rung to the next, and where the true SSIM is
already high the prediction must be high too, or an early-stopping target is never reached.

A rung is one sample count: images of a ladder rendered at the same count (a sampler that rounds the count
it is asked for, :mod:`nriqa.eval.sample_counts`) are one rung, its true and predicted scores their means.

Per ladder (SSIM-scale predictors only, from the rows of :func:`nriqa.eval.evaluate.run_predictors`):

* ``largest_drop``: the largest fall of the predicted score from one rung to the next (0 when it
  never falls), and the spp at which it happens;
* ``low_where_converged``: the smallest prediction among the rungs whose true SSIM is at least
  :data:`CONVERGED_TRUE` (``nan`` when no rung gets there).

A ladder *passes* when its largest drop is at most :data:`MAX_DROP` and its low prediction is at
least :data:`MIN_CONVERGED_PREDICTION` (issue 15's done-when).
"""

from __future__ import annotations

import itertools
import math
from collections import defaultdict

MAX_DROP = 0.01
CONVERGED_TRUE = 0.98
MIN_CONVERGED_PREDICTION = 0.96

LADDER_COLUMNS = [
    "predictor",
    "scene",
    "variant",
    "algorithm",
    "rungs",
    "largest_drop",
    "drop_at_spp",
    "converged_rungs",
    "low_where_converged",
    "passes",
]
SUMMARY_COLUMNS = [
    "predictor",
    "ladders",
    "passing",
    "largest_drop",
    "ladders_with_drop",
    "converged_rungs",
    "low_where_converged",
    "ladders_low",
]


def ladders(rows: list[dict]) -> dict[tuple, list[dict]]:
    """The rows grouped by (predictor, scene, variant, algorithm), each group sorted by spp."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["predictor"], r["scene"], r["variant"], r["algorithm"])].append(r)
    return {k: sorted(v, key=lambda r: r["spp"]) for k, v in sorted(groups.items(), key=lambda kv: str(kv[0]))}


def merge_counts(rungs: list[dict]) -> list[dict]:
    """One rung per sample count (``rungs`` sorted by spp): the mean true and predicted score of its images."""
    merged = []
    for spp, group in itertools.groupby(rungs, key=lambda r: r["spp"]):
        members = list(group)
        true = sum(r["true"] for r in members) / len(members)
        merged.append({"spp": spp, "true": true, "predicted": sum(r["predicted"] for r in members) / len(members)})
    return merged


def ladder_row(key: tuple, rungs: list[dict]) -> dict:
    """One ladder's figures (see the module docstring); ``rungs`` sorted by spp, predictions on the SSIM scale."""
    predictor, scene, variant, algorithm = key
    rungs = merge_counts(rungs)
    drop, drop_at = 0.0, ""
    for lo, hi in zip(rungs, rungs[1:]):
        fall = lo["predicted"] - hi["predicted"]
        if math.isfinite(fall) and fall > drop:
            drop, drop_at = fall, hi["spp"]
    converged = [r["predicted"] for r in rungs if r["true"] >= CONVERGED_TRUE]
    low = min(converged) if converged else math.nan
    passes = drop <= MAX_DROP and not (converged and low < MIN_CONVERGED_PREDICTION)
    return {
        "predictor": predictor,
        "scene": scene,
        "variant": variant,
        "algorithm": algorithm,
        "rungs": len(rungs),
        "largest_drop": drop,
        "drop_at_spp": drop_at,
        "converged_rungs": len(converged),
        "low_where_converged": low,
        "passes": "yes" if passes else "no",
    }


def monotonicity(rows: list[dict], ssim_predictors: list[str]) -> tuple[list[dict], list[dict]]:
    """``(per_ladder, summary)`` for the predictors named in ``ssim_predictors`` (on the SSIM scale)."""
    per_ladder = [ladder_row(k, v) for k, v in ladders(rows).items() if k[0] in ssim_predictors]
    summary = []
    for name in ssim_predictors:
        own = [r for r in per_ladder if r["predictor"] == name]
        if not own:
            continue
        lows = [r["low_where_converged"] for r in own if r["converged_rungs"]]
        summary.append(
            {
                "predictor": name,
                "ladders": len(own),
                "passing": sum(r["passes"] == "yes" for r in own),
                "largest_drop": max(r["largest_drop"] for r in own),
                "ladders_with_drop": sum(r["largest_drop"] > MAX_DROP for r in own),
                "converged_rungs": sum(r["converged_rungs"] for r in own),
                "low_where_converged": min(lows) if lows else math.nan,
                "ladders_low": sum(low < MIN_CONVERGED_PREDICTION for low in lows),
            }
        )
    return per_ladder, summary
