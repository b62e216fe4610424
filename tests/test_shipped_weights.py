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


def test_the_gaussian_weights_read_renders_through_mitsubas_default_filter(tiny):
    """``unet_fast_gaussian`` on the tiny renders through Mitsuba's Gaussian (emulated on the linear pair, as in
    training): it ranks them and reads them far closer than the box-filter default, which takes their smoothed
    noise for convergence (measured on Mitsuba's own Gaussian renders in docs/results/evaluation.md, stop 57)."""
    from nriqa.core.ssim import ssim_map
    from nriqa.core.tonemap import tonemap
    from nriqa.data.pixel_filter import apply_pixel_filter
    from nriqa.io.imread import read_image
    from nriqa.io.manifest import read_manifest

    def filtered(path):
        linear = torch.from_numpy(read_image(tiny / path)[0]).permute(2, 0, 1)[None]
        return apply_pixel_filter(linear, 0.45)

    gaussian, box = Scorer.from_pretrained("unet_fast_gaussian"), Scorer.from_pretrained("unet_fast")
    assert gaussian.pixel_filter == "gaussian" and box.pixel_filter == "box"
    # its interval: fitted on the 380 Gaussian-filtered images it was chosen on, none of them learnt
    assert gaussian.interval.level == 0.9 and sum(gaussian.interval.counts) == 380
    assert "gaussian" in gaussian.interval.source and "not the external set" in gaussian.interval.source
    records, _ = read_manifest(tiny)
    true, read = [], {"gaussian": [], "box": []}
    for r in records:
        # pebbles (stop 59) only the default learnt: this file reads its small stones far too noisy (0.39-0.64
        # for a true 0.68-0.97 here), a shortfall docs/scoring.md states
        if r.role != "test" or r.scene == "pebbles":
            continue
        x, y = filtered(r.path), filtered(r.reference)
        true.append(float(ssim_map(tonemap(x), tonemap(y)).mean()))
        image = x[0].permute(1, 2, 0).numpy()
        read["gaussian"].append(gaussian(image, hdr=True).score)
        read["box"].append(box(image, hdr=True).score)
    true = np.array(true)
    error = {k: float(np.abs(np.array(v) - true).mean()) for k, v in read.items()}
    assert len(true) >= 64 and float(srocc(torch.tensor(read["gaussian"]), torch.tensor(true))) > 0.85
    assert error["gaussian"] < error["box"] / 2, error
