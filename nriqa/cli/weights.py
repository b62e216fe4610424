"""``nriqa-weights``: list the shipped weights, export a training checkpoint as shipped weights, or ship the
weights between two trainings of one network (a fine-tune and its start).

    nriqa-weights list [--dir DIR]
    nriqa-weights export CHECKPOINT [CHECKPOINT ...] NAME [--card KEY=VALUE ...] [--spec KEY=VALUE ...] [--dir DIR]
    nriqa-weights interpolate START END NAME --alpha A [--card KEY=VALUE ...] [--spec KEY=VALUE ...] [--dir DIR]

Formats and checks are :mod:`nriqa.inference.pretrained`'s. Exit code 2 with one line on stderr for
unknown weights or an unusable checkpoint.
"""

from __future__ import annotations

import argparse
import json
import sys

from nriqa.inference.pretrained import (
    WEIGHTS_DIR,
    PretrainedError,
    export_checkpoint,
    export_interpolation,
    list_pretrained,
    load_card,
)


def parse_card(items: list[str], option: str = "--card") -> dict:
    """``["key=value", ...]`` as a dict; each value parsed as JSON where it can be, else kept as a string."""
    card = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise PretrainedError(f"{option} {item!r}: expected key=value")
        try:
            card[key] = json.loads(value)
        except ValueError:
            card[key] = value
    return card


_SPEC_HELP = "a network argument that leaves the weights as they are, e.g. window=64 for unet_fast"


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        description="List shipped weights, or export a training checkpoint as shipped weights."
    )
    sub = ap.add_subparsers(dest="cmd", required=True)
    ex = sub.add_parser("export", help="turn a training checkpoint into shipped weights + model card")
    ex.add_argument(
        "checkpoint", nargs="+", help="a training checkpoint; several (seeds of one recipe) ship as their mean"
    )
    ex.add_argument("name", help="weights name, e.g. fcnn_fast")
    ex.add_argument(
        "--card",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a card entry (value parsed as JSON if it can be)",
    )
    ex.add_argument(
        "--spec",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=_SPEC_HELP,
    )
    ex.add_argument("--dir", default=None, help=f"target folder (default {WEIGHTS_DIR})")
    ip = sub.add_parser(
        "interpolate", help="ship (1 - alpha) START + alpha END, two trainings of one network (a fine-tune, its start)"
    )
    ip.add_argument("start", help="a training checkpoint (.ckpt), shipped weights' name, or a .pt with its card")
    ip.add_argument("end", help="the same, e.g. the fine-tune of START")
    ip.add_argument("name", help="weights name to write")
    ip.add_argument("--alpha", type=float, required=True, help="in [0, 1]: 0 ships START's weights, 1 END's")
    for option, text in (("--card", "a card entry (value parsed as JSON if it can be)"), ("--spec", _SPEC_HELP)):
        ip.add_argument(option, action="append", default=[], metavar="KEY=VALUE", help=text)
    ip.add_argument("--dir", default=None, help=f"target folder (default {WEIGHTS_DIR})")
    ls = sub.add_parser("list", help="list shipped weights and their cards")
    ls.add_argument("--dir", default=None, help=f"folder of weights (default {WEIGHTS_DIR})")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 unknown weights, unusable checkpoint or mismatch)."""
    from nriqa.training.checkpoint import CheckpointError

    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        if args.cmd == "export":
            card, spec = parse_card(args.card), parse_card(args.spec, "--spec")
            pt = export_checkpoint(args.checkpoint, args.name, card, dir=args.dir, spec=spec)
            print(f"wrote {pt} and {pt.with_suffix('.json')}")
        elif args.cmd == "interpolate":
            card, spec = parse_card(args.card), parse_card(args.spec, "--spec")
            pt = export_interpolation(args.start, args.end, args.alpha, args.name, card, dir=args.dir, spec=spec)
            mix = f"{1 - args.alpha:g} x {args.start} + {args.alpha:g} x {args.end}"
            print(f"wrote {pt} and {pt.with_suffix('.json')} ({mix})")
        else:
            for name in list_pretrained(args.dir):
                card, _ = load_card(name, args.dir)
                print(name, json.dumps({k: v for k, v in card.items() if k != "spec"}, sort_keys=True))
    except (PretrainedError, CheckpointError) as exc:
        print(f"{ap.prog}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
