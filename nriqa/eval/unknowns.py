"""Where a composed-SSIM model's error sits: the noise share it reads, or the mean shift.

A composed-SSIM model (``unet_fast_ssim``, :mod:`nriqa.models.unet_ssim`) predicts two unknowns per
window -- the share of the render's local variance that is noise and the shift of its mean -- and
composes SSIM from the render's own moments. Against the reference both are known
(:func:`true_unknowns`), so each image's error splits: the map composed with the true shift and the
predicted share is off only by the share, the one with the true share only by the shift, and the one
with both true only by the model's form (it takes the reference's variance equal to the covariance).

    python -m nriqa.eval.unknowns data/v2 --crossval reports/crossval/NAME   # each scene by its fold
    python -m nriqa.eval.unknowns data/v2 --checkpoint last.ckpt --scenes door shadows

prints, per scene family and pooled, the bias and MAE of each reading's mean SSIM against the true
mean SSIM, and the variance-weighted noise share predicted and true. Networks read whole images.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict

import torch
from torch import Tensor, nn

from nriqa.core.ssim import local_moments, pair_moments, ssim_map
from nriqa.core.tonemap import luminance
from nriqa.errors import NriqaError
from nriqa.eval.dataset import load_dataset, records_of
from nriqa.eval.predictors import fold_checkpoints
from nriqa.io.atomic import write_text_atomic
from nriqa.io.tables import markdown_table
from nriqa.models.unet_ssim import ssim_from_unknowns
from nriqa.training.checkpoint import load_net_from_checkpoint

__all__ = ["READINGS", "UnknownsError", "error_split", "true_unknowns", "main"]

# mean-SSIM readings of one image: the model's own, then with one or both unknowns taken from the reference
READINGS = ("predicted", "true_shift", "true_share", "true_both")
# Windows of x with a local variance up to this are flat: their share is 0. Float32 rounding leaves ~1e-7 there,
# and SSIM's contrast term moves by under 0.2 % over any share at a variance this far below C2 (9e-4).
FLAT_VARIANCE = 1e-6


class UnknownsError(NriqaError):
    """A network, run or dataset the split cannot work with; one line saying what to do."""


def true_unknowns(x: Tensor, y: Tensor) -> tuple[Tensor, Tensor]:
    """The noise share and mean shift of LDR render ``x`` against its reference ``y`` (``(B,3,H,W)`` each).

    Share ``1 - cov_xy / var_x`` clipped to [0, 1] (0 where ``x`` is flat: :data:`FLAT_VARIANCE`), shift
    ``mu_y - mu_x``: the values under which :func:`~nriqa.models.unet_ssim.composed_ssim` takes ``y``'s mean and
    covariance exactly.
    """
    mx, my, vx, _, cov = pair_moments(luminance(x), luminance(y))
    busy = vx > FLAT_VARIANCE
    share = torch.where(busy, 1 - cov / vx.clamp_min(FLAT_VARIANCE), 0.0)
    return share.clamp(0.0, 1.0), my - mx


@torch.no_grad()
def error_split(net: nn.Module, x: Tensor, y: Tensor) -> dict[str, float]:
    """One image's readings (:data:`READINGS`) and truth as mean SSIM, and its variance-weighted noise shares.

    ``net``: a composed-SSIM network (with ``unknowns``); ``x``, ``y``: ``(1,3,H,W)`` LDR render and reference.
    """
    if not callable(getattr(net, "unknowns", None)):
        raise UnknownsError(
            f"{type(net).__name__} predicts SSIM itself, not its unknowns; the split needs a composed-SSIM model "
            "(unet_fast_ssim)"
        )
    share, shift = net.unknowns(x)
    true_share, true_shift = true_unknowns(x, y)
    mean, var = local_moments(luminance(x))
    out = {
        "truth": float(ssim_map(x, y).mean()),
        "predicted": float(ssim_from_unknowns(mean, var, share, shift).mean()),
        "true_shift": float(ssim_from_unknowns(mean, var, share, true_shift).mean()),
        "true_share": float(ssim_from_unknowns(mean, var, true_share, shift).mean()),
        "true_both": float(ssim_from_unknowns(mean, var, true_share, true_shift).mean()),
    }
    weight = var.sum()
    if weight > 0:
        out["share"] = float((share * var).sum() / weight)
        out["share_true"] = float((true_share * var).sum() / weight)
    return out


def summarise(rows: list[dict]) -> list[dict]:
    """Per scene family and pooled (``all``): n, each reading's bias and MAE, mean variance-weighted shares."""
    groups = defaultdict(list)
    for row in rows:
        groups[row["scene"]].append(row)
    table = []
    for name, group in [("all", rows), *sorted(groups.items())]:
        line = {"scene": name, "n": len(group)}
        for reading in READINGS:
            errors = [r[reading] - r["truth"] for r in group]
            line[f"{reading}_bias"] = sum(errors) / len(errors)
            line[f"{reading}_mae"] = sum(abs(e) for e in errors) / len(errors)
        shares = [r for r in group if "share" in r]
        if shares:
            line["share"] = sum(r["share"] for r in shares) / len(shares)
            line["share_true"] = sum(r["share_true"] for r in shares) / len(shares)
        table.append(line)
    return table


def _fold_nets(crossval: str | None, checkpoint: str | None) -> dict[str | None, nn.Module]:
    """Networks by held-out scene (``--crossval``) or one for every scene (key ``None``, ``--checkpoint``)."""
    if checkpoint:
        return {None: load_net_from_checkpoint(checkpoint)}
    return {scene: load_net_from_checkpoint(path) for scene, path in fold_checkpoints(crossval).items()}


def split_dataset(data: list[str], nets: dict[str | None, nn.Module], scenes: list[str] | None) -> list[dict]:
    """:func:`error_split` of every test image of ``data`` whose scene has a network (and is in ``scenes``)."""
    rows = []
    for root_arg in data:
        root, records = records_of(root_arg)
        keep = [r for r in records if (None in nets or r.scene in nets) and (not scenes or r.scene in scenes)]
        if not keep:
            continue
        dataset = load_dataset(root, keep, twins=False)
        for item in dataset.items:
            net = nets.get(item.record.scene, nets.get(None))
            ref = dataset.refs[item.record.reference]
            row = error_split(net, item.ldr[None], ref[None])
            rows.append({"scene": item.record.scene, "path": str(root / item.record.path), **row})
    if not rows:
        raise UnknownsError(f"{', '.join(data)}: no test image of the scenes asked for; check --scenes and the folds")
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("data", nargs="+", help="dataset roots (with a manifest) or external folders")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--crossval", help="a nriqa-crossval run: each scene read by the fold that held it out")
    source.add_argument("--checkpoint", help="one training checkpoint for every scene")
    parser.add_argument("--scenes", nargs="*", default=None, help="only these scene families")
    parser.add_argument("--out", default=None, help="also write the table to this .md file")
    args = parser.parse_args(argv)
    try:
        table = summarise(split_dataset(args.data, _fold_nets(args.crossval, args.checkpoint), args.scenes))
    except NriqaError as exc:
        sys.exit(f"error: {exc}")
    columns = ["scene", "n", *(f"{r}_{k}" for r in READINGS for k in ("bias", "mae")), "share", "share_true"]
    text = markdown_table(table, columns, digits=4)
    print(text, end="")
    if args.out:
        write_text_atomic(args.out, text)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
