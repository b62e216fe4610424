"""The two-buffer scorer dual_fast: untrained it is the corrected dual buffer; field, tiling, refusals."""

import numpy as np
import pytest
import torch

from nriqa.eval.baselines.dual_buffer import correct_dual_buffer, dual_buffer_map
from nriqa.inference.scorer import Scorer, ScorerInputError
from nriqa.models import create_model
from nriqa.models.dual_fast import DualFast


def _noisy_pair(h, w, sigma=0.05, seed=0):
    g = torch.Generator().manual_seed(seed)
    clean = torch.rand(1, 3, h, w, generator=g)
    a = (clean + sigma * torch.randn(clean.shape, generator=g)).clamp(0, 1)
    b = (clean + sigma * torch.randn(clean.shape, generator=g)).clamp(0, 1)
    return a, b


def _trained_like(seed=0, **kwargs):
    """A model whose correction is not zero (random head), as after training."""
    torch.manual_seed(seed)
    model = create_model("dual_fast", **kwargs).eval()
    with torch.no_grad():
        model.head.weight.normal_(0, 0.05)
    return model


@pytest.mark.parametrize("hw", [(6, 6), (37, 45), (64, 64)])
def test_untrained_is_the_corrected_dual_buffer(hw):
    a, b = _noisy_pair(*hw)
    with torch.no_grad():
        y = create_model("dual_fast").eval()(torch.cat([a, b], 1))
    expected = correct_dual_buffer(dual_buffer_map(a[0], b[0]).clamp(0, 1))
    assert y.shape == (1, 1, *hw)
    torch.testing.assert_close(y[0, 0], expected, atol=1e-6, rtol=0)


def test_identical_buffers_score_one():
    a, _ = _noisy_pair(32, 32)
    with torch.no_grad():
        y = create_model("dual_fast").eval()(torch.cat([a, a], 1))
    torch.testing.assert_close(y, torch.ones_like(y), atol=1e-5, rtol=0)


def test_more_noise_scores_lower():
    model = create_model("dual_fast").eval()
    with torch.no_grad():
        low, high = (model(torch.cat(_noisy_pair(48, 48, s), 1)).mean() for s in (0.02, 0.2))
    assert float(high) < float(low) < 1.0


def test_receptive_field_bounds_the_dependency():
    model = _trained_like().double()
    x = torch.rand(1, 6, 96, 96, dtype=torch.float64, requires_grad=True)
    model(x)[0, 0, 47, 48].backward()
    g = x.grad.abs().sum(dim=(0, 1))
    # ssim_map centres each image on its global mean (shift-invariant maths, better float32): far
    # pixels reach the gradient only at rounding level.
    g = g > 1e-9 * g.max()
    rows, cols = g.any(1).nonzero()[:, 0], g.any(0).nonzero()[:, 0]
    for lo, hi in ((int(rows.min()), int(rows.max()) + 1), (int(cols.min()), int(cols.max()) + 1)):
        assert hi - lo <= model.receptive_field == 24
        assert hi - lo >= 20


@pytest.mark.parametrize("tile, context", [(32, 0), (48, 0), (48, 21)])
def test_tiled_equals_untiled(tile, context):
    rng = np.random.default_rng(3)
    image = rng.uniform(0, 4, (150, 130, 3)).astype(np.float32)
    twin = (image * rng.uniform(0.7, 1.3, image.shape)).astype(np.float32)
    # sparse samples: most pixels black in one buffer or both, as at 2 spp in a dark render
    image[rng.uniform(size=image.shape[:2]) < 0.7] = 0.0
    twin[rng.uniform(size=twin.shape[:2]) < 0.7] = 0.0
    net = _trained_like(context=context)
    whole = Scorer(net, tile=0)(image, twin=twin)
    tiled = Scorer(net, tile=tile)(image, twin=twin)
    np.testing.assert_allclose(tiled.map, whole.map, atol=1e-5, rtol=0)


def test_scorer_needs_the_twin_and_sees_it():
    scorer = Scorer(_trained_like(), tile=0)
    rng = np.random.default_rng(0)
    image, twin = (rng.uniform(0, 4, (40, 40, 3)).astype(np.float32) for _ in range(2))
    assert scorer.needs_twin
    assert not np.array_equal(scorer(image, twin=twin).map, scorer(image, twin=image).map)
    with pytest.raises(ScorerInputError, match="pass twin="):
        scorer(image)
    with pytest.raises(ScorerInputError, match="smaller than the 6x6"):
        scorer(image[:5], twin=twin[:5])


def test_bad_pixels_never_nan():
    rng = np.random.default_rng(1)
    image, twin = (rng.uniform(0, 4, (64, 64, 3)).astype(np.float32) for _ in range(2))
    twin[0, 0], twin[1, 1], image[2, 2] = np.nan, np.inf, 1e6
    image[10:30, 10:30] = 0.0
    twin[10:30, 10:30] = 0.0  # a constant (black) region in both buffers
    assert np.isfinite(Scorer(_trained_like(), tile=0)(image, twin=twin).map).all()


def test_refuses_one_image_and_bad_construction():
    with pytest.raises(ValueError, match=r"expects \(B,6,H,W\)"):
        create_model("dual_fast")(torch.rand(1, 3, 16, 16))
    with pytest.raises(ValueError):
        DualFast(n3x3=0)


def _sparse(h, w, keep, seed):
    """A dark render at very few samples: a dim field where only a fraction ``keep`` of pixels got light."""
    g = torch.Generator().manual_seed(seed)
    lit = (torch.rand(1, 1, h, w, generator=g) < keep).float()
    return (0.6 * torch.rand(1, 3, h, w, generator=g) * lit).clamp(0, 1)


def test_context_features_count_black_pixels():
    model = DualFast(context=5)
    black, lit = torch.zeros(1, 3, 9, 9), torch.full((1, 3, 9, 9), 0.5)
    both, one = model._sparse_fractions(black, black)
    assert float(both.min()) == 1.0 and float(one.max()) == 0.0  # a truly black region
    both, one = model._sparse_fractions(lit, lit)
    assert float(both.max()) == 0.0 and float(one.max()) == 0.0  # a converged one
    half = lit.clone()
    half[..., ::2] = 0.0  # every other column black in one buffer only
    both, one = model._sparse_fractions(half, lit)
    assert float(both.max()) == 0.0 and 0.3 < float(one[0, 0, 4, 4]) < 0.7


def test_context_reaches_as_far_as_its_receptive_field():
    model = _trained_like(context=21).double()
    assert model.receptive_field == 2 * 7 + 20 == 34 and model.min_size == 12
    a = _sparse(96, 96, 0.6, 0).double()
    b = a * (torch.rand(a.shape, generator=torch.Generator().manual_seed(1), dtype=a.dtype) > 0.2)
    with torch.no_grad():
        y = model(torch.cat([a, b], 1))[0, 0, 48, 48]
        for dx, moves in ((16, True), (18, False)):  # the window reaches 17 px a side, no further
            a2 = a.clone()
            a2[..., 48, 48 + dx] = 0.7  # a sample lands on a black pixel: no gradient through the threshold
            y2 = model(torch.cat([a2, b], 1))[0, 0, 48, 48]
            # on some CPUs (stop 29's AMD EPYC) any input change moves the output by ~1e-16, float64 rounding,
            # even 25 px away; a change inside the receptive field is far above that (here ~4e-7)
            assert float(y) > 0 and (float((y2 - y).abs()) > 1e-12) == moves, dx


def test_context_is_off_by_default_and_checked():
    assert create_model("dual_fast").context == 0
    assert create_model("dual_fast", context=21).trunk[0].in_channels == (7 + 2) * 4
    for bad in (2, 1, -3):
        with pytest.raises(ValueError, match="context"):
            DualFast(context=bad)
