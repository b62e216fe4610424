"""The weights shipped in the package: they load (checksum, weights_only) and rank renders."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from nriqa.core.correlation import srocc
from nriqa.inference.pretrained import WEIGHTS_DIR, list_pretrained
from nriqa.inference.scorer import Scorer


def test_shipped_models_load_with_their_cards():
    names = list_pretrained()
    assert {"fcnn_fast", "fcnn", "dual_fast"} <= set(names)
    x, twin = np.random.default_rng(0).random((2, 40, 40, 3)).astype(np.float32)
    for name in names:
        card = json.loads((WEIGHTS_DIR / f"{name}.json").read_text())
        assert card["name"] == name and len(card["sha256"]) == 64 and card["command"] and card["data"]
        scorer = Scorer.from_pretrained(name)
        result = scorer(x, hdr=False, twin=twin if scorer.needs_twin else None)
        assert np.isfinite(result.map).all() and np.isfinite(result.score)


def test_the_default_weights_are_shipped_single_image_and_used_when_none_is_named():
    from nriqa.cli.predict import build_parser
    from nriqa.inference import DEFAULT_WEIGHTS

    assert DEFAULT_WEIGHTS in list_pretrained()
    scorer = Scorer.from_pretrained()
    assert not scorer.needs_twin
    assert build_parser().parse_args(["x.exr"]).model == DEFAULT_WEIGHTS
    x = np.random.default_rng(1).random((40, 40, 3)).astype(np.float32)
    assert scorer(x, hdr=False).score == Scorer.from_pretrained(DEFAULT_WEIGHTS)(x, hdr=False).score


# Image SROCC measured with the shipped weights: fcnn_fast 0.965 (4000 CPU steps on the default
# set), fcnn 0.892 (800 CPU steps), dual_fast 0.987 with each image's twin, unet_fast 0.969 (two
# seeds of 12000 steps on v2m; a 32x32 image is one window); the bounds leave room for other CPUs'
# rounding.
@pytest.mark.parametrize("name, bound", [("fcnn_fast", 0.85), ("fcnn", 0.8), ("dual_fast", 0.95), ("unet_fast", 0.85)])
def test_shipped_models_rank_the_tiny_renders(tiny, name, bound):
    """Predicted pooled SSIM against the true mean SSIM over the tiny preset's test images (2-16 spp)."""
    from nriqa.core.ssim import ssim_map
    from nriqa.io.imread import load_ldr
    from nriqa.io.manifest import read_manifest

    records, _ = read_manifest(tiny)
    by_id = {r.id: r for r in records}
    scorer = Scorer.from_pretrained(name)
    predicted, true = [], []
    for r in records:
        if r.role != "test":
            continue
        x, y = load_ldr(tiny / r.path)[None], load_ldr(tiny / r.reference)[None]
        twin = load_ldr(tiny / by_id[r.twin].path).permute(1, 2, 0).numpy() if scorer.needs_twin else None
        true.append(float(ssim_map(x, y).mean()))
        predicted.append(scorer(x[0].permute(1, 2, 0).numpy(), hdr=False, twin=twin).score)
    assert len(true) >= 64
    value = float(srocc(torch.tensor(predicted), torch.tensor(true)))
    assert value > bound
