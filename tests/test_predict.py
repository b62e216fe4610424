"""predict.py: reading every kind of input file, bad files, JSON output, exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import skimage.io
import torch

from nriqa.cli import predict
from nriqa.inference import DEFAULT_WEIGHTS
from nriqa.inference.pretrained import save_pretrained
from nriqa.io.exr import ImageReadError, read_exr, write_exr
from nriqa.io.imread import read_image
from nriqa.models import create_model

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def weights(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    out = tmp_path_factory.mktemp("weights")
    save_pretrained(create_model("fcnn_fast"), "fcnn_fast", {"note": "untrained, for tests"}, dir=out)
    return out


def run_predict_py(cwd: Path, weights: Path, *args: str) -> subprocess.CompletedProcess:
    """``python predict.py ARGS`` in a subprocess with the test weights (``fcnn_fast`` by name: these
    24x30 images are below ``unet_fast``'s 32-pixel minimum); one torch thread."""
    cmd = [sys.executable, str(REPO / "predict.py"), *args, "--weights-dir", str(weights), "--model", "fcnn_fast"]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}  # tiny images: one thread is faster on a shared CPU
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def rgb(h=24, w=30, scale=3.0, seed=0) -> np.ndarray:
    return (np.random.default_rng(seed).random((h, w, 3)) * scale).astype(np.float32)


def tiles(x, y):
    td = OpenEXR.TileDescription()
    td.xSize, td.ySize, td.mode = x, y, OpenEXR.ONE_LEVEL
    return td


# --- EXR kinds ------------------------------------------------------------------------------


def test_exr_rgb_float_scanline(tmp_path):
    a = rgb()
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": a}).write(str(tmp_path / "a.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), a)


def test_exr_rgba_half_tiled(tmp_path):
    a = rgb()
    rgba = np.concatenate([a, np.ones(a.shape[:2] + (1,), np.float32)], axis=2).astype(np.float16)
    OpenEXR.File({"type": OpenEXR.tiledimage, "tiles": tiles(8, 8)}, {"RGBA": rgba}).write(str(tmp_path / "a.exr"))
    out = read_exr(tmp_path / "a.exr")
    assert out.dtype == np.float32 and out.shape == a.shape
    np.testing.assert_allclose(out, a, rtol=1e-3)


@pytest.mark.parametrize("channel", ["Y", "L", "Z"])
def test_exr_luminance_only(tmp_path, channel):
    y = rgb()[..., 0].astype(np.float16)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {channel: y}).write(str(tmp_path / "y.exr"))
    out = read_exr(tmp_path / "y.exr")
    assert out.shape == y.shape + (3,)
    np.testing.assert_array_equal(out[..., 2], y.astype(np.float32))


def test_exr_multipart_and_deep_refused(tmp_path):
    a = rgb()
    OpenEXR.File([OpenEXR.Part({}, {"RGB": a}, "left"), OpenEXR.Part({}, {"RGB": a}, "right")]).write(
        str(tmp_path / "m.exr")
    )
    with pytest.raises(ImageReadError, match="multi-part"):
        read_exr(tmp_path / "m.exr")
    z = np.empty((4, 5), dtype=object)
    for idx in np.ndindex(z.shape):
        z[idx] = np.ones(1 + sum(idx) % 2, np.float32)
    OpenEXR.File({"type": OpenEXR.deepscanline, "compression": OpenEXR.ZIPS_COMPRESSION}, {"Z": z}).write(
        str(tmp_path / "d.exr")
    )
    with pytest.raises(ImageReadError, match="deep"):
        read_exr(tmp_path / "d.exr")


# --- LDR files ------------------------------------------------------------------------------


def test_read_png_jpeg_kinds(tmp_path):
    rng = np.random.default_rng(0)
    u8 = (rng.random((20, 22, 4)) * 255).astype(np.uint8)
    skimage.io.imsave(tmp_path / "rgba.png", u8, check_contrast=False)
    img, hdr = read_image(tmp_path / "rgba.png")
    assert not hdr and img.shape == (20, 22, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img, u8[..., :3] / 255.0, atol=1e-6)
    u16 = (rng.random((20, 22)) * 65535).astype(np.uint16)
    skimage.io.imsave(tmp_path / "gray16.png", u16, check_contrast=False)
    img, _ = read_image(tmp_path / "gray16.png")
    np.testing.assert_allclose(img[..., 1], u16 / 65535.0, atol=1e-6)
    skimage.io.imsave(tmp_path / "photo.jpg", u8[..., :3], check_contrast=False)
    img, hdr = read_image(tmp_path / "photo.jpg")
    assert not hdr and img.shape == (20, 22, 3) and 0 <= img.min() and img.max() <= 1
    with pytest.raises(ImageReadError, match="unsupported file type"):
        read_image(tmp_path / "photo.jpg.txt" if (tmp_path / "photo.jpg.txt").write_text("x") else None)


# --- the command line -----------------------------------------------------------------------


def bad_inputs(root: Path) -> tuple[list[str], list[str]]:
    """Write good and bad inputs; return (good paths, bad paths)."""
    write_exr(root / "good.exr", rgb())
    skimage.io.imsave(root / "good.png", (rgb(scale=1) * 255).astype(np.uint8), check_contrast=False)
    skimage.io.imsave(root / "gray16.png", (rgb(scale=1)[..., 0] * 65535).astype(np.uint16), check_contrast=False)
    rgba = np.concatenate([rgb(scale=1), np.full((24, 30, 1), 0.5, np.float32)], axis=2)
    skimage.io.imsave(root / "alpha.png", (rgba * 255).astype(np.uint8), check_contrast=False)
    dirty = rgb()
    dirty[0, 0], dirty[1, 1], dirty[2, 2], dirty[3, 3] = np.nan, np.inf, -4.0, 1e38
    write_exr(root / "dirty.exr", dirty)
    good = ["good.exr", "good.png", "gray16.png", "alpha.png", "dirty.exr"]

    (root / "folder").mkdir()
    (root / "truncated.png").write_bytes((root / "good.png").read_bytes()[:120])
    (root / "text.png").write_text("not an image\n")
    (root / "truncated.exr").write_bytes((root / "good.exr").read_bytes()[:300])
    write_exr(root / "small.exr", rgb(8, 8))
    OpenEXR.File([OpenEXR.Part({}, {"RGB": rgb()}, "a"), OpenEXR.Part({}, {"RGB": rgb()}, "b")]).write(
        str(root / "multi.exr")
    )
    (root / "notes.txt").write_text("hello")
    bad = ["missing.exr", "folder", "truncated.png", "text.png", "truncated.exr", "small.exr", "multi.exr", "notes.txt"]
    return good, bad


def test_cli_bad_files_do_not_stop_the_others(tmp_path, weights):
    good, bad = bad_inputs(tmp_path)
    files = [good[0], *bad[:4], *good[1:], *bad[4:]]
    proc = run_predict_py(tmp_path, weights, *files, "--json", "--out", "out", "--no-figures")
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    warnings = [line for line in lines if line.startswith("predict.py: warning: ")]
    errors = [line for line in lines if line not in warnings]
    assert len(errors) == len(bad), proc.stderr  # one line per bad file, no traceback
    assert warnings == [
        "predict.py: warning: dirty.exr: 2 of 720 pixels are NaN or infinite; scored as if NaN and "
        "-Inf were 0, +Inf white"
    ]
    for line, name in zip(errors, bad):
        assert line.startswith("predict.py: error: ") and name in line
    assert "smaller than the 14x14 receptive field" in errors[bad.index("small.exr")]
    assert "multi-part" in errors[bad.index("multi.exr")]
    rows = [json.loads(line) for line in proc.stdout.strip().splitlines()]
    assert [r["path"] for r in rows] == good
    for r in rows:
        assert {"path", "score", "height", "width", "seconds", "hdr", "map"} <= r.keys()
        assert r["pixel_filter"] == "box"  # the weights' card names no filter: box
        assert np.isfinite(r["score"]) and (r["height"], r["width"]) == (24, 30)
        assert r["hdr"] == r["path"].endswith(".exr")
        qmap = read_exr(tmp_path / r["map"])
        assert qmap.shape == (24, 30, 3) and np.isfinite(qmap).all()
        assert np.mean(qmap[..., 0]) == pytest.approx(r["score"], abs=1e-5)
    assert not list((tmp_path / "out").glob("*.partial*"))


def test_cli_without_weights_is_one_line(tmp_path, capsys):
    write_exr(tmp_path / "a.exr", rgb())
    code = predict.main(
        [str(tmp_path / "a.exr"), "--weights-dir", str(tmp_path / "none"), "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"no shipped weights '{DEFAULT_WEIGHTS}'" in err[0]


def test_cli_plain_output_is_deterministic_and_flags_override(tmp_path, weights, capsys):
    write_exr(tmp_path / "a.exr", rgb(scale=1.0))
    args = [str(tmp_path / "a.exr"), "--weights-dir", str(weights), "--model", "fcnn_fast", "--out"]
    assert predict.main([*args, str(tmp_path / "o1")]) == 0
    assert predict.main([*args, str(tmp_path / "o2"), "--no-figures"]) == 0
    assert predict.main([*args, str(tmp_path / "o3"), "--no-figures", "--ldr"]) == 0
    assert (tmp_path / "o1" / "a_figure.png").stat().st_size > 1000 and not (tmp_path / "o2" / "a_figure.png").exists()
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == lines[1] and lines[0].split()[0] == str(tmp_path / "a.exr")
    assert lines[2] != lines[0]  # --ldr skips the tone map of an in-range EXR
    np.testing.assert_array_equal(read_exr(tmp_path / "o1" / "a_map.exr"), read_exr(tmp_path / "o2" / "a_map.exr"))


def test_cli_device_cpu_is_the_default_and_an_unusable_device_is_one_line(tmp_path, weights, capsys):
    write_exr(tmp_path / "a.exr", rgb(scale=1.0))
    args = [str(tmp_path / "a.exr"), "--weights-dir", str(weights), "--model", "fcnn_fast", "--no-figures", "--out"]
    assert predict.main([*args, str(tmp_path / "o1")]) == 0
    assert predict.main([*args, str(tmp_path / "o2"), "--device", "cpu"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == lines[1]
    refused = [("gpu0", "is not a torch device")]
    if not torch.cuda.is_available():
        refused.append(("cuda", "not usable here"))
    for device, why in refused:
        assert predict.main([*args, str(tmp_path / "o3"), "--device", device]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0] and f"--device {device}" in err[0].replace("'", "")
    assert not (tmp_path / "o3").exists()


# --- truncated EXR: stdout carries only results ---------------------------------------------


def truncated_exr(root: Path) -> Path:
    """The first 30 kB of a valid EXR (a 128x128 float image, ~190 kB)."""
    write_exr(root / "whole.exr", rgb(128, 128))
    data = (root / "whole.exr").read_bytes()
    assert len(data) > 60_000
    (root / "cut.exr").write_bytes(data[:30_000])
    return root / "cut.exr"


def test_truncated_exr_is_named_and_silent(tmp_path, capfd):
    cut = truncated_exr(tmp_path)
    with pytest.raises(ImageReadError, match="truncated or damaged") as info:
        read_exr(cut)
    assert "multi-part" not in str(info.value) and str(cut) in str(info.value)
    (tmp_path / "head.exr").write_bytes(cut.read_bytes()[:300])  # even the header cut short
    with pytest.raises(ImageReadError, match="truncated or damaged"):
        read_exr(tmp_path / "head.exr")
    out, err = capfd.readouterr()  # the file descriptors: what the C++ library would print
    assert out == "" and err == ""
    np.testing.assert_array_equal(read_exr(tmp_path / "whole.exr"), rgb(128, 128))  # reading still works


def test_truncated_exr_in_a_json_batch(tmp_path, weights):
    cut = truncated_exr(tmp_path)
    write_exr(tmp_path / "a.exr", rgb())
    write_exr(tmp_path / "b.exr", rgb(seed=1))
    files = ["a.exr", cut.name, "b.exr"]
    proc = run_predict_py(tmp_path, weights, *files, "--json", "--no-figures")
    assert proc.returncode == 1
    rows = [json.loads(line) for line in proc.stdout.splitlines()]  # every stdout line is a result
    assert [r["path"] for r in rows] == ["a.exr", "b.exr"]
    (error,) = proc.stderr.splitlines()
    assert error.startswith("predict.py: error: ") and cut.name in error and "truncated or damaged" in error


def test_progress_bar_goes_to_stderr(tmp_path, weights, capsys):
    for k in range(2):
        write_exr(tmp_path / f"{k}.exr", rgb(seed=k))
    files = [str(tmp_path / f"{k}.exr") for k in range(2)]
    args = [
        *files,
        "--weights-dir",
        str(weights),
        "--model",
        "fcnn_fast",
        "--out",
        str(tmp_path / "o"),
        "--no-figures",
        "--progress",
        "on",
    ]
    assert predict.main(args) == 0
    out, err = capsys.readouterr()
    assert [line.split()[0] for line in out.splitlines()] == files
    assert "2/2" in err


@pytest.fixture(scope="module")
def twin_weights(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    out = tmp_path_factory.mktemp("twin_weights")
    net = create_model("unet_fast_twin", width=8, depth=1)
    spec = {"name": "unet_fast_twin", "width": 8, "depth": 1}
    save_pretrained(net, "unet_fast_twin", {"note": "untrained, for tests"}, dir=out, spec=spec)
    return out


def _predict(tmp_path, *args):
    cmd = [sys.executable, str(REPO / "predict.py"), *args, "--out", "out", "--no-figures"]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)


def test_cli_twin_scores_with_a_two_buffer_model(tmp_path, twin_weights, weights):
    for i, seed in enumerate((1, 2, 3, 4)):
        write_exr(tmp_path / f"{'ab'[i % 2]}{i // 2}.exr", rgb(40, 48, seed=seed))
    twin_args = ["--model", "unet_fast_twin", "--weights-dir", str(twin_weights)]
    proc = _predict(tmp_path, "a0.exr", "a1.exr", "--twin", "b0.exr", "b1.exr", *twin_args, "--json")
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [(r["path"], r["twin"]) for r in rows] == [("a0.exr", "b0.exr"), ("a1.exr", "b1.exr")]
    assert all(np.isfinite(r["score"]) for r in rows)
    # without a twin, with too few twins, or a twin for a one-image model: one line, exit 2, nothing scored
    for args, message in (
        (["a0.exr", *twin_args], "pass --twin TWIN"),
        (["a0.exr", "a1.exr", "--twin", "b0.exr", *twin_args], "give one twin per image"),
        (
            ["a0.exr", "--twin", "b0.exr", "--weights-dir", str(weights), "--model", "fcnn_fast"],
            "needs a two-buffer model",
        ),
    ):
        proc = _predict(tmp_path, *args)
        assert proc.returncode == 2 and proc.stdout == ""
        (line,) = proc.stderr.strip().splitlines()
        assert message in line


def test_cli_albedo_scores_with_a_model_that_takes_the_pass(tmp_path, weights):
    torch.manual_seed(0)
    spec = {"name": "unet_fast_albedo", "width": 8, "depth": 1}
    save_pretrained(create_model(**spec), "unet_fast_albedo", {"note": "untrained, for tests"}, dir=tmp_path, spec=spec)
    write_exr(tmp_path / "a.exr", rgb(40, 48, seed=1))
    write_exr(tmp_path / "alb.exr", np.clip(rgb(40, 48, seed=2), 0, 1))
    model = ["--model", "unet_fast_albedo", "--weights-dir", str(tmp_path)]
    proc = _predict(tmp_path, "a.exr", "--albedo", "alb.exr", *model, "--json")
    assert proc.returncode == 0, proc.stderr
    (row,) = [json.loads(line) for line in proc.stdout.splitlines()]
    assert row["albedo"] == "alb.exr" and np.isfinite(row["score"])
    for args, message in (
        (["a.exr", *model], "pass --albedo ALBEDO"),
        (["a.exr", "--albedo", "alb.exr", "alb.exr", *model], "give one per image"),
        (["a.exr", "--albedo", "alb.exr", "--weights-dir", str(weights), "--model", "fcnn_fast"], "takes no albedo"),
    ):
        proc = _predict(tmp_path, *args)
        assert proc.returncode == 2 and proc.stdout == ""
        (line,) = proc.stderr.strip().splitlines()
        assert message in line


def test_cli_twin_of_another_size_is_one_line(tmp_path, twin_weights):
    write_exr(tmp_path / "a.exr", rgb(40, 48))
    write_exr(tmp_path / "b.exr", rgb(40, 40))
    args = ["a.exr", "--twin", "b.exr", "--model", "unet_fast_twin", "--weights-dir", str(twin_weights)]
    proc = _predict(tmp_path, *args)
    assert proc.returncode == 1 and proc.stdout == ""
    (line,) = proc.stderr.strip().splitlines()
    assert "a.exr" in line and "same size" in line


def test_cli_overlap_reads_the_default_in_blended_windows(tmp_path, capsys):
    """``--overlap`` scores with ``Scorer(overlap=True)``: the map the API gives, unlike the side-by-side one."""
    from nriqa.inference.scorer import Scorer

    image = rgb(96, 80, scale=1.0, seed=2)
    write_exr(tmp_path / "a.exr", image)
    args = [str(tmp_path / "a.exr"), "--no-figures", "--threads", "1", "--out"]
    assert predict.main([*args, str(tmp_path / "side")]) == 0
    assert predict.main([*args, str(tmp_path / "blend"), "--overlap"]) == 0
    side = read_exr(tmp_path / "side" / "a_map.exr")[..., 0]
    blend = read_exr(tmp_path / "blend" / "a_map.exr")[..., 0]
    expected = Scorer.from_pretrained(overlap=True)(image, hdr=True).map
    np.testing.assert_allclose(blend, expected, atol=1e-6)
    assert np.abs(blend - side).max() > 1e-3


def test_cli_names_non_finite_pixels_and_refuses_an_image_with_nothing_else(tmp_path, weights, twin_weights):
    """A few NaN/Inf pixels: scored, with a warning line and the count in --json; every pixel: one error line."""
    partly, wholly = rgb(), np.full((24, 30, 3), np.nan, np.float32)
    partly[:3, :5] = np.nan
    partly[5, 5] = np.inf
    write_exr(tmp_path / "partly.exr", partly)
    write_exr(tmp_path / "wholly.exr", wholly)
    write_exr(tmp_path / "clean.exr", rgb(seed=1))
    proc = run_predict_py(tmp_path, weights, "partly.exr", "wholly.exr", "clean.exr", "--json", "--no-figures")
    assert proc.returncode == 1
    rows = [json.loads(line) for line in proc.stdout.strip().splitlines()]
    assert [(r["path"], r["nonfinite_pixels"]) for r in rows] == [("partly.exr", 16), ("clean.exr", 0)]
    assert all(np.isfinite(r["score"]) for r in rows)
    warning, error = proc.stderr.strip().splitlines()
    assert warning == (
        "predict.py: warning: partly.exr: 16 of 720 pixels are NaN or infinite; scored as if NaN and -Inf were 0, "
        "+Inf white"
    )
    assert error.startswith("predict.py: error: wholly.exr: every pixel is NaN or infinite")
    assert not (tmp_path / "predictions" / "wholly_map.exr").exists()
    write_exr(tmp_path / "image.exr", rgb(40, 48, seed=3))
    write_exr(tmp_path / "twin.exr", np.full((40, 48, 3), np.inf, np.float32))
    twin_args = ["--model", "unet_fast_twin", "--weights-dir", str(twin_weights)]
    proc = _predict(tmp_path, "image.exr", "--twin", "twin.exr", *twin_args)
    assert proc.returncode == 1 and proc.stdout == ""
    assert "every pixel of its twin twin.exr is NaN or infinite" in proc.stderr.strip()


def test_cli_spread_is_in_the_json_only_when_asked(tmp_path):
    write_exr(tmp_path / "a.exr", rgb(48, 64, seed=5))
    plain = json.loads(_predict(tmp_path, "a.exr", "--json").stdout)
    asked = json.loads(_predict(tmp_path, "a.exr", "--json", "--spread").stdout)
    assert plain["spread"] is None and asked["spread"] >= 0 and asked["score"] == plain["score"]
    assert (asked["low"], asked["high"]) != (plain["low"], plain["high"])  # the spread interval's ends
    proc = _predict(tmp_path, "a.exr", "--spread", "--model", "dual_fast", "--twin", "a.exr")
    assert proc.returncode == 2 and "single-image SSIM map models" in proc.stderr.strip()
