"""Hard-example sampling: draw training images in proportion to how wrong a model reads them.

Training draws its images uniformly, so an image the model misreads gets the same share of the steps as
one it already reads right. When a fine-tune starts from trained weights, the rare images it gets most
wrong (particle tracing at 2 spp in a dark room: a few splats on black, read as far better than they are)
are a fraction of a percent of the draws and stay wrong. :func:`image_errors` measures the starting
network on every training image as users run it (the :class:`~nriqa.inference.scorer.Scorer`, package
tone map, the model's windows) against the image's true mean SSIM; :func:`sampling_weights` turns those
errors into draw probabilities, a fraction ``mix`` in proportion to the error (or a ``power`` of it) and the
rest uniform, so every image keeps a share. :func:`draw_weights` does both for a training set, leaving the images
of anchored images (``data.anchor_scenes``, ``data.anchor_data``, which learn the start's own map) their uniform share;
``nriqa-train ... hard_sampling.mix=M`` calls it after ``init_from`` (:func:`nriqa.training.fit.train`), and
:meth:`nriqa.data.patches.TrainPatches.set_weights` draws by its weights.

    >>> [round(p, 4) for p in sampling_weights(torch.tensor([0.0, 0.1, 0.3]), 0.5).tolist()]
    [0.1667, 0.2917, 0.5417]
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from nriqa.data.anchors import NO_ANCHORS, Anchors
from nriqa.data.images import ImagePair
from nriqa.data.patches import TONEMAP, displayed
from nriqa.data.targets import compute_target

__all__ = ["check_mix", "check_power", "draw_summary", "draw_weights", "image_errors", "sampling_weights"]


@torch.no_grad()
def image_errors(net: nn.Module, pairs: Sequence[ImagePair], batch_size: int = 64) -> Tensor:
    """``|predicted - true|`` mean SSIM of each pair's noisy image through the package tone map, ``(N,)`` float64.

    The prediction is the Scorer's score with ``net`` (a copy in eval mode; ``net`` is left as it is,
    its windows included); the truth is the mean of the SSIM map of the tone-mapped noisy image
    against its reference. A two-buffer model is given each pair's twin.
    """
    from nriqa.inference.scorer import Scorer

    if not pairs:
        raise ValueError("image_errors needs at least one image pair")
    scorer = Scorer(net)
    out = torch.empty(len(pairs), dtype=torch.float64)
    start = 0
    while start < len(pairs):
        shape = pairs[start].noisy.shape
        stop = start
        while stop < len(pairs) and stop - start < batch_size and pairs[stop].noisy.shape == shape:
            stop += 1
        chunk = pairs[start:stop]
        shown = [displayed(p, (p.noisy, p.ref) + ((p.twin,) if scorer.needs_twin else ()), TONEMAP) for p in chunk]
        noisy = torch.stack([s[0] for s in shown])
        ref = torch.stack([s[1] for s in shown])
        twin = torch.stack([s[2] for s in shown]) if scorer.needs_twin else None
        albedo = torch.stack([p.albedo for p in chunk]) if scorer.needs_albedo else None
        predicted = scorer(noisy, hdr=False, twin=twin, albedo=albedo).score.double()
        true = compute_target("ssim_map", noisy, ref).mean(dim=(1, 2, 3), dtype=torch.float64)
        out[start:stop] = (predicted - true).abs()
        start = stop
    return out


def check_mix(mix: float) -> float:
    """``mix`` as a float; outside [0, 1] a one-line ``ValueError``."""
    if not 0.0 <= float(mix) <= 1.0:
        raise ValueError(f"hard_sampling.mix must be in [0, 1], got {mix}")
    return float(mix)


def check_power(power: float) -> float:
    """``power`` as a float; not > 0 a one-line ``ValueError``."""
    if not float(power) > 0.0:
        raise ValueError(f"hard_sampling.power must be > 0, got {power}")
    return float(power)


def sampling_weights(errors: Tensor, mix: float, power: float = 1.0) -> Tensor:
    """Draw probabilities ``(1 - mix) / N + mix * e_i**power / sum(e**power)``, ``(N,)`` float64 summing to 1.

    ``mix = 0`` is uniform; ``mix = 1`` draws only in proportion to the error (``power`` 1) or its square
    (``power`` 2: the few images read worst get most of those draws). Errors that are all zero give uniform
    draws.

    Raises:
        ValueError: ``mix`` outside [0, 1], ``power`` not > 0, no errors, or an error that is negative or
            not finite.
    """
    mix, power = check_mix(mix), check_power(power)
    e = torch.as_tensor(errors, dtype=torch.float64).flatten()
    if e.numel() == 0:
        raise ValueError("sampling_weights needs at least one error")
    if not bool(torch.isfinite(e).all()) or bool((e < 0).any()):
        raise ValueError("sampling_weights needs finite, non-negative errors")
    uniform = torch.full_like(e, 1.0 / e.numel())
    e = e**power
    total = float(e.sum())
    if total == 0.0:
        return uniform
    return (1.0 - mix) * uniform + mix * e / total


def draw_summary(errors: Tensor, weights: Tensor) -> dict[str, float]:
    """Figures for the log: mean error, and the share of draws going to the 1 % of images read worst."""
    e = torch.as_tensor(errors, dtype=torch.float64)
    w = torch.as_tensor(weights, dtype=torch.float64)
    top = max(1, e.numel() // 100)
    worst = torch.topk(e, top).indices
    return {
        "images": float(e.numel()),
        "mean_error": float(e.mean()),
        "worst_1pct_error": float(e[worst].mean()),
        "worst_1pct_share": float(w[worst].sum() / w.sum()),
    }


def draw_weights(
    net: nn.Module, pairs: Sequence[ImagePair], mix: float, power: float = 1.0, anchored: Anchors = NO_ANCHORS
) -> tuple[Tensor, dict[str, float]]:
    """Draw probabilities for a training set, ``(N,)`` float64 summing to 1, and the summary for the log.

    The ``anchored`` images (:mod:`nriqa.data.anchors`) learn the starting network's own map, so they carry no
    error to chase:
    each keeps its uniform share ``1 / N`` of the draws, whatever ``mix``, and the rest is shared out among the
    other (learning) images by :func:`sampling_weights` of ``net``'s errors on them (:func:`image_errors`).
    Without anchoring that is every image. The summary (:func:`draw_summary`) is over the learning images, with
    ``anchored_share`` where some are anchored.

    Raises:
        ValueError: ``mix`` or ``power`` out of range, or no learning image (every image anchored).
    """
    mix, power = check_mix(mix), check_power(power)
    learning = [i for i, p in enumerate(pairs) if not anchored(p.record)]
    if not learning:
        raise ValueError("hard sampling draws by the error of learning images, but every training image is anchored")
    errors = image_errors(net, [pairs[i] for i in learning])
    weights = torch.full((len(pairs),), 1.0 / len(pairs), dtype=torch.float64)
    weights[learning] = sampling_weights(errors, mix, power) * (len(learning) / len(pairs))
    summary = draw_summary(errors, weights[learning])
    if len(learning) < len(pairs):
        summary["anchored_share"] = 1.0 - len(learning) / len(pairs)
    return weights, summary
