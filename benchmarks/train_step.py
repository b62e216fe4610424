"""What one training step costs on the CPU: making the batch of patches against the network's step.

Training patches are drawn per item (image, position, display, jitter: a pure function of the seed
and the item's index) and, since stop 38, made a batch at a time (``TrainPatches.__getitems__``:
cut, displayed, jittered and scored as one batch). This measures, interleaved in one run on the same
machine, a batch made one item at a time (the loader's fetch without ``__getitems__``), the same
batch made at once, and one ``unet_fast`` training step (forward, Charbonnier+PCC-like loss,
backward, Adam) on it. Prints a Markdown table; medians over repeats.

With ``--device cuda`` the network steps there, and a third way is timed: the same batch made on the
accelerator (``data.device``: the images moved there once, each batch cut, displayed, jittered and
scored there; the random draws stay on the CPU). Times on the accelerator are taken after a
synchronisation.

Usage::

    python benchmarks/train_step.py --data data/default [--patch 64 --batch 8 --repeats 30 --threads 1]
    python benchmarks/train_step.py --data data/default --device cuda
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
    ap.add_argument("--device", default="cpu", help="where the network steps (cuda: batches made there are timed too)")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        sys.exit("train_step: --device cuda, but torch sees no CUDA device here; leave --device out")
    on_device = args.device != "cpu"  # cpu:0 times the device path on the CPU

    def patch_set(where: str | None):
        dm = NRIQADataModule(
            args.data,
            patch_size=args.patch,
            batch_size=args.batch,
            display=None if args.tonemap_only else MIX,
            device=where,
        )
        dm.setup()
        return dm.train_set

    try:
        ds = patch_set(None)
        ds_device = patch_set(args.device) if on_device else None
    except (OSError, ValueError) as exc:
        sys.exit(f"train_step: {exc}")
    net = create_model("unet_fast", window=args.patch).to(device)
    opt = torch.optim.Adam(net.parameters(), 1e-4)

    def sync() -> float:
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter()

    def one_by_one(ks: list[int]):
        return [ds.__getitems__([k])[0] for k in ks]

    def batched(ks: list[int]):
        return ds.__getitems__(ks)

    def step(x: torch.Tensor, y: torch.Tensor) -> None:
        x, y = x.to(device), y.to(device)
        out = net(x)
        loss = torch.sqrt((out - y) ** 2 + 1e-6).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()

    ways = ["one by one", "batched"] + ([f"batched on {args.device}"] if on_device else [])
    times: dict[str, list[float]] = {name: [] for name in [*ways, "network step"]}
    for r in range(args.repeats + 2):  # the first two are warm-up
        ks = list(range(r * args.batch, (r + 1) * args.batch))
        t0 = sync()
        one_by_one(ks)
        t1 = sync()
        items = batched(ks)
        t2 = sync()
        step(torch.stack([i[0] for i in items]), torch.stack([i[1] for i in items]))
        took = [t1 - t0, t2 - t1, sync() - t2]
        if on_device:
            t4 = sync()
            ds_device.__getitems__(ks)
            took.insert(2, sync() - t4)
        if r >= 2:
            for name, t in zip([*ways, "network step"], took):
                times[name].append(t)
    med = {name: statistics.median(t) for name, t in times.items()}
    net_t = med["network step"]
    rows = []
    for name in ways:
        rows.append(
            [
                f"patches, {name}",
                f"{med[name] * 1e3:.1f}",
                f"{med[name] / (med[name] + net_t):.0%}",
                f"{1.0 / (med[name] + net_t):.1f}",
                f"{med['one by one'] / med[name]:.2f}x",
            ]
        )
    rows.append([f"unet_fast step (fwd+bwd+Adam, {args.device})", f"{net_t * 1e3:.1f}", "-", "-", "-"])
    gpu = f"; {torch.cuda.get_device_name(device)}" if device.type == "cuda" else ""
    print(
        f"CPU: {machine_line()}{gpu}; {args.data}, {len(ds.pairs)} training images, {args.batch} patches of "
        f"{args.patch}x{args.patch}, {'tone map only' if args.tonemap_only else 'display mix'}; "
        f"median of {args.repeats} interleaved repeats\n"
    )
    cols = ["what", "ms / batch", "share of a step", "steps / s (data + step, one thread)", "patch speed-up"]
    print(markdown_table(rows, cols), end="")


if __name__ == "__main__":
    main()
