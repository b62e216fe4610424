"""What one training step costs on the CPU: making the batch of patches against the network's step.

Training patches are drawn per item (image, position, display, jitter: a pure function of the seed
and the item's index) and, since stop 38, made a batch at a time (``TrainPatches.__getitems__``:
cut, displayed, jittered and scored as one batch). This measures, interleaved in one run on the same
machine, a batch made one item at a time (the loader's fetch without ``__getitems__``), the same
batch made at once, and one ``unet_fast`` training step (forward, Charbonnier+PCC-like loss,
backward, Adam) on it. Prints a Markdown table; medians over repeats.

Usage::

    python benchmarks/train_step.py --data data/default [--patch 64 --batch 8 --repeats 30 --threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.machine import machine_line  # noqa: E402
from nriqa.data.datamodule import NRIQADataModule  # noqa: E402
from nriqa.io.tables import markdown_table  # noqa: E402
from nriqa.models import create_model  # noqa: E402

MIX = {"tonemap": 0.5, "srgb": 0.25, "gamma22": 0.25, "stops": 2.0, "quantise_p": 0.5}  # experiment unet_fast's


def main(argv: list[str] | None = None) -> None:
    """Measure and print the table; see the module docstring for the arguments."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="a rendered dataset root (holds manifest.json)")
    ap.add_argument("--patch", type=int, default=64, help="patch side")
    ap.add_argument("--batch", type=int, default=8, help="patches per batch")
    ap.add_argument("--repeats", type=int, default=30, help="batches timed per way")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads (training runs use 1)")
    ap.add_argument("--tonemap-only", action="store_true", help="no display mix (experiments fcnn, fcnn_fast)")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    try:
        dm = NRIQADataModule(
            args.data, patch_size=args.patch, batch_size=args.batch, display=None if args.tonemap_only else MIX
        )
        dm.setup()
    except (OSError, ValueError) as exc:
        sys.exit(f"train_step: {exc}")
    ds = dm.train_set
    net = create_model("unet_fast", window=args.patch)
    opt = torch.optim.Adam(net.parameters(), 1e-4)

    def one_by_one(ks: list[int]):
        return [ds.__getitems__([k])[0] for k in ks]

    def batched(ks: list[int]):
        return ds.__getitems__(ks)

    def step(x: torch.Tensor, y: torch.Tensor) -> None:
        out = net(x)
        loss = torch.sqrt((out - y) ** 2 + 1e-6).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()

    times: dict[str, list[float]] = {"one by one": [], "batched": [], "network step": []}
    for r in range(args.repeats + 2):  # the first two are warm-up
        ks = list(range(r * args.batch, (r + 1) * args.batch))
        t0 = time.perf_counter()
        one_by_one(ks)
        t1 = time.perf_counter()
        items = batched(ks)
        t2 = time.perf_counter()
        step(torch.stack([i[0] for i in items]), torch.stack([i[1] for i in items]))
        t3 = time.perf_counter()
        if r >= 2:
            for name, t in zip(times, (t1 - t0, t2 - t1, t3 - t2)):
                times[name].append(t)
    med = {name: statistics.median(t) for name, t in times.items()}
    net_t = med["network step"]
    rows = []
    for name in ("one by one", "batched"):
        rows.append(
            [
                f"patches, {name}",
                f"{med[name] * 1e3:.1f}",
                f"{med[name] / (med[name] + net_t):.0%}",
                f"{1.0 / (med[name] + net_t):.1f}",
                f"{med['one by one'] / med[name]:.2f}x",
            ]
        )
    rows.append(["unet_fast step (fwd+bwd+Adam)", f"{net_t * 1e3:.1f}", "-", "-", "-"])
    print(
        f"CPU: {machine_line()}; {args.data}, {len(ds.pairs)} training images, {args.batch} patches of "
        f"{args.patch}x{args.patch}, {'tone map only' if args.tonemap_only else 'display mix'}; "
        f"median of {args.repeats} interleaved repeats\n"
    )
    cols = ["what", "ms / batch", "share of a step", "steps / s (data + step, one thread)", "patch speed-up"]
    print(markdown_table(rows, cols), end="")


if __name__ == "__main__":
    main()
