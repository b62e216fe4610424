"""Evaluate a trained network on one fold: patch-level and image-level correlations (thesis ch. 5).

Patch level (tables 5.3 / 5.7): predictions on a fixed patch set vs their targets.
Image level (tables 5.4 / 5.8): for each held-out noisy image, the mean-pooled prediction vs the
true full-image score -- the mean SSIM map against its reference (maps), or the image MAE (the
patch model, whose prediction is the mean over a grid of patches). Predictions go through
:class:`nriqa.inference.scorer.Scorer`, the package's one inference path.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.utils.data import DataLoader

from nriqa.core.sampling import evenly_spaced, metric_samples
from nriqa.data.images import ImagePair
from nriqa.data.targets import compute_target
from nriqa.inference.scorer import Scorer
from nriqa.training.metrics import correlations

EVAL_PIXELS_PER_MAP = 64
EVAL_MAX_SAMPLES = 4096


@torch.no_grad()
def patch_correlations(net: nn.Module, loader: DataLoader, max_samples: int = EVAL_MAX_SAMPLES) -> dict[str, float]:
    """``{"pcc", "srocc", "tau", "n"}`` of ``net`` on a fixed ``(noisy, target)`` patch loader.

    Maps contribute :data:`EVAL_PIXELS_PER_MAP` fixed pixels each; at most ``max_samples`` evenly
    spaced samples are correlated (Kendall's tau is quadratic in their number).
    """
    net.eval()
    device = next(net.parameters()).device
    preds, targets = [], []
    for x, y in loader:
        p, t = metric_samples(net(x.to(device)).cpu(), y, EVAL_PIXELS_PER_MAP)
        preds.append(p)
        targets.append(t)
    pred, target = evenly_spaced(torch.cat(preds), torch.cat(targets), max_samples)
    return {**correlations(pred, target), "n": pred.numel()}


def true_image_score(pair: ImagePair, target: str) -> float:
    """The full-reference score of a whole noisy image: mean SSIM map, or image MAE."""
    return float(compute_target(target, pair.noisy[None], pair.ref[None]).mean())


def predicted_image_score(
    scorer: Scorer, image: Tensor, twin: Tensor | None = None, albedo: Tensor | None = None
) -> float:
    """Mean-pooled prediction of ``scorer`` for a ``(3, H, W)`` LDR image (with the ``twin`` and the
    ``albedo`` pass where the model takes them)."""
    twin = twin if scorer.needs_twin else None
    albedo = albedo if scorer.needs_albedo else None
    return float(scorer(image, hdr=False, twin=twin, albedo=albedo).score)


def image_level(
    net: nn.Module, pairs: list[ImagePair], target: str, patch_size: int
) -> tuple[list[dict], dict[str, float]]:
    """Per-image ``(true, predicted)`` rows and their correlations over ``pairs``.

    Predictions go through :class:`nriqa.inference.scorer.Scorer`: map models predict the whole map;
    the patch model scores a grid of ``patch_size`` windows with stride ``patch_size`` (the last one
    moved in to touch the border).

    Returns:
        ``(rows, stats)``: rows ``{"id", "scene", "spp", "role", "true", "predicted"}``;
        stats ``{"pcc", "srocc", "tau", "n"}``.
    """
    scorer = Scorer(net, stride=patch_size)
    rows = [
        {
            "id": p.record.id,
            "scene": p.record.scene,
            "spp": p.record.spp,
            "role": p.record.role,
            "true": true_image_score(p, target),
            "predicted": predicted_image_score(scorer, p.noisy, p.twin, p.albedo),
        }
        for p in pairs
    ]
    true = torch.tensor([r["true"] for r in rows], dtype=torch.float64)
    pred = torch.tensor([r["predicted"] for r in rows], dtype=torch.float64)
    return rows, {**correlations(pred, true), "n": len(rows)}
