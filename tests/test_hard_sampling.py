"""Hard-example sampling: training images drawn in proportion to the starting network's error on them."""

from __future__ import annotations

import pytest
import torch
from test_train import compose_cfg

from nriqa.core.ssim import ssim_map
from nriqa.data.anchors import Anchors
from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.patches import TONEMAP, displayed
from nriqa.inference.pretrained import load_pretrained
from nriqa.inference.scorer import Scorer
from nriqa.training.fit import train
from nriqa.training.hard_sampling import draw_summary, draw_weights, image_errors, sampling_weights


def _datamodule(root, **kwargs) -> NRIQADataModule:
    dm = NRIQADataModule(root, patch_size=32, batch_size=4, batches_per_epoch=2, val_patches=4, **kwargs)
    dm.setup("fit")
    return dm


def test_weights_mix_uniform_and_error_proportional():
    e = torch.tensor([0.0, 0.1, 0.3, 0.0])
    torch.testing.assert_close(sampling_weights(e, 0.0), torch.full((4,), 0.25, dtype=torch.float64))
    torch.testing.assert_close(sampling_weights(e, 1.0), torch.tensor([0.0, 0.25, 0.75, 0.0], dtype=torch.float64))
    half = sampling_weights(e, 0.5)
    torch.testing.assert_close(half, torch.tensor([0.125, 0.25, 0.5, 0.125], dtype=torch.float64))
    assert float(half.sum()) == pytest.approx(1.0)
    # power 2: in proportion to the squared error
    torch.testing.assert_close(
        sampling_weights(e, 1.0, power=2), torch.tensor([0.0, 0.1, 0.9, 0.0], dtype=torch.float64)
    )
    # nothing misread: uniform, whatever the mix
    torch.testing.assert_close(sampling_weights(torch.zeros(3), 0.8), torch.full((3,), 1 / 3, dtype=torch.float64))


@pytest.mark.parametrize(
    ("errors", "mix", "message"),
    [
        ([0.1, 0.2], 1.5, r"mix must be in \[0, 1\]"),
        ([0.1, 0.2], -0.1, r"mix must be in \[0, 1\]"),
        ([], 0.5, "at least one error"),
        ([0.1, float("nan")], 0.5, "finite, non-negative"),
        ([0.1, -0.2], 0.5, "finite, non-negative"),
    ],
)
def test_weights_refuse_bad_input(errors, mix, message):
    with pytest.raises(ValueError, match=message):
        sampling_weights(torch.tensor(errors), mix)
    with pytest.raises(ValueError, match="power must be > 0"):
        sampling_weights(torch.tensor([0.1]), 0.5, power=0)


def test_summary_gives_the_worst_images_share_of_draws():
    e = torch.tensor([0.0] * 99 + [1.0], dtype=torch.float64)
    s = draw_summary(e, sampling_weights(e, 0.5))
    assert s["images"] == 100 and s["worst_1pct_error"] == 1.0
    assert s["worst_1pct_share"] == pytest.approx(0.5 / 100 + 0.5)


def test_patches_follow_the_weights_deterministically(synthetic_dataset):
    dm = _datamodule(synthetic_dataset)
    patches = dm.train_set
    n = len(patches.pairs)
    chosen = n - 1
    draws = [patches.pick(torch.Generator().manual_seed(k)) for k in range(20)]
    assert len({id(p) for p in draws}) > 1  # uniform: several images
    weights = torch.zeros(n)
    weights[chosen] = 2.0
    patches.set_weights(weights)
    assert all(patches.pick(torch.Generator().manual_seed(k)) is patches.pairs[chosen] for k in range(20))
    # item k stays a pure function of (seed, k) and the weights
    a, b = patches[5], patches[5]
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    patches.set_weights(None)
    assert [id(patches.pick(torch.Generator().manual_seed(k))) for k in range(20)] == [id(p) for p in draws]


@pytest.mark.parametrize(
    ("weights", "message"),
    [("short", "one weight per training image"), ("negative", "non-negative"), ("zero", "positive sum")],
)
def test_patches_refuse_bad_weights(synthetic_dataset, weights, message):
    patches = _datamodule(synthetic_dataset).train_set
    n = len(patches.pairs)
    w = {"short": torch.ones(n - 1), "negative": torch.tensor([-1.0] + [1.0] * (n - 1)), "zero": torch.zeros(n)}
    with pytest.raises(ValueError, match=message):
        patches.set_weights(w[weights])


@pytest.mark.parametrize("linear", [False, True])
def test_errors_are_the_scorers_against_the_true_mean_ssim(synthetic_dataset, linear):
    display = {"tonemap": 0.5, "srgb": 0.5} if linear else None
    pairs = _datamodule(synthetic_dataset, display=display).train_pairs
    net = load_pretrained("fcnn_fast").train()
    before = {k: v.clone() for k, v in net.state_dict().items()}
    errors = image_errors(net, pairs, batch_size=5)
    assert errors.shape == (len(pairs),) and errors.dtype == torch.float64
    scorer = Scorer(load_pretrained("fcnn_fast"))
    for pair, error in zip(pairs[:6], errors[:6]):
        noisy, ref = displayed(pair, (pair.noisy, pair.ref), TONEMAP)
        true = float(ssim_map(noisy[None], ref[None]).mean())
        assert float(error) == pytest.approx(abs(scorer(noisy, hdr=False).score - true), abs=1e-5)
    # the network is left as it was: weights, statistics and train mode
    assert net.training and all(torch.equal(before[k], v) for k, v in net.state_dict().items())
    # noisier images are read worse by a trained model on this data, on average
    assert float(errors.max()) > float(errors.min())


def test_two_buffer_model_is_given_the_twins(synthetic_dataset):
    pairs = _datamodule(synthetic_dataset, twins=True).train_pairs
    errors = image_errors(load_pretrained("dual_fast"), pairs)
    assert errors.shape == (len(pairs),) and bool(torch.isfinite(errors).all())


def test_draw_weights_leave_anchored_families_their_uniform_share(synthetic_dataset):
    pairs = _datamodule(synthetic_dataset).train_pairs
    net = load_pretrained("fcnn_fast")
    # no anchoring: the weights of the starting errors on every image
    weights, summary = draw_weights(net, pairs, 0.5)
    torch.testing.assert_close(weights, sampling_weights(image_errors(net, pairs), 0.5))
    assert summary["images"] == len(pairs) and "anchored_share" not in summary
    # one family anchored: 1 / N each there, the rest by error among the others
    anchored = torch.tensor([p.record.scene == "alpha" for p in pairs])
    n_a = int(anchored.sum())
    assert 0 < n_a < len(pairs)
    weights, summary = draw_weights(net, pairs, 1.0, 2.0, anchored=Anchors(frozenset({"alpha"})))
    assert float(weights.sum()) == pytest.approx(1.0)
    torch.testing.assert_close(weights[anchored], torch.full((n_a,), 1 / len(pairs), dtype=torch.float64))
    learning = [p for p, a in zip(pairs, anchored) if not a]
    expected = sampling_weights(image_errors(net, learning), 1.0, 2.0) * (len(learning) / len(pairs))
    torch.testing.assert_close(weights[~anchored], expected)
    assert summary["images"] == len(learning) and summary["anchored_share"] == pytest.approx(n_a / len(pairs))
    # every family anchored leaves nothing to draw by error: one line
    with pytest.raises(ValueError, match="every training image is anchored") as info:
        draw_weights(net, pairs, 0.5, anchored=Anchors(frozenset(p.record.scene for p in pairs)))
    assert "\n" not in str(info.value)


def test_fine_tune_draws_by_the_starting_error(tmp_path, synthetic_dataset):
    cfg = compose_cfg(
        tmp_path,
        synthetic_dataset,
        "experiment=fcnn_fast",
        "init_from=fcnn_fast",
        "hard_sampling.mix=0.5",
        "hard_sampling.power=2",
    )
    _, objects = train(cfg)
    summary = objects["model"].hparams["hard_sampling"]
    assert (
        summary["mix"] == 0.5
        and summary["power"] == 2.0
        and summary["images"] == len(objects["datamodule"].train_pairs)
    )
    cdf = objects["datamodule"].train_set.cdf
    assert cdf is not None and float(cdf[-1]) == pytest.approx(1.0)
    # uniform by default
    cfg = compose_cfg(tmp_path / "uniform", synthetic_dataset, "experiment=fcnn_fast")
    _, objects = train(cfg)
    assert objects["datamodule"].train_set.cdf is None and "hard_sampling" not in objects["model"].hparams


def test_train_refuses_a_bad_mix_before_any_work(tmp_path, synthetic_dataset):
    cfg = compose_cfg(tmp_path, synthetic_dataset, "experiment=fcnn_fast", "hard_sampling.mix=1.5")
    with pytest.raises(ValueError, match=r"hard_sampling.mix must be in \[0, 1\], got 1.5"):
        train(cfg)
    cfg = compose_cfg(
        tmp_path, synthetic_dataset, "experiment=fcnn_fast", "hard_sampling.mix=0.5", "hard_sampling.power=0"
    )
    with pytest.raises(ValueError, match="hard_sampling.power must be > 0, got 0"):
        train(cfg)
