"""Shipped weights: ``nriqa/inference/weights/<name>.pt`` plus a model card ``<name>.json`` each.

The ``.pt`` file holds plain data only -- ``{"format": 1, "spec": {"name": model, **kwargs},
"state_dict": {...}}`` -- so it loads with ``torch.load(weights_only=True)``. The card is JSON:
what the weights are (data preset, commit, command, training time, cross-validation figures,
whatever the exporter passes) plus ``sha256`` of the ``.pt`` file, checked on every load.
Weights are local files shipped in the package; nothing is downloaded.

Export a training checkpoint, ship the weights halfway between a fine-tune and its start, or list
what is shipped (``nriqa-weights``, :mod:`nriqa.cli.weights`)::

    nriqa-weights export logs/train/runs/.../checkpoints/last.ckpt fcnn_fast \\
        --card data=default --card "command=nriqa-train experiment=fcnn_fast" --card val_srocc=0.91
    nriqa-weights interpolate unet_fast logs/.../last.ckpt unet_fast_new --alpha 0.5 --spec window=64
    nriqa-weights list
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import subprocess
from collections.abc import Mapping, Sequence
from pathlib import Path

import torch
from torch import nn

from nriqa.errors import NriqaError
from nriqa.io.atomic import atomic_path, write_text_atomic
from nriqa.models import create_model

__all__ = [
    "WEIGHTS_DIR",
    "PretrainedError",
    "save_pretrained",
    "load_pretrained",
    "list_pretrained",
    "net_from_card",
    "export_interpolation",
    "sha256_file",
    "update_card",
]

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
FORMAT = 1


class PretrainedError(NriqaError):
    """Shipped weights that cannot be used (unknown name, checksum mismatch, unreadable); one line."""


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def list_pretrained(dir: str | os.PathLike | None = None) -> list[str]:
    """Sorted names with both a card and a weights file in ``dir`` (default: the shipped weights)."""
    root = Path(dir) if dir is not None else WEIGHTS_DIR
    if not root.is_dir():
        return []
    return sorted(p.stem for p in root.glob("*.json") if p.with_suffix(".pt").is_file())


def save_pretrained(
    net: nn.Module,
    name: str,
    card: Mapping,
    dir: str | os.PathLike | None = None,
    spec: Mapping | None = None,
) -> Path:
    """Write ``net`` as shipped weights ``<dir>/<name>.pt`` and its card ``<dir>/<name>.json``.

    Args:
        net: a model built by :func:`nriqa.models.create_model`.
        name: the weights' name (a file stem), e.g. ``"fcnn_fast"``.
        card: JSON-serialisable facts about the weights (data, commit, command, time, figures).
        dir: target folder (default: the package's ``nriqa/inference/weights``).
        spec: ``{"name": model, **kwargs}`` that rebuilds ``net`` (default ``{"name": name}``); it is
            checked by rebuilding the model and loading the weights strictly before anything is written.

    Both files are written atomically, the weights first: a card exists only for complete weights.
    The card gets ``name``, ``spec``, ``parameters``, ``file`` and ``sha256`` added.

    Returns:
        The path of the ``.pt`` file.
    """
    spec = dict(spec) if spec is not None else {"name": name}
    state = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
    try:
        create_model(**spec).load_state_dict(state)
    except (ValueError, RuntimeError, TypeError) as exc:
        raise PretrainedError(
            f"weights {name!r}: spec {spec} does not rebuild this network ({exc}); pass spec="
        ) from None
    if not all(torch.isfinite(v).all() for v in state.values() if v.is_floating_point()):
        raise PretrainedError(f"weights {name!r}: the network has NaN/Inf parameters; refusing to ship them")
    root = Path(dir) if dir is not None else WEIGHTS_DIR
    pt = root / f"{name}.pt"
    # Through a file object: torch.save names the archive's records after a path's stem (here the
    # random temporary name), so the same weights would get a different sha256 on every export.
    with atomic_path(pt) as tmp, open(tmp, "wb") as fh:
        torch.save({"format": FORMAT, "spec": spec, "state_dict": state}, fh)
    full_card = {
        **dict(card),
        "name": name,
        "spec": spec,
        "parameters": sum(p.numel() for p in net.parameters() if p.requires_grad),
        "file": pt.name,
        "sha256": sha256_file(pt),
    }
    write_text_atomic(pt.with_suffix(".json"), json.dumps(full_card, indent=2, sort_keys=True) + "\n")
    return pt


def load_card(name: str, dir: str | os.PathLike | None = None) -> tuple[dict, Path]:
    """The card of shipped weights ``name`` and the path of its ``.pt`` file.

    ``name`` may also be a path to a ``.pt`` file with its ``.json`` card beside it.

    Raises:
        PretrainedError: unknown name (the message lists what is available) or unreadable card.
    """
    as_path = Path(name)
    if as_path.suffix == ".pt":
        pt = as_path
    else:
        pt = (Path(dir) if dir is not None else WEIGHTS_DIR) / f"{name}.pt"
    card_path = pt.with_suffix(".json")
    if not pt.is_file() or not card_path.is_file():
        avail = list_pretrained(pt.parent)
        have = f"available: {', '.join(avail)}" if avail else "none are there yet"
        raise PretrainedError(
            f"no shipped weights {name!r} in {pt.parent} ({have}); train a model and export it with "
            f"'nriqa-weights export CHECKPOINT NAME', or pass a checkpoint"
        )
    try:
        card = json.loads(card_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PretrainedError(f"{card_path}: unreadable model card ({exc})") from None
    if not isinstance(card, dict) or "sha256" not in card or "spec" not in card:
        raise PretrainedError(f"{card_path}: model card without sha256/spec; re-export the weights")
    return card, pt


def update_card(name: str, entries: Mapping, dir: str | os.PathLike | None = None) -> Path:
    """Add or replace ``entries`` in the card of shipped weights ``name``; the weights are not touched.

    For facts measured after export (a calibration, an evaluation). The keys that describe the file
    itself (``name``, ``spec``, ``file``, ``sha256``, ``parameters``) cannot be set here. The card is
    rewritten atomically. Returns the card's path.
    """
    fixed = {"name", "spec", "file", "sha256", "parameters"} & set(entries)
    if fixed:
        raise PretrainedError(f"card entries {sorted(fixed)} describe the weights file; re-export to change them")
    card, pt = load_card(name, dir)
    card.update(dict(entries))
    path = pt.with_suffix(".json")
    write_text_atomic(path, json.dumps(card, indent=2, sort_keys=True) + "\n")
    return path


def load_pretrained(name: str, dir: str | os.PathLike | None = None) -> nn.Module:
    """Build the network of shipped weights ``name`` in eval mode, after checking its SHA-256.

    Args:
        name: weights name (``list_pretrained()``), or a path to a ``.pt`` with its card beside it.
        dir: folder holding ``<name>.pt`` and ``<name>.json`` (default: the package's ``nriqa/inference/weights``).

    Raises:
        PretrainedError: unknown name (lists the available ones), checksum mismatch, unreadable file.
    """
    return net_from_card(*load_card(name, dir))


def net_from_card(card: dict, pt: Path) -> nn.Module:
    """The network of the ``.pt`` file ``pt`` whose card :func:`load_card` read, in eval mode, after checking its
    SHA-256 against the card (for callers that also read the card, so that it is read once)."""
    actual = sha256_file(pt)
    if actual != card["sha256"]:
        raise PretrainedError(
            f"{pt}: sha256 mismatch (file {actual[:12]}..., card {card['sha256'][:12]}...); "
            "the weights are corrupt or were replaced: re-export or reinstall them"
        )
    try:
        payload = torch.load(pt, map_location="cpu", weights_only=True)
        net = create_model(**payload["spec"])
        net.load_state_dict(payload["state_dict"])
    except Exception as exc:  # torch.load raises many types; a spec/state mismatch raises RuntimeError
        raise PretrainedError(f"{pt}: cannot rebuild the network ({type(exc).__name__}: {exc})") from None
    return net.eval()


def _git_commit() -> str | None:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() or None


def export_checkpoint(
    checkpoint: str | os.PathLike | Sequence[str | os.PathLike],
    name: str,
    card: Mapping,
    dir: str | os.PathLike | None = None,
    spec: Mapping | None = None,
) -> Path:
    """Turn a Lightning checkpoint of :class:`nriqa.training.module.NRIQAModule` into shipped weights.

    The card gets ``checkpoint``, ``exported`` (UTC time), ``commit`` (``git rev-parse HEAD``),
    ``epoch``, ``global_step`` and the ModelCheckpoint ``monitor``/``best_model_score`` added
    (entries given in ``card`` win). ``spec`` adds or replaces constructor arguments of the
    checkpoint's network spec that do not change its weights (e.g. ``window`` for ``unet_fast``);
    the network is rebuilt with them, so a wrong one fails here. Several checkpoints (map models
    of one recipe, e.g. two seeds) become one ``map_mean`` of them (``spec`` applies to each); the
    card's ``checkpoint``, ``epoch`` and ``global_step`` are then lists. Returns the ``.pt`` path.
    """
    paths = [checkpoint] if isinstance(checkpoint, (str, os.PathLike)) else list(checkpoint)
    members = [_member(path, spec) for path in paths]
    if len(members) == 1:
        net_spec, net, ckpt = members[0]
        info = {"checkpoint": str(paths[0]), "epoch": ckpt.get("epoch"), "global_step": ckpt.get("global_step")}
        info.update(_checkpoint_monitor(ckpt))
    else:
        net_spec = {"name": "map_mean", "members": [m[0] for m in members]}
        try:  # the members' networks are built already; save_pretrained checks the spec rebuilds them
            net = create_model("map_mean", members=[m[1] for m in members]).eval()
        except ValueError as exc:
            raise PretrainedError(f"{', '.join(map(str, paths))}: cannot average these networks ({exc})") from None
        info = {
            "checkpoint": [str(p) for p in paths],
            "epoch": [m[2].get("epoch") for m in members],
            "global_step": [m[2].get("global_step") for m in members],
        }
    full = {
        **info,
        "exported": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "commit": _git_commit(),
        **dict(card),
    }
    return save_pretrained(net, name, full, dir=dir, spec=net_spec)


def _member(checkpoint: str | os.PathLike, spec: Mapping | None) -> tuple[dict, nn.Module, Mapping]:
    """A checkpoint's network spec (``spec`` merged in), its network rebuilt with that spec, and the checkpoint."""
    from nriqa.training.checkpoint import load_net_from_checkpoint

    net = load_net_from_checkpoint(checkpoint)
    ckpt = torch.load(checkpoint, map_location="cpu", weights_only=True)
    net_spec = {**ckpt["hyper_parameters"]["net"], **dict(spec or {})}
    if spec:
        net = _rebuilt(net, net_spec, checkpoint)
    return net_spec, net, ckpt


def _rebuilt(net: nn.Module, net_spec: dict, source: str | os.PathLike) -> nn.Module:
    """``net``'s weights in a network built from ``net_spec`` (arguments that leave the weights as they are)."""
    try:
        rebuilt = create_model(**net_spec)
        rebuilt.load_state_dict(net.state_dict())
    except (TypeError, ValueError, RuntimeError, KeyError) as exc:
        raise PretrainedError(f"{source}: the network spec {net_spec} does not fit its weights ({exc})") from None
    return rebuilt.eval()


def _checkpoint_monitor(ckpt: Mapping) -> dict:
    """The ModelCheckpoint callback's monitored metric and best value, if the checkpoint has one."""
    for key, state in (ckpt.get("callbacks") or {}).items():
        if "ModelCheckpoint" in str(key) and isinstance(state, Mapping) and state.get("best_model_score") is not None:
            return {"monitor": state.get("monitor"), "best_model_score": float(state["best_model_score"])}
    return {}


def export_interpolation(
    start: str | os.PathLike,
    end: str | os.PathLike,
    alpha: float,
    name: str,
    card: Mapping,
    dir: str | os.PathLike | None = None,
    spec: Mapping | None = None,
) -> Path:
    """Ship the weights ``(1 - alpha) * start + alpha * end`` of two trainings of one network as ``name``.

    For a fine-tune and the weights it started from (weight-space interpolation, as in WiSE-FT): part of
    what the fine-tune learnt, less of its drift on what it did not see. Unlike ``export`` of several
    checkpoints (one network per member, their maps averaged), the result is one network of the same size.

    Args:
        start, end: each a training checkpoint (``.ckpt``), shipped weights' name, or a ``.pt`` with its card.
        alpha: in [0, 1]; 0 ships ``start``'s weights, 1 ``end``'s.
        spec: constructor arguments that leave the weights as they are (``window``), applied to both.

    Every floating-point tensor is interpolated (batch-norm statistics too); integer buffers (batch norm's
    step count) are ``start``'s. The card gets ``interpolated`` (both sources, their sha256 where shipped,
    ``alpha``), ``exported`` and ``commit``; entries in ``card`` win.

    Raises:
        PretrainedError: ``alpha`` outside [0, 1]; the two are not the same network (their specs differ); an
            unreadable source.
    """
    alpha = float(alpha)
    if not 0.0 <= alpha <= 1.0:
        raise PretrainedError(f"--alpha {alpha}: must be in [0, 1] (0 ships the start, 1 the end)")
    (spec_a, net_a, info_a), (spec_b, net_b, info_b) = _source(start, spec), _source(end, spec)
    if spec_a != spec_b:
        raise PretrainedError(f"{start} and {end} are not the same network: spec {spec_a} against {spec_b}")
    state_a, state_b = net_a.state_dict(), net_b.state_dict()  # one spec: the same names and shapes
    mixed = {
        k: torch.lerp(a, state_b[k].to(a.dtype), alpha) if a.is_floating_point() else a.clone()
        for k, a in state_a.items()
    }
    net_a.load_state_dict(mixed)
    full = {
        "interpolated": {"start": info_a, "end": info_b, "alpha": alpha},
        "exported": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "commit": _git_commit(),
        **dict(card),
    }
    return save_pretrained(net_a, name, full, dir=dir, spec=spec_a)


def _source(source: str | os.PathLike, spec: Mapping | None) -> tuple[dict, nn.Module, dict]:
    """A training checkpoint's or shipped weights' network spec (``spec`` merged in), network and provenance."""
    if Path(source).suffix == ".ckpt":
        net_spec, net, ckpt = _member(source, spec)
        return net_spec, net, {"checkpoint": str(source), "global_step": ckpt.get("global_step")}
    card, pt = load_card(str(source))
    net = net_from_card(card, pt)
    net_spec = {**card["spec"], **dict(spec or {})}
    if net_spec != card["spec"]:
        net = _rebuilt(net, net_spec, source)
    return net_spec, net, {"weights": str(source), "sha256": card["sha256"]}
