"""The Scorer (tiling, layouts, HDR/LDR rule, sanitising) and shipped weights (nriqa.inference.pretrained)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from nriqa.cli.weights import main as pretrained_main
from nriqa.inference.pretrained import PretrainedError, list_pretrained, load_pretrained, save_pretrained
from nriqa.inference.scorer import Scorer, ScorerInputError
from nriqa.models import create_model

pytestmark = pytest.mark.usefixtures("one_thread")


def untrained(name: str, seed: int = 0) -> torch.nn.Module:
    """A fixed-seed model with non-trivial batch-norm statistics, so its map is not flat."""
    torch.manual_seed(seed)
    net = create_model(name)
    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.2, 0.2)
            m.running_var.uniform_(0.3, 1.5)
            m.bias.data.uniform_(0.0, 0.2)
    return net.eval()


@pytest.fixture(scope="module")
def fast_net():
    return untrained("fcnn_fast")


def image(h: int = 37, w: int = 45, scale: float = 3.0, seed: int = 0) -> np.ndarray:
    return (np.random.default_rng(seed).random((h, w, 3)) * scale).astype(np.float32)


@pytest.mark.parametrize("name, tile", [("fcnn", 16), ("fcnn_fast", 16), ("fcnn_fast", 15)])
def test_tiled_equals_untiled(name, tile):
    net = untrained(name)
    x = image(37, 45)
    whole = Scorer(net, tile=0)(x)
    tiled = Scorer(net, tile=tile)(x)
    assert whole.map.std() > 1e-4  # the comparison means something
    np.testing.assert_allclose(tiled.map, whole.map, atol=1e-5, rtol=0)
    assert tiled.score == pytest.approx(whole.score, abs=1e-6)


def brute_force_patch_map(net, ldr: torch.Tensor, stride: int) -> np.ndarray:
    """Independent reference: loop over windows, add each score to its pixels, divide by counts."""
    _, h, w = ldr.shape
    total, count = np.zeros((h, w)), np.zeros((h, w))
    ys = sorted(set(range(0, h - 32 + 1, stride)) | {h - 32})
    xs = sorted(set(range(0, w - 32 + 1, stride)) | {w - 32})
    with torch.inference_mode():
        for y in ys:
            for x in xs:
                s = float(net(ldr[None, :, y : y + 32, x : x + 32])[0, 0])
                total[y : y + 32, x : x + 32] += s
                count[y : y + 32, x : x + 32] += 1
    return total / count


def test_patch_map_matches_brute_force_and_is_tile_invariant():
    net = untrained("patch_cnn")
    x = image(40, 50, scale=1.0)
    scorer = Scorer(net, stride=8, tile=0)
    res = scorer(x)
    assert res.quantity == "mae" and not scorer.higher_is_better
    ldr = torch.from_numpy(x).permute(2, 0, 1)
    np.testing.assert_allclose(res.map, brute_force_patch_map(net, ldr, 8), atol=1e-5)
    np.testing.assert_allclose(Scorer(net, stride=8, tile=1)(x).map, res.map, atol=1e-5)
    assert res.score == pytest.approx(float(res.map.mean()), abs=1e-6)


def test_layouts_agree(fast_net):
    scorer = Scorer(fast_net)
    a, b = image(seed=1), image(seed=2)
    one = scorer(a)
    assert isinstance(one.map, np.ndarray) and one.map.shape == a.shape[:2] and isinstance(one.score, float)
    t = scorer(torch.from_numpy(a).permute(2, 0, 1))
    assert isinstance(t.map, torch.Tensor) and isinstance(t.score, float)
    np.testing.assert_allclose(t.map.numpy(), one.map, atol=1e-6)
    batch = scorer(np.stack([a, b]))
    assert batch.map.shape == (2, *a.shape[:2]) and batch.score.shape == (2,)
    tbatch = scorer(torch.from_numpy(np.stack([a, b])).permute(0, 3, 1, 2))
    assert isinstance(tbatch.score, torch.Tensor)
    np.testing.assert_allclose(batch.map[0], one.map, atol=1e-5)
    np.testing.assert_allclose(tbatch.map.numpy(), batch.map, atol=1e-5)
    assert batch.score[1] == pytest.approx(scorer(b).score, abs=1e-6)


def test_deterministic(fast_net):
    x = image()
    first, second = Scorer(fast_net)(x), Scorer(fast_net)(x)
    assert np.array_equal(first.map, second.map) and first.score == second.score


def test_hdr_ldr_detection(fast_net):
    scorer = Scorer(fast_net)
    ldr = image(scale=1.0)
    hdr = image(scale=4.0)
    assert scorer(ldr).hdr is False and scorer(hdr).hdr is True
    assert np.array_equal(scorer(ldr).map, scorer(ldr, hdr=False).map)
    assert np.array_equal(scorer(hdr).map, scorer(hdr, hdr=True).map)
    assert not np.allclose(scorer(ldr, hdr=True).map, scorer(ldr).map)  # forcing HDR tone-maps
    assert scorer(np.stack([ldr, hdr])).hdr == [False, True]  # decided per image
    as_u8 = (ldr * 255).round().astype(np.uint8)
    np.testing.assert_allclose(scorer(as_u8).map, scorer(as_u8.astype(np.float32) / 255).map, atol=1e-6)
    as_u16 = (ldr * 65535).round().astype(np.uint16)
    assert scorer(as_u16).hdr is False


def test_gray_and_alpha(fast_net):
    scorer = Scorer(fast_net)
    x = image(scale=1.0)
    gray = x[..., 0]
    np.testing.assert_array_equal(scorer(gray).map, scorer(np.repeat(gray[..., None], 3, axis=2)).map)
    rgba = np.concatenate([x, np.full(x.shape[:2] + (1,), 0.3, np.float32)], axis=2)
    np.testing.assert_array_equal(scorer(rgba).map, scorer(x).map)


@pytest.mark.parametrize("hdr", [None, True, False])
def test_bad_pixels_never_nan(fast_net, hdr):
    x = image(scale=2.0)
    x[0, 0] = np.nan
    x[1, 1] = np.inf
    x[2, 2] = -np.inf
    x[3, 3] = -5.0
    x[4, 4] = 3e38
    res = Scorer(fast_net)(x, hdr=hdr)
    assert np.isfinite(res.map).all() and np.isfinite(res.score)
    assert np.isfinite(Scorer(fast_net)(np.full((20, 20, 3), np.nan, np.float32), hdr=hdr).score)


def test_bad_pixel_policy_matches_clean_equivalent(fast_net):
    """NaN and negative count as 0; +inf in LDR as 1 (white)."""
    scorer = Scorer(fast_net)
    x = image(scale=1.0)
    dirty, clean = x.copy(), x.copy()
    dirty[5, 5], clean[5, 5] = np.nan, 0.0
    dirty[6, 6], clean[6, 6] = -2.0, 0.0
    dirty[7, 7], clean[7, 7] = np.inf, 1.0
    np.testing.assert_array_equal(scorer(dirty, hdr=False).map, scorer(clean, hdr=False).map)


def test_refuses_bad_inputs(fast_net):
    scorer = Scorer(fast_net)
    with pytest.raises(ScorerInputError, match="smaller than the 14x14 receptive field"):
        scorer(image(8, 40))
    with pytest.raises(ScorerInputError, match="channels"):
        scorer(np.zeros((20, 20, 5), np.float32))
    with pytest.raises(ScorerInputError, match="expected"):
        scorer(np.zeros((1, 2, 20, 20, 3), np.float32))
    with pytest.raises(ScorerInputError, match="numpy array or torch tensor"):
        scorer([[0.0]])
    with pytest.raises(ScorerInputError, match="32x32 receptive field of PatchCNN"):
        Scorer(untrained("patch_cnn"))(image(31, 40))


def test_pretrained_roundtrip(tmp_path, fast_net):
    pt = save_pretrained(fast_net, "fcnn_fast", {"data": "tiny", "val_srocc": 0.5}, dir=tmp_path)
    assert list_pretrained(tmp_path) == ["fcnn_fast"]
    payload = torch.load(pt, weights_only=True)  # plain data only
    assert payload["spec"] == {"name": "fcnn_fast"}
    card = json.loads(pt.with_suffix(".json").read_text())
    assert card["data"] == "tiny" and len(card["sha256"]) == 64 and card["parameters"] == 90_052
    x = image()
    np.testing.assert_array_equal(Scorer.from_pretrained("fcnn_fast", dir=tmp_path)(x).map, Scorer(fast_net)(x).map)
    assert not load_pretrained(str(pt)).training  # a path to the .pt works too


def test_pretrained_export_is_reproducible(tmp_path, fast_net):
    """The same weights exported twice are the same bytes (the card's sha256 names the weights, not the export)."""
    shas = [
        json.loads(save_pretrained(fast_net, "fcnn_fast", {}, dir=tmp_path / d).with_suffix(".json").read_text())[
            "sha256"
        ]
        for d in ("a", "b")
    ]
    assert shas[0] == shas[1]


def test_pretrained_unknown_name_lists_available(tmp_path, fast_net):
    save_pretrained(fast_net, "fcnn_fast", {}, dir=tmp_path)
    with pytest.raises(PretrainedError, match="no shipped weights 'nope'.*available: fcnn_fast"):
        load_pretrained("nope", dir=tmp_path)
    with pytest.raises(PretrainedError, match="none are there yet"):
        load_pretrained("fcnn_fast", dir=tmp_path / "empty")


def test_pretrained_checksum_mismatch_refused(tmp_path, fast_net):
    pt = save_pretrained(fast_net, "fcnn_fast", {}, dir=tmp_path)
    data = bytearray(pt.read_bytes())
    data[-20] ^= 0xFF
    pt.write_bytes(bytes(data))
    with pytest.raises(PretrainedError, match="sha256 mismatch"):
        load_pretrained("fcnn_fast", dir=tmp_path)


def test_save_pretrained_checks_spec(tmp_path, fast_net):
    with pytest.raises(PretrainedError, match="does not rebuild"):
        save_pretrained(fast_net, "x", {}, dir=tmp_path, spec={"name": "fcnn"})
    assert not list(tmp_path.iterdir())


def test_export_command(tmp_path, fast_net, capsys):
    # The parts of a Lightning checkpoint that load_net_from_checkpoint reads.
    ckpt = tmp_path / "best.ckpt"
    state = {f"net.{k}": v for k, v in fast_net.state_dict().items()}
    torch.save({"state_dict": state, "hyper_parameters": {"net": {"name": "fcnn_fast"}}}, ckpt)
    out = tmp_path / "weights"
    args = ["export", str(ckpt), "shipped", "--card", "data=tiny", "--card", "val_srocc=0.75", "--dir", str(out)]
    assert pretrained_main(args) == 0
    card = json.loads((out / "shipped.json").read_text())
    assert card["val_srocc"] == 0.75 and card["data"] == "tiny" and card["checkpoint"] == str(ckpt) and "commit" in card
    x = image()
    np.testing.assert_array_equal(
        Scorer.from_pretrained("shipped", dir=out)(x).map, Scorer.from_checkpoint(ckpt)(x).map
    )
    assert pretrained_main(["export", str(tmp_path / "missing.ckpt"), "x", "--dir", str(out)]) == 2
    assert "no such checkpoint" in capsys.readouterr().err
