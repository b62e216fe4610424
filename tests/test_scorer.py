"""The Scorer (tiling, layouts, HDR/LDR rule, sanitising) and shipped weights (nriqa.inference.pretrained)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from nriqa.cli.weights import main as pretrained_main
from nriqa.core.ssim import flat_windows
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


def test_the_card_says_which_pixel_filter_the_weights_read(tmp_path, fast_net):
    spec = {"name": "fcnn_fast"}
    save_pretrained(fast_net, "plain", {}, dir=tmp_path, spec=spec)
    save_pretrained(fast_net, "gauss", {"pixel_filter": "gaussian"}, dir=tmp_path, spec=spec)
    save_pretrained(fast_net, "odd", {"pixel_filter": "tent"}, dir=tmp_path, spec=spec)
    assert Scorer.from_pretrained("plain", dir=tmp_path).pixel_filter == "box"  # a card that says none: box
    assert Scorer.from_pretrained("gauss", dir=tmp_path).pixel_filter == "gaussian"
    assert Scorer.from_pretrained("gauss", dir=tmp_path, pixel_filter="box").pixel_filter == "box"
    with pytest.raises(PretrainedError, match=r"weights 'odd': the card's pixel_filter 'tent' is none of"):
        Scorer.from_pretrained("odd", dir=tmp_path)


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


def _windowed_unet(window=32):
    torch.manual_seed(0)
    return create_model("unet_fast", width=8, depth=1, window=window).eval()


def test_window_model_reads_large_images_in_independent_pieces():
    """Each window-side piece is scored alone, as in training; the last piece is moved in, overlaps averaged."""
    net = _windowed_unet(32)
    x = np.random.default_rng(3).random((80, 72, 3)).astype(np.float32)
    scorer = Scorer(net)
    assert scorer.window == 32
    qmap = scorer(x, hdr=False).map
    t = torch.from_numpy(x).permute(2, 0, 1)[None]
    with torch.inference_mode():
        alone = lambda y0, x0: net(t[..., y0 : y0 + 32, x0 : x0 + 32])[0, 0].clamp(0, 1).numpy()  # noqa: E731
        np.testing.assert_allclose(qmap[:32, :32], alone(0, 0), atol=1e-6)
        np.testing.assert_allclose(qmap[32:48, 32:40], alone(32, 32)[:16, :8], atol=1e-6)
        # rows 64..79 only in the piece moved in (48..79); rows 48..63 the mean of two pieces
        np.testing.assert_allclose(qmap[64:, :32], alone(48, 0)[16:], atol=1e-6)
        np.testing.assert_allclose(qmap[48:64, :32], (alone(32, 0)[16:] + alone(48, 0)[:16]) / 2, atol=1e-6)
    # a change in another piece leaves this piece's map alone; window=0 reads the image in one piece
    y = x.copy()
    y[40:, 40:] = 1.0
    np.testing.assert_array_equal(scorer(y, hdr=False).map[:32, :32], qmap[:32, :32])
    with torch.inference_mode():
        whole = net(t)[0, 0].clamp(0, 1).numpy()
    np.testing.assert_allclose(Scorer(net, window=0)(x, hdr=False).map, whole, atol=1e-6)


def test_window_leaves_small_images_whole_and_batches_agree():
    net = _windowed_unet(64)
    rng = np.random.default_rng(4)
    small = rng.random((64, 48, 3)).astype(np.float32)
    with torch.inference_mode():
        whole = net(torch.from_numpy(small).permute(2, 0, 1)[None])[0, 0].clamp(0, 1).numpy()
    np.testing.assert_allclose(Scorer(net)(small, hdr=False).map, whole, atol=1e-6)
    batch = rng.random((3, 150, 100, 3)).astype(np.float32)
    scorer = Scorer(net, tile=64)  # tile only sizes the chunks of pieces per forward here
    maps = scorer(batch, hdr=False).map
    for i in range(3):
        np.testing.assert_allclose(maps[i], Scorer(net)(batch[i], hdr=False).map, atol=1e-6)
    with pytest.raises(ValueError, match="window"):
        Scorer(net, window=-1)


def test_overlap_blends_half_window_steps_with_tent_weights():
    """``overlap=True``: pieces every half window, each pixel the tent-weighted mean of the pieces over it."""
    net = _windowed_unet(32)
    x = np.random.default_rng(5).random((64, 48, 3)).astype(np.float32)
    qmap = Scorer(net, overlap=True)(x, hdr=False).map
    t = torch.from_numpy(x).permute(2, 0, 1)[None]
    tent = (np.minimum(np.arange(32) + 0.5, 32 - np.arange(32) - 0.5) / 16).astype(np.float32)
    weight = tent[:, None] * tent[None, :]
    total, count = np.zeros((64, 48)), np.zeros((64, 48))
    with torch.inference_mode():
        for y0 in (0, 16, 32):  # rows: 64 = 32 + 2 half steps; columns: 48 = 32 + 1
            for x0 in (0, 16):
                piece = net(t[..., y0 : y0 + 32, x0 : x0 + 32])[0, 0].clamp(0, 1).numpy()
                total[y0 : y0 + 32, x0 : x0 + 32] += piece * weight
                count[y0 : y0 + 32, x0 : x0 + 32] += weight
    np.testing.assert_allclose(qmap, total / count, atol=1e-5)
    # two tents half a window apart sum to 1: interior weights form a partition of unity
    np.testing.assert_allclose(tent[:16] + tent[16:], 1.0, atol=1e-6)
    # images no larger than the window, and models not read in windows, are read as without overlap
    small = x[:32, :32]
    np.testing.assert_array_equal(Scorer(net, overlap=True)(small, hdr=False).map, Scorer(net)(small, hdr=False).map)
    fast = untrained("fcnn_fast")
    np.testing.assert_array_equal(Scorer(fast, overlap=True)(x, hdr=False).map, Scorer(fast)(x, hdr=False).map)


def test_overlap_removes_the_seams_of_the_window_grid():
    """On stationary noise the shipped default's side-by-side map steps where its 64x64 pieces meet
    (5.6 times the median jump between columns); the blended map does not (1.0 times)."""
    net = load_pretrained("unet_fast")
    x = np.clip(0.4 + 0.15 * np.random.default_rng(0).standard_normal((256, 256, 3)), 0, 1).astype(np.float32)

    def seam_ratio(qmap):
        jumps = np.abs(np.diff(qmap, axis=1)).mean(axis=0)  # jumps[j]: between columns j and j + 1
        return jumps[[63, 127, 191]].mean() / np.median(jumps)

    side_by_side = seam_ratio(Scorer(net)(x, hdr=False).map)
    blended = seam_ratio(Scorer(net, overlap=True)(x, hdr=False).map)
    assert side_by_side > 3.0 and blended < 1.5, (side_by_side, blended)


def test_export_spec_states_the_window(tmp_path, capsys):
    net = _windowed_unet(0)
    ckpt = tmp_path / "last.ckpt"
    state = {f"net.{k}": v for k, v in net.state_dict().items()}
    torch.save({"state_dict": state, "hyper_parameters": {"net": {"name": "unet_fast", "width": 8, "depth": 1}}}, ckpt)
    out = tmp_path / "weights"
    assert pretrained_main(["export", str(ckpt), "u", "--spec", "window=32", "--dir", str(out)]) == 0
    shipped = Scorer.from_pretrained("u", dir=out)
    assert shipped.window == 32 and json.loads((out / "u.json").read_text())["spec"]["window"] == 32
    assert pretrained_main(["export", str(ckpt), "v", "--spec", "windw=32", "--dir", str(out)]) == 2
    err = capsys.readouterr().err
    assert "does not fit its weights" in err and len(err.strip().splitlines()) == 1
    assert not (out / "v.pt").exists()


def test_export_of_several_checkpoints_ships_their_mean(tmp_path, capsys):
    nets, ckpts = [], []
    for seed in (0, 1):
        torch.manual_seed(seed)
        nets.append(create_model("unet_fast", width=8, depth=1, window=32).eval())
        ckpts.append(tmp_path / f"s{seed}.ckpt")
        state = {f"net.{k}": v for k, v in nets[-1].state_dict().items()}
        spec = {"name": "unet_fast", "width": 8, "depth": 1}
        torch.save({"state_dict": state, "hyper_parameters": {"net": spec}, "epoch": 5}, ckpts[-1])
    out = tmp_path / "weights"
    args = ["export", *map(str, ckpts), "pair", "--spec", "window=32", "--dir", str(out)]
    assert pretrained_main(args) == 0
    card = json.loads((out / "pair.json").read_text())
    assert card["spec"]["name"] == "map_mean" and card["checkpoint"] == [str(c) for c in ckpts]
    assert card["epoch"] == [5, 5] and [m["window"] for m in card["spec"]["members"]] == [32, 32]
    x = image()
    pair = Scorer.from_pretrained("pair", dir=out)
    assert pair.window == 32
    maps = [Scorer(n)(x).map for n in nets]
    np.testing.assert_allclose(pair(x).map, np.clip((maps[0] + maps[1]) / 2, 0, 1), atol=1e-5)
    twin_spec = {"name": "unet_fast_twin", "width": 8, "depth": 1}  # six channels in: cannot be averaged with one image
    other = {f"net.{k}": v for k, v in create_model(**twin_spec).state_dict().items()}
    torch.save({"state_dict": other, "hyper_parameters": {"net": twin_spec}}, tmp_path / "other.ckpt")
    assert pretrained_main(["export", str(ckpts[0]), str(tmp_path / "other.ckpt"), "x", "--dir", str(out)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1 and not (out / "x.pt").exists()


def test_interpolate_ships_the_weights_between_a_start_and_its_fine_tune(tmp_path, capsys):
    """``nriqa-weights interpolate``: every float tensor at (1 - alpha) start + alpha end, one network of the
    same size; alpha 0 and 1 give the two exactly; a shipped start, a checkpoint end; mismatches refused."""
    out = tmp_path / "weights"
    spec = {"name": "unet_fast", "width": 8, "depth": 1}
    nets = []
    for seed in (0, 1):
        torch.manual_seed(seed)
        nets.append(create_model(**spec, window=32).train())
        nets[-1](torch.rand(2, 3, 32, 32))  # batch-norm statistics of its own
    save_pretrained(nets[0].eval(), "start", {"data": "tiny"}, dir=out, spec={**spec, "window": 32})
    ckpt = tmp_path / "fine.ckpt"
    torch.save(
        {
            "state_dict": {f"net.{k}": v for k, v in nets[1].state_dict().items()},
            "hyper_parameters": {"net": spec},
            "global_step": 40,
        },
        ckpt,
    )
    start = str(out / "start.pt")
    for alpha, name in ((0.0, "a0"), (0.25, "a25"), (1.0, "a1")):
        args = ["interpolate", start, str(ckpt), name, "--alpha", str(alpha), "--spec", "window=32", "--dir", str(out)]
        assert pretrained_main(args) == 0
    got = {n: torch.load(out / f"{n}.pt", weights_only=True)["state_dict"] for n in ("a0", "a25", "a1")}
    a, b = nets[0].state_dict(), nets[1].state_dict()
    for k in a:
        torch.testing.assert_close(got["a0"][k], a[k], rtol=0, atol=0)
        if a[k].is_floating_point():
            torch.testing.assert_close(got["a1"][k], b[k], rtol=0, atol=0)
            torch.testing.assert_close(got["a25"][k], 0.75 * a[k] + 0.25 * b[k])
        else:  # batch norm's step count: the start's
            assert torch.equal(got["a25"][k], a[k])
    card = json.loads((out / "a25.json").read_text())
    assert card["interpolated"]["alpha"] == 0.25 and card["interpolated"]["end"]["global_step"] == 40
    assert card["interpolated"]["start"]["sha256"] == json.loads((out / "start.json").read_text())["sha256"]
    assert card["parameters"] == json.loads((out / "start.json").read_text())["parameters"]
    assert Scorer.from_pretrained("a25", dir=out).window == 32
    capsys.readouterr()
    wider = {"name": "unet_fast", "width": 16, "depth": 1}
    torch.save(
        {
            "state_dict": {f"net.{k}": v for k, v in create_model(**wider).state_dict().items()},
            "hyper_parameters": {"net": wider},
        },
        tmp_path / "wide.ckpt",
    )
    for bad in (
        ["interpolate", start, str(ckpt), "x", "--alpha", "1.5", "--spec", "window=32"],
        ["interpolate", start, str(ckpt), "x", "--alpha", "0.5"],  # the checkpoint's spec lacks window=32
        ["interpolate", str(ckpt), str(tmp_path / "wide.ckpt"), "x", "--alpha", "0.5"],
        ["interpolate", "nope", str(ckpt), "x", "--alpha", "0.5"],
    ):
        assert pretrained_main([*bad, "--dir", str(out)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "error:" in err, err
    assert not (out / "x.pt").exists()


def test_flat_bright_windows_score_one(fast_net):
    """Where the whole SSIM window is one bright colour the map is 1; elsewhere it is the network's."""
    x = image(40, 48, scale=0.9)
    x[4:30, 10:40] = 1.0  # clipped white
    x[30:, 0:25] = (0.6, 0.5, 0.2)  # a flat backdrop touching the border
    raw = Scorer(fast_net, exact_flat=False)(x).map
    res = Scorer(fast_net)(x)
    inside = np.zeros(x.shape[:2], bool)
    inside[9:25, 15:35] = True
    inside[35:, 0:20] = True
    assert (raw[inside] < 1).all() and (res.map[inside] == 1).all()
    np.testing.assert_array_equal(res.map[~inside], raw[~inside])
    assert res.score == pytest.approx(float(res.map.mean(dtype=np.float64)), abs=1e-6)
    tiled = Scorer(fast_net, tile=16)(x).map  # the flat test is tiled with the network: the same pixels
    np.testing.assert_array_equal(tiled[inside], res.map[inside])
    assert ((tiled == 1) == (res.map == 1)).all()
    # A blown-out or flat bright image is converged, as LDR, as 8-bit or as HDR (+inf is white).
    for flat in (np.ones((20, 20, 3), np.float32), np.full((20, 20, 3), 255, np.uint8), np.full((20, 20, 3), 0.5)):
        assert Scorer(fast_net)(flat).score == 1.0
    assert Scorer(fast_net)(np.full((20, 20, 3), np.inf, np.float32), hdr=True).score == 1.0
    one_inf = np.zeros((20, 20, 3), np.float32)
    one_inf[..., 0] = np.inf  # the tone map whitens a pixel with any +inf channel
    assert Scorer(fast_net)(one_inf, hdr=True).score == 1.0
    # Black and dark flat windows are the network's: most often no sample has reached them yet.
    for dark in (np.zeros((20, 20, 3), np.float32), np.full((20, 20, 3), 0.05, np.float32)):
        assert Scorer(fast_net)(dark).score < 1.0
    # Bad LDR pixels count as the sanitising policy makes them: above 1 and +inf white, NaN black.
    dirty = x.copy()
    dirty[10, 20], dirty[12, 22], dirty[20, 30] = 3.0, np.inf, np.nan
    got = Scorer(fast_net)(dirty, hdr=False).map == 1
    want = flat_windows(Scorer.prepare(torch.from_numpy(dirty).permute(2, 0, 1)[None], [False]))[0].numpy()
    assert want[12, 22] and not want[20, 30] and np.array_equal(got, want)
    # The MAE-patch model's map is an error, not an SSIM: left alone.
    patch = untrained("patch_cnn")
    np.testing.assert_array_equal(Scorer(patch)(x).map, Scorer(patch, exact_flat=False)(x).map)
