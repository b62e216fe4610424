"""Error by sample count: is a scorer's bias the same at 2 spp as near convergence?

A scorer can rank every image right and still compress the range -- read the noisiest renders too
good and the nearly converged ones too noisy -- so that one stopping threshold means different
things at different sample counts (issue 15). Pooled MAE hides this; per band of spp it shows.

From the rows of :func:`nriqa.eval.evaluate.run_predictors`, per predictor on the SSIM scale (raw
scores through their monotone map) and per band of :data:`SPP_BANDS`: the number of images, the
MAE and the bias (mean of predicted minus true) of the mapped score against the true mean SSIM.
"""

from __future__ import annotations

import math

import numpy as np

# Inclusive spp ranges: the noisy start of a render, the middle of the ladder, near convergence.
SPP_BANDS = ((1, 8), (9, 64), (65, None))
COLUMNS = ["predictor", "spp", "n", "true", "mae", "bias"]


def band_label(low: int, high: int | None) -> str:
    return f"{low}-{high}" if high is not None else f">={low}"


def by_spp(rows: list[dict], predictors: list[str]) -> list[dict]:
    """One row per (predictor, spp band holding images): ``n``, mean ``true``, ``mae``, ``bias``."""
    out = []
    for name in predictors:
        own = [r for r in rows if r["predictor"] == name]
        for low, high in SPP_BANDS:
            sel = [r for r in own if r["spp"] >= low and (high is None or r["spp"] <= high)]
            if not sel:
                continue
            err = np.array([r["mapped"] - r["true"] for r in sel], dtype=float)
            keep = np.isfinite(err)
            true = np.array([r["true"] for r in sel], dtype=float)[keep]
            out.append(
                {
                    "predictor": name,
                    "spp": band_label(low, high),
                    "n": int(keep.sum()),
                    "true": float(true.mean()) if keep.any() else math.nan,
                    "mae": float(np.abs(err[keep]).mean()) if keep.any() else math.nan,
                    "bias": float(err[keep].mean()) if keep.any() else math.nan,
                }
            )
    return out
