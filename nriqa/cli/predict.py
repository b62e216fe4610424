"""``nriqa-predict``: score rendered images without their reference, a quality map and a pooled score per file.

    nriqa-predict render.exr more/*.png [--model fcnn_fast | --checkpoint best.ckpt] [--out predictions]
                  [--json] [--hdr | --ldr] [--tile 512] [--stride 8] [--threads N] [--device cuda]
                  [--no-figures]

(``python predict.py ...`` in a checkout runs the same.) Per input, written atomically into ``--out``:
``<stem>_map.exr`` (the predicted map as float32, replicated to RGB) and ``<stem>_figure.png`` (the
image the network saw | the map with a colour bar). Prints ``path score`` per image -- ``path score low
high`` for shipped weights with a calibrated interval (where the true mean SSIM lies, 90 %, its coverage
measured on the card) -- or with ``--json`` one JSON object per line (path, score, low, high, level,
quantity, pixel_filter, height, width, hdr, seconds, map, figure); stdout carries nothing else. Map models predict
SSIM (higher is better), the patch model MAE (lower is better).

Inputs: EXR (RGB, RGBA, luminance-only; half or float; scanline or tiled) is linear HDR and is
tone-mapped; PNG/JPEG (8 or 16 bit, gray, RGB, with or without alpha) is display-referred LDR
scaled to [0, 1]. ``--hdr``/``--ldr`` override the choice. Bad pixels (NaN, Inf, negative, huge)
follow the policy of :class:`nriqa.inference.scorer.Scorer`. A file that cannot be scored (missing, a
folder, truncated, not an image, smaller than the model's receptive field, deep or multi-part EXR)
gets one line on stderr and the others are still scored; the exit code is then 1 (2 for a usage
or model error). A progress bar (tqdm) goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from nriqa.inference import DEFAULT_WEIGHTS
from nriqa.io.imread import read_image

DESCRIPTION = "Score rendered images without their reference: a quality map and a pooled score per file."


def write_figure(
    path: Path, shown: np.ndarray, qmap: np.ndarray, score: float, quantity: str, title: str, span: str = ""
) -> None:
    """Save ``image | map`` side by side with a colour bar as a PNG, atomically.

    ``shown`` is the ``(H, W, 3)`` LDR image the network saw; ``qmap`` the ``(H, W)`` map; ``span``
    an interval to print after the mean (e.g. ``"90 %: 0.91-0.95"``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from nriqa.io.atomic import save_figure

    step = max(1, max(qmap.shape) // 1024)  # a figure needs no more than ~1k pixels a side
    shown, qmap = shown[::step, ::step], qmap[::step, ::step]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.4), constrained_layout=True)
    axes[0].imshow(np.clip(shown, 0, 1), interpolation="nearest")
    axes[0].set_title(title, fontsize=9)
    vmax = 1.0 if quantity == "ssim" else max(float(qmap.max()), 1e-6)
    im = axes[1].imshow(qmap, cmap="viridis", vmin=0.0, vmax=vmax, interpolation="nearest")
    better = "higher is better" if quantity == "ssim" else "lower is better"
    span = f", {span}" if span else ""
    axes[1].set_title(f"predicted {quantity.upper()} map, mean {score:.4f}{span} ({better})", fontsize=9)
    for ax in axes:
        ax.set_axis_off()
    fig.colorbar(im, ax=axes[1], fraction=0.046)
    save_figure(fig, path, dpi=100)


def _unique_stem(stem: str, used: set[str]) -> str:
    name, k = stem, 1
    while name in used:
        k += 1
        name = f"{stem}_{k}"
    used.add(name)
    return name


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=DESCRIPTION)
    ap.add_argument("images", nargs="+", metavar="IMAGE", help=".exr (linear HDR) or .png/.jpg (LDR) files")
    src = ap.add_mutually_exclusive_group()
    src.add_argument(
        "--model",
        default=DEFAULT_WEIGHTS,
        help=f"shipped weights name or a path to a .pt (default {DEFAULT_WEIGHTS}, for box-filtered renders; "
        "unet_fast_gaussian for renders through Mitsuba's default Gaussian film filter)",
    )
    src.add_argument("--checkpoint", type=Path, help="a training checkpoint (.ckpt) instead of shipped weights")
    ap.add_argument(
        "--twin",
        nargs="+",
        metavar="TWIN",
        default=None,
        help="for a two-buffer model (dual_fast): an independent render of each IMAGE at the same spp, in order",
    )
    ap.add_argument(
        "--albedo",
        nargs="+",
        metavar="ALBEDO",
        default=None,
        help="for a model with the albedo pass (unet_fast_albedo): each IMAGE's albedo pass (linear EXR, as "
        "renderers write it for their denoisers), in order",
    )
    ap.add_argument("--weights-dir", type=Path, default=None, help="folder of shipped weights (default: the package's)")
    ap.add_argument("--out", type=Path, default=Path("predictions"), help="output folder (default predictions/)")
    ap.add_argument("--json", action="store_true", help="print one JSON object per image instead of 'path score'")
    rng = ap.add_mutually_exclusive_group()
    rng.add_argument(
        "--hdr", dest="hdr", action="store_const", const=True, help="treat every input as linear HDR (tone map it)"
    )
    rng.add_argument(
        "--ldr", dest="hdr", action="store_const", const=False, help="treat every input as display-referred LDR"
    )
    ap.add_argument("--tile", type=int, default=512, help="tile side for large images (0: never tile)")
    ap.add_argument("--stride", type=int, default=8, help="window stride of the patch model")
    ap.add_argument(
        "--overlap",
        action="store_true",
        help="a model read in 64x64 windows (unet_fast): blend windows read every half window, so the map has "
        "no seams on the window grid (about 4x slower on large images)",
    )
    ap.add_argument(
        "--spread",
        action="store_true",
        help="also score the image's 8 flips and turns: the score's spread over them ('spread' in --json) widens "
        "the interval where the network is unsure (the card's score_interval_spread, _ldr for LDR input; 8x the time)",
    )
    ap.add_argument(
        "--threads",
        type=int,
        default=None,
        help="torch CPU threads (default: torch's choice; 1 is faster for small images on a busy CPU)",
    )
    ap.add_argument(
        "--device",
        default="cpu",
        help="where the network runs: cpu (default) or a torch device such as cuda, cuda:1 (a GPU: the same "
        "scores to about 2e-4, many times faster on large images)",
    )
    ap.add_argument("--no-figures", action="store_true", help="write only the map EXR")
    ap.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="progress bar on stderr (auto: terminal and >1 file)",
    )
    return ap


def _emit(line: str, stream) -> None:
    """One line on ``stream``, around the progress bar (tqdm clears and redraws it), flushed."""
    tqdm.write(line, file=stream)
    stream.flush()


def _one_line(prog: str, msg: str, kind: str = "error") -> str:
    return f"{prog}: {kind}: {' '.join(msg.split())}"


def warn(msg: str) -> None:
    """A warning line on stderr (the file is still scored)."""
    _emit(_one_line(Path(sys.argv[0]).name, msg, "warning"), sys.stderr)  # argparse's default prog


def _pixels(image: np.ndarray) -> int:
    return int(image.shape[0] * image.shape[1])


def nonfinite_pixels(image: np.ndarray) -> int:
    """Pixels ``(H, W, C)`` with a NaN or infinite value in any channel."""
    return int((~np.isfinite(image)).any(axis=-1).sum())


def score_file(
    scorer,
    name: str,
    args: argparse.Namespace,
    used: set[str],
    twin_name: str | None = None,
    albedo_name: str | None = None,
) -> str:
    """Score one file, write its map (and figure) into ``args.out``; return its line for stdout.

    Raises whatever reading, scoring or writing raises (:class:`nriqa.io.exr.ImageReadError`,
    :class:`nriqa.inference.scorer.ScorerInputError`, ``OSError``, ...).
    """
    import torch

    from nriqa.inference.scorer import ScorerInputError
    from nriqa.io.exr import write_exr

    start = time.perf_counter()
    image, file_hdr = read_image(name)
    twin = read_image(twin_name)[0] if twin_name is not None else None
    albedo = read_image(albedo_name)[0] if albedo_name is not None else None
    bad = {n: (nonfinite_pixels(x), _pixels(x)) for n, x in ((name, image), (twin_name, twin)) if x is not None}
    for n, (count, total) in bad.items():
        if count == total:
            which = "every pixel" if n == name else f"every pixel of its twin {n}"
            raise ScorerInputError(f"{which} is NaN or infinite: nothing to score; check the renderer's output")
        if count:
            warn(f"{n}: {count} of {total} pixels are NaN or infinite; scored as if NaN and -Inf were 0, +Inf white")
    hdr = file_hdr if args.hdr is None else args.hdr
    t0 = time.perf_counter()
    result = scorer(image, hdr=hdr, twin=twin, albedo=albedo)
    seconds = time.perf_counter() - t0
    stem = _unique_stem(Path(name).stem, used)
    map_path = args.out / f"{stem}_map.exr"
    write_exr(map_path, np.repeat(result.map[..., None], 3, axis=2))
    fig_path = None
    if not args.no_figures:
        with torch.inference_mode():
            t = torch.from_numpy(image).permute(2, 0, 1)[None]
            shown = scorer.prepare(t, [hdr])[0].permute(1, 2, 0).numpy()
        fig_path = args.out / f"{stem}_figure.png"
        title = f"{name} ({'HDR, tone-mapped' if hdr else 'LDR'})"
        span = "" if result.low is None else f"{scorer.interval.level:.0%}: {result.low:.3f}-{result.high:.3f}"
        write_figure(fig_path, shown, result.map, result.score, result.quantity, title, span)
    if not args.json:
        ends = "" if result.low is None else f" {result.low:.6f} {result.high:.6f}"
        return f"{name} {result.score:.6f}{ends}"
    row = {
        "path": str(name),
        "twin": twin_name,
        "albedo": albedo_name,
        "score": round(result.score, 6),
        "low": None if result.low is None else round(result.low, 6),
        "high": None if result.high is None else round(result.high, 6),
        "level": None if scorer.interval is None else scorer.interval.level,
        "quantity": result.quantity,
        "pixel_filter": scorer.pixel_filter,  # the filter of the renders the weights read
        "height": int(image.shape[0]),
        "width": int(image.shape[1]),
        "hdr": hdr,
        "nonfinite_pixels": bad[name][0],
        "spread": None if result.spread is None else round(float(result.spread), 6),
        "seconds": round(seconds, 4),
        "total_seconds": round(time.perf_counter() - start, 4),
        "map": str(map_path),
        "figure": str(fig_path) if fig_path else None,
    }
    return json.dumps(row)


def _failure(name: str, exc: Exception) -> str:
    """The stderr message for a file that could not be scored (it names the file)."""
    from nriqa.inference.scorer import ScorerInputError
    from nriqa.io.exr import ImageReadError

    if isinstance(exc, (ImageReadError, OSError)):
        return str(exc)
    if isinstance(exc, ScorerInputError):
        return f"{name}: {exc}"
    return f"{name}: {type(exc).__name__}: {exc}"


def _twin_problem(scorer, args: argparse.Namespace) -> str | None:
    """Why ``--twin`` or ``--albedo`` does not fit the model or the images, or ``None``."""
    model = type(scorer.net).__name__
    for given, needed, missing, unwanted, what in (
        (
            args.twin,
            scorer.needs_twin,
            "scores an image with its twin: pass --twin TWIN (an independent render at the same spp)",
            "scores one image; --twin needs a two-buffer model (--model dual_fast)",
            "twins: give one twin per image",
        ),
        (
            args.albedo,
            scorer.needs_albedo,
            "scores an image with its scene's albedo pass: pass --albedo ALBEDO (one per image)",
            "takes no albedo pass; leave --albedo out, or choose a model trained with one",
            "albedo passes: give one per image",
        ),
    ):
        if needed and given is None:
            return f"{model} {missing}"
        if not needed and given is not None:
            return f"{model} {unwanted}"
        if given is not None and len(given) != len(args.images):
            return f"{len(args.images)} images but {len(given)} {what}, in order"
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 1 some file failed, 2 usage/model error)."""
    ap = build_parser()
    args = ap.parse_args(argv)
    import torch

    from nriqa.inference.scorer import Scorer, device_problem

    if args.threads:
        torch.set_num_threads(args.threads)
    problem = device_problem(args.device)
    if problem:
        print(_one_line(ap.prog, problem), file=sys.stderr, flush=True)
        return 2
    try:
        opts = {"tile": args.tile, "stride": args.stride, "overlap": args.overlap, "device": args.device}
        if args.spread:
            opts["spread"] = True
        if args.checkpoint is not None:
            scorer = Scorer.from_checkpoint(args.checkpoint, **opts)
        else:
            scorer = Scorer.from_pretrained(args.model, dir=args.weights_dir, **opts)
    except ValueError as exc:  # PretrainedError, CheckpointError: one line each
        print(_one_line(ap.prog, str(exc)), file=sys.stderr, flush=True)
        return 2
    problem = _twin_problem(scorer, args)
    if problem:
        print(_one_line(ap.prog, problem), file=sys.stderr, flush=True)
        return 2
    twins = args.twin or [None] * len(args.images)
    albedos = args.albedo or [None] * len(args.images)

    show = args.progress == "on" or (args.progress == "auto" and sys.stderr.isatty() and len(args.images) > 1)
    used: set[str] = set()
    failures = 0
    with tqdm(total=len(args.images), disable=not show, file=sys.stderr, unit="image", dynamic_ncols=True) as bar:
        for name, twin_name, albedo_name in zip(args.images, twins, albedos):
            try:
                line = score_file(scorer, name, args, used, twin_name, albedo_name)
            except Exception as exc:  # one bad file must not stop the others
                failures += 1
                _emit(_one_line(ap.prog, _failure(name, exc)), sys.stderr)
            else:
                _emit(line, sys.stdout)
            bar.set_postfix_str(Path(name).name[:40], refresh=False)
            bar.update(1)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
