"""The variance-based peer (half-buffer placement and stop rule), the half film and its halves, and the
Rater's halves for two-buffer scorers: on a synthetic renderer (Gaussian samples per pixel), plus one
small Mitsuba run (llvm_ad_rgb)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nriqa.core.ssim import ssim_map
from nriqa.render import (
    Converged,
    HalfFilm,
    PixelAllocation,
    PixelFilm,
    Probes,
    ReferenceScorer,
    Schedule,
    SppBudget,
    UnconvergedPixels,
    render_loop,
    split_halves,
)
from nriqa.render.peer import unconverged_pixels
from nriqa.render.rating import at_full_samples, rate_halves
from nriqa.render.stop import Progress, StopRule

SIZE = 16

pytestmark = pytest.mark.usefixtures("one_thread")


class GaussianRenderer:
    """The renderer protocol of PixelFilm / HalfFilm in numpy: each sample is ``clean + sigma * N(0, 1)``.

    Samples are drawn from ``default_rng(seed)`` in pixel order, so a seed and counts give the same
    sums; the even sums take the samples of even index among each pixel's (``done + j``)."""

    def __init__(self, clean: np.ndarray, sigma: np.ndarray):
        self.clean, self.sigma = clean, sigma
        self.height, self.width = sigma.shape

    def _samples(self, counts, seed):
        flat = np.asarray(counts, dtype=np.int64).reshape(-1)
        pixel = np.repeat(np.arange(flat.size), flat)
        noise = np.random.default_rng(seed).standard_normal((pixel.size, 3))
        return flat, pixel, self.clean.reshape(-1, 3)[pixel] + self.sigma.reshape(-1)[pixel, None] * noise

    def _sums(self, pixel, values, size):
        out = np.zeros((size, 3))
        np.add.at(out, pixel, values)
        return out.reshape(self.height, self.width, 3)

    def __call__(self, counts, seed):
        flat, pixel, values = self._samples(counts, seed)
        return self._sums(pixel, values, flat.size)

    def with_half(self, counts, seed, done):
        flat, pixel, values = self._samples(counts, seed)
        starts = np.cumsum(flat) - flat
        index = np.arange(pixel.size) - starts[pixel] + np.asarray(done, dtype=np.int64).reshape(-1)[pixel]
        even = index % 2 == 0
        return self._sums(pixel, values, flat.size), self._sums(pixel[even], values[even], flat.size)


@pytest.fixture
def scene():
    """A smooth image; its left half is noise-free (converged at once), its right half noisy."""
    yy, xx = np.mgrid[0:SIZE, 0:SIZE] / SIZE
    clean = np.stack([0.4 + 0.3 * np.sin(3 * xx + c) * np.cos(2 * yy) for c in range(3)], axis=2)
    sigma = np.zeros((SIZE, SIZE))
    sigma[:, SIZE // 2 :] = 0.3
    return clean, sigma


class Shares(StopRule):
    """Never stops; records the share of unconverged pixels at every row (placed before the rule tested)."""

    name = "shares"

    def __init__(self, threshold, min_spp):
        self.threshold, self.min_spp, self.seen = threshold, min_spp, []

    def reached(self, progress: Progress) -> bool:
        self.seen.append(float(unconverged_pixels(progress.film, self.threshold, self.min_spp).mean()))
        return False


def _peer_run(scene, threshold=0.05, seed=3, min_spp=8, budget=4000):
    clean, sigma = scene
    shares = Shares(threshold, min_spp)
    film = HalfFilm(GaussianRenderer(clean, sigma), seed)
    stops = [shares, Converged(threshold, 0.0, min_spp), SppBudget(budget)]
    placement = UnconvergedPixels(threshold, min_spp, seed=seed)
    image, log = render_loop(film, placement, stops, None, schedule=Schedule(4, 4, 0.25), warmup=False)
    return film, image, log, shares.seen


def test_peer_stops_when_every_pixel_has_converged_and_not_before(scene):
    film, _, log, shares = _peer_run(scene)
    assert log[-1]["stop"] == "converged" and len(log) > 3
    assert shares[-1] == 0.0 and all(s > 0 for s in shares[:-1])
    counts = log[-1]["spp_map"]
    # The noise-free half stops at min_spp (its first pass and one step); the noisy half goes on.
    assert counts[:, : SIZE // 2 - 1].max() == 8 and counts[:, SIZE // 2 :].min() > 8 * 4
    assert unconverged_pixels(film, 0.05, 8).sum() == 0


def test_converged_with_a_fraction_stops_earlier(scene):
    _, _, full, _ = _peer_run(scene, seed=5)
    clean, sigma = scene
    film = HalfFilm(GaussianRenderer(clean, sigma), 5)
    stops = [Converged(0.05, 0.5, 8), SppBudget(4000)]
    _, log = render_loop(
        film, UnconvergedPixels(0.05, 8, seed=5), stops, None, schedule=Schedule(4, 4, 0.25), warmup=False
    )
    assert log[-1]["stop"] == "converged" and log[-1]["spp"] < full[-1]["spp"]
    assert 0 < unconverged_pixels(film, 0.05, 8).mean() <= 0.5


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: Converged(0.0), "threshold"),
        (lambda: Converged(-0.1), "threshold"),
        (lambda: Converged(float("nan")), "threshold"),
        (lambda: Converged(0.1, fraction=1.0), "fraction"),
        (lambda: Converged(0.1, min_spp=-1), "min_spp"),
        (lambda: UnconvergedPixels(0.0), "threshold"),
        (lambda: UnconvergedPixels(0.1, refine=1.0), "refine"),
        (lambda: UnconvergedPixels(0.1, growth=-1), "growth"),
    ],
)
def test_peer_settings_are_refused_with_their_name(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_placement_skips_converged_pixels_and_dilates_the_rest(scene):
    clean, sigma = scene
    film = HalfFilm(GaussianRenderer(clean, sigma), 1)
    film.add_uniform(16)
    before = film.count.copy()
    placement = UnconvergedPixels(0.05, min_spp=8, seed=1)
    mask = placement.active(film)
    placement.step(film, 4, None)
    added = film.count - before
    # The noisy half and the one column the dilation adds; nothing further left.
    assert mask[:, SIZE // 2 - 1 :].all() and not mask[:, : SIZE // 2 - 1].any()
    assert (added[:, : SIZE // 2 - 1] == 0).all() and (added[:, SIZE // 2 - 1 :] > 0).all()
    # Every sampled pixel gets the same count (a pass), no more than a uniform step's samples in all.
    assert len(np.unique(added[mask])) <= 2 and added.sum() <= 4 * SIZE * SIZE


def test_placement_lowers_its_threshold_when_every_pixel_has_converged(scene):
    clean, _ = scene
    film = HalfFilm(GaussianRenderer(clean, np.full((SIZE, SIZE), 0.05)), 2)
    film.add_uniform(64)
    error_max = float(unconverged_pixels(film, 1e-9).mean())  # everything is above a tiny threshold
    assert error_max == 1.0
    placement = UnconvergedPixels(10.0, min_spp=8, refine=0.5, seed=2)
    mask = placement.active(film)
    assert mask.any() and placement.threshold < 10.0
    assert not unconverged_pixels(film, placement.threshold / 0.5, 8).any()  # the one before had none


def test_peer_is_deterministic_for_a_seed(scene):
    _, image_a, log_a, _ = _peer_run(scene, seed=7)
    _, image_b, log_b, _ = _peer_run(scene, seed=7)
    np.testing.assert_array_equal(image_a, image_b)
    np.testing.assert_array_equal(log_a[-1]["spp_map"], log_b[-1]["spp_map"])
    assert [r["spp"] for r in log_a] == [r["spp"] for r in log_b]
    _, image_c, _, _ = _peer_run(scene, seed=8)
    assert not np.array_equal(image_a, image_c)


@pytest.mark.parametrize("n", [16, 17])
def test_halves_are_the_even_and_the_odd_samples(n):
    rng = np.random.default_rng(n)
    samples = 0.5 + 0.2 * rng.standard_normal((n, 50, 1, 3))
    image, even = samples.mean(axis=0), samples[0::2].mean(axis=0)
    counts = np.full((50, 1), n)
    first, second, share = split_halves(image, even, counts, np.ceil(counts / 2))
    np.testing.assert_allclose(first, even, rtol=1e-6)
    np.testing.assert_allclose(second, samples[1::2].mean(axis=0), rtol=1e-5)
    np.testing.assert_allclose(share, np.ceil(n / 2) / n)
    # a pixel with one sample has no second half: it is its own, with the whole share
    one = split_halves(image[:1], image[:1], np.ones((1, 1)), np.ones((1, 1)))
    np.testing.assert_array_equal(one[1], one[0])
    assert one[2][0, 0] == 1.0


def test_at_full_samples_on_known_values():
    q = np.array([0.0, 0.25, 0.5, 0.9, 1.0, 1.2, -0.1])
    expected = [0, 0.4, 2 / 3, 1.8 / 1.9, 1, 1, 0]  # 2q / (1 + q) of q clipped to [0, 1]
    np.testing.assert_allclose(at_full_samples(q, np.full(q.shape, 0.5)), expected, rtol=1e-6)
    np.testing.assert_allclose(at_full_samples(q[:5], np.ones(5)), q[:5], rtol=1e-6)  # all the samples: unchanged


def test_the_halves_interval_is_carried_to_the_whole_image():
    from nriqa.inference.scorer import ScoreResult

    def twin_scorer(first, *, twin, hdr=None, low=0.76):
        return ScoreResult(np.full((4, 4), 0.8, np.float32), 0.8, "ssim", True, low, 0.83 if low else None)

    share = np.full((4, 4), 0.5)
    rated = rate_halves(twin_scorer, np.zeros((4, 4, 3)), second=np.zeros((4, 4, 3)), share=share)
    assert rated.score == pytest.approx(1.6 / 1.8)  # 2q / (1 + q)
    assert rated.low == pytest.approx(2 * 0.76 / 1.76)  # the low end by the same law (a flat map: exactly)
    none = rate_halves(
        lambda f, **kw: twin_scorer(f, low=None, **kw), np.zeros((4, 4, 3)), second=np.zeros((4, 4, 3)), share=share
    )
    assert none.low is None


def test_a_half_rated_against_the_other_carries_to_the_whole_image():
    """SSIM(half, reference) carried to n samples matches SSIM(image, reference), on Gaussian noise."""
    rng = np.random.default_rng(5)
    size, n = 96, 16
    clean = np.clip(0.5 + 0.15 * rng.standard_normal((size, size, 1)) * np.ones(3), 0, 1)
    samples = clean + 0.3 * rng.standard_normal((n, size, size, 3))
    image, first = samples.mean(0), samples[0::2].mean(0)

    def ssim(x, y):
        x, y = (torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1)))[None].float() for a in (x, y))
        return ssim_map(x, y)[0, 0].numpy()

    truth = float(ssim(image, clean).mean())
    carried = float(at_full_samples(ssim(first, clean), np.full((size, size), 0.5)).mean())
    assert float(ssim(first, clean).mean()) < truth - 0.03  # half the samples: worse
    assert carried == pytest.approx(truth, abs=0.01)


def test_half_film_keeps_the_even_samples_and_its_halves(scene):
    clean, sigma = scene
    film = HalfFilm(GaussianRenderer(clean, sigma), 4)
    plain = PixelFilm(GaussianRenderer(clean, sigma), 4)
    for counts in (np.full((SIZE, SIZE), 3), np.arange(SIZE * SIZE).reshape(SIZE, SIZE) % 4):
        film.add(counts)
        plain.add(counts)
    np.testing.assert_array_equal(film.image, plain.image)  # the same samples as a PixelFilm
    np.testing.assert_array_equal(HalfFilm.even_count(np.array([0, 1, 2, 3, 6])), [0, 1, 1, 2, 3])
    left = film.half[:, : SIZE // 2]
    np.testing.assert_allclose(left, clean[:, : SIZE // 2], atol=1e-6)  # noise-free: A = I = clean
    a, b, share = film.halves()
    assert a.shape == b.shape == (SIZE, SIZE, 3) and a.dtype == b.dtype == np.float32 and share.shape == (SIZE, SIZE)
    whole = share[..., None] * a + (1 - share[..., None]) * b  # the halves weighted by their samples
    np.testing.assert_allclose(whole, film.image, atol=1e-5)


class TwinScorer:
    """A two-buffer scorer stand-in: records the twin it is given, rates like the true SSIM map."""

    needs_twin = True
    higher_is_better = True

    def __init__(self, reference):
        self.oracle, self.twins = ReferenceScorer(reference), []

    def __call__(self, image, *, twin=None, hdr=None):
        self.twins.append((image, twin))
        return self.oracle(image)


def _twin_run(scene, probes):
    clean, sigma = scene
    scorer = TwinScorer(clean)
    film = HalfFilm(GaussianRenderer(clean, sigma), 6)
    common = dict(schedule=Schedule(4, 4, 0.25), probes=probes, max_overhead=None, warmup=False)
    _, log = render_loop(film, PixelAllocation(0.5, 6), [SppBudget(48)], scorer, **common)
    assert len(scorer.twins) == sum(r["scored"] for r in log) > 2
    assert all(twin is not None and twin.shape == image.shape for image, twin in scorer.twins)
    assert all(not np.array_equal(twin, image) for image, twin in scorer.twins)
    return film, scorer, log


def test_rater_passes_the_image_twin_to_a_two_buffer_scorer(scene):
    film, scorer, _ = _twin_run(scene, Probes(map_spp=None))
    image, twin = scorer.twins[-1]  # the last row is rated: the image's halves at the end
    first, second, _ = film.halves()
    np.testing.assert_array_equal(image, first)
    np.testing.assert_array_equal(twin, second)


def test_a_two_buffer_scorer_rates_the_images_halves_past_map_spp(scene):
    """map_spp is a single-image scorer's range: a two-buffer scorer rates the image's halves at
    every count (never a probe), so every rating's halves hold all the film's samples."""
    film, scorer, log = _twin_run(scene, Probes(map_spp=16, probe_spp=8))
    scored = [r for r in log if r["scored"]]
    assert max(r["spp"] for r in scored) > 16 and len(scorer.twins) == len(scored)
    image, twin = scorer.twins[-1]
    first, second, _ = film.halves()
    np.testing.assert_array_equal(image, first)
    np.testing.assert_array_equal(twin, second)
    # halves of the whole 48-spp image (24 samples each), not of an 8-spp probe (4 each)
    spread = float(np.std((twin - image)[:, SIZE // 2 :]))
    assert spread == pytest.approx(0.3 * np.sqrt(2 / 24), rel=0.25)


def test_a_two_buffer_scorer_needs_a_film_with_a_half_buffer(scene):
    clean, sigma = scene
    with pytest.raises(ValueError, match="HalfFilm"):
        render_loop(PixelFilm(GaussianRenderer(clean, sigma)), PixelAllocation(), [SppBudget(8)], TwinScorer(clean))


def test_a_single_image_scorer_gets_no_twin(scene):
    clean, sigma = scene
    calls = []

    def scorer(image, **kwargs):
        calls.append(kwargs)
        return ReferenceScorer(clean)(image)

    scorer.higher_is_better = True
    render_loop(HalfFilm(GaussianRenderer(clean, sigma)), PixelAllocation(), [SppBudget(16)], scorer, warmup=False)
    assert calls and all("twin" not in kw for kw in calls)


@pytest.fixture(scope="module")
def llvm_loop_scene():
    """A loop scene at 32x32 in llvm_ad_rgb (skipped where libLLVM 19 is missing) and a 256-spp reference."""
    mi = pytest.importorskip("mitsuba")
    from nriqa.render.backend import LLVM_VARIANT, init_worker, probe_llvm

    ok, reason = probe_llvm()
    if not ok:
        pytest.skip(f"llvm_ad_rgb unusable here: {reason}")
    from data_gen.render import loop_scene

    previous = mi.variant()
    init_worker(LLVM_VARIANT, 1)
    scene = loop_scene("cornell", (32, 32))
    reference = np.array(mi.render(mi.load_dict(scene), spp=256, seed=4321), dtype=np.float32)[..., :3]
    yield scene, reference
    if previous is not None:
        mi.set_variant(previous)


def test_pixel_renderer_splits_the_same_wavefront_into_even_and_odd_samples(llvm_loop_scene):
    from nriqa.render import PixelRenderer
    from nriqa.render.film import load_scene

    scene, _ = llvm_loop_scene
    renderer = PixelRenderer(load_scene(scene))
    counts = np.random.default_rng(0).integers(0, 6, (32, 32))
    done = np.random.default_rng(1).integers(0, 5, (32, 32))
    sums, even = renderer.with_half(counts, 11, done)
    np.testing.assert_array_equal(sums, renderer(counts, 11))
    _, odd = renderer.with_half(counts, 11, done + 1)  # the same samples, parity swapped
    np.testing.assert_allclose(even + odd, sums, rtol=1e-5, atol=1e-6)
    _, single = renderer.with_half(np.ones((32, 32), np.int64), 3, np.zeros((32, 32)))
    np.testing.assert_array_equal(single, renderer(np.ones((32, 32), np.int64), 3))


def test_render_peer_on_a_mitsuba_scene(llvm_loop_scene):
    from nriqa.render import render_peer, true_ssim

    scene, reference = llvm_loop_scene
    runs = [render_peer(scene, 0.2, max_spp=256, reference=reference, seed=2, warmup=False) for _ in range(2)]
    (image, log), (image_b, log_b) = runs
    np.testing.assert_array_equal(image, image_b)
    np.testing.assert_array_equal(log[-1]["spp_map"], log_b[-1]["spp_map"])
    assert log[-1]["stop"] in ("converged", "max_spp") and log[-1]["threshold"] == 0.2
    counts = log[-1]["spp_map"]
    assert counts.min() >= 16 and counts.max() > counts.min()  # converged pixels stopped, others went on
    assert log[-1]["true"] == pytest.approx(true_ssim(image, reference))
    _, timed = render_peer(scene, 0.2, time_budget_s=0.5, stop_fraction=None, reference=reference, seed=2)
    assert timed[-1]["stop"] == "time" and timed[-1]["seconds"] >= 0.5
    with pytest.raises(ValueError, match="budget"):
        render_peer(scene, 0.2)


def test_loops_render_into_a_half_film_for_a_two_buffer_scorer(llvm_loop_scene):
    from nriqa.render import render_adaptive, render_until

    scene, reference = llvm_loop_scene
    for run in (
        lambda by: render_adaptive(scene, by, total_spp=16, max_overhead=None, warmup=False),
        lambda by: render_until(scene, by, 2.0, 1e9, 4, max_spp=16, max_overhead=None, warmup=False),
    ):
        scorer = TwinScorer(reference)
        _, log = run(scorer)
        assert len(scorer.twins) == sum(r["scored"] for r in log) >= 2
        assert all(twin is not None and twin.shape == image.shape for image, twin in scorer.twins)
    with pytest.raises(ValueError, match="per-pixel"):
        render_adaptive(scene, TwinScorer(reference), total_spp=8, tile=16)
