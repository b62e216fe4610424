"""What a training step of F leave-one-scene-out folds costs: one fold after another, or all stacked as one.

``nriqa-crossval crossval.stacked=true`` (:mod:`nriqa.training.stacked`) runs the folds' networks as one
(stacked weights, ``torch.func.vmap``): one forward, backward and Adam update per step for every fold. This
times, interleaved in one run on one device, F separate steps (each fold's network on its own batch, one
after the other in this process: the best that F processes sharing a device could do) against one stacked
step on the same batches, with the recipe's loss (signed Charbonnier + PCC). Batches are random tensors:
making patches is ``benchmarks/train_step.py``'s subject. Prints a Markdown table; medians over repeats.

Usage::

    python benchmarks/stacked_step.py [--folds 17 --model unet_fast --batch 8 --patch 64 --repeats 10]
    python benchmarks/stacked_step.py --device cuda
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.machine import machine_line  # noqa: E402
from nriqa.io.tables import markdown_table  # noqa: E402
from nriqa.losses import create_loss  # noqa: E402
from nriqa.models import create_model, list_models  # noqa: E402
from nriqa.training.stacked import StackedNets  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    """Measure and print the table; see the module docstring for the arguments."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--folds", type=int, default=17, help="folds trained together (17: the v2 families)")
    ap.add_argument("--model", default="unet_fast", help="a registered map model")
    ap.add_argument("--batch", type=int, default=8, help="patches per fold and step")
    ap.add_argument("--patch", type=int, default=64, help="patch side")
    ap.add_argument("--repeats", type=int, default=10, help="steps timed per way")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--device", default="cpu", help="where the networks step (cpu, cuda)")
    args = ap.parse_args(argv)
    if args.folds < 1 or args.batch < 2 or args.patch < 16 or args.repeats < 1:
        sys.exit("stacked_step: give --folds >= 1, --batch >= 2 (the PCC loss), --patch >= 16, --repeats >= 1")
    if args.model not in list_models():
        sys.exit(f"stacked_step: no model {args.model!r}; use one of {', '.join(list_models())}")
    torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        sys.exit("stacked_step: --device cuda, but torch sees no CUDA device here; leave --device out")

    torch.manual_seed(0)
    base = create_model(args.model)
    if getattr(base, "output", "map") != "map":
        sys.exit(f"stacked_step: {args.model} is not a map model")
    nets = [copy.deepcopy(base).to(device) for _ in range(args.folds)]
    opts = [torch.optim.Adam(n.parameters(), 1e-3) for n in nets]
    stack = StackedNets(base, args.folds).to(device)
    opt = torch.optim.Adam(stack.params.values(), 1e-3)
    loss_fn = create_loss("joint", signed=True).to(device)
    channels = getattr(base, "in_channels", 3)

    def sync() -> float:
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter()

    def separate(x: torch.Tensor, y: torch.Tensor) -> None:
        for f, (net, o) in enumerate(zip(nets, opts)):
            o.zero_grad()
            loss_fn(net(x[f]), y[f]).backward()
            o.step()

    def stacked(x: torch.Tensor, y: torch.Tensor) -> None:
        opt.zero_grad()
        stack.losses(x, y, loss_fn).sum().backward()
        opt.step()

    times: dict[str, list[float]] = {"separate": [], "stacked": []}
    shape = (args.folds, args.batch)
    for r in range(args.repeats + 2):  # the first two are warm-up
        x = torch.rand(*shape, channels, args.patch, args.patch, device=device)
        y = torch.rand(*shape, 1, args.patch, args.patch, device=device)
        t0 = sync()
        separate(x, y)
        t1 = sync()
        stacked(x, y)
        t2 = sync()
        if r >= 2:
            times["separate"].append(t1 - t0)
            times["stacked"].append(t2 - t1)
    med = {k: statistics.median(v) for k, v in times.items()}
    rows = [
        [
            f"{args.folds} folds one after another ({args.folds} x {args.model})"
            if name == "separate"
            else f"{args.folds} folds stacked (one vmapped {args.model})",
            f"{med[name] * 1e3:.1f}",
            f"{med[name] * 1e3 / args.folds:.2f}",
            f"{med['separate'] / med[name]:.2f}x",
        ]
        for name in ("separate", "stacked")
    ]
    gpu = f"; {torch.cuda.get_device_name(device)}" if device.type == "cuda" else ""
    print(
        f"CPU: {machine_line()}{gpu}; {args.device}, {args.threads} thread(s); {args.folds} folds x {args.batch} "
        f"patches of {args.patch}x{args.patch}; median of {args.repeats} interleaved repeats\n"
    )
    cols = ["step of every fold", "ms / step", "ms / fold-step", "speed-up"]
    print(markdown_table(rows, cols), end="")


if __name__ == "__main__":
    main()
