"""Start a training from trained weights instead of random ones (fine-tuning).

``nriqa-train ... init_from=SOURCE [init_member=I]``: ``SOURCE`` is a shipped weights name
(``unet_fast``), a ``.pt`` with its card beside it, or a training checkpoint (``.ckpt``). Shipped
weights that average several runs (``map_mean``) hold one network per member; ``init_member``
picks which one starts this run. The network being trained must be the same model with the same
settings: every weight name and shape must match, or nothing is loaded. ``init_body_only=true`` loads
everything but the output head (the weights under ``head.``) and leaves the head at its random start:
a model with another head on the same body, e.g. ``unet_fast_ssim`` started from ``unet_fast``.

    >>> net = create_model("unet_fast", window=64)  # doctest: +SKIP
    >>> warm_start(net, "unet_fast", member=0)  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

from torch import nn

from nriqa.errors import NriqaError
from nriqa.inference.pretrained import load_pretrained
from nriqa.training.checkpoint import load_net_from_checkpoint

__all__ = ["WarmStartError", "source_net", "warm_start"]


class WarmStartError(NriqaError):
    """Weights that cannot start this training; the message says which source and what to do."""


def source_net(source: str) -> nn.Module:
    """The trained network of ``source``: a ``.ckpt`` training checkpoint, else shipped weights.

    Raises:
        CheckpointError, PretrainedError (both :class:`~nriqa.errors.NriqaError`): unreadable or unknown.
    """
    if Path(source).suffix == ".ckpt":
        return load_net_from_checkpoint(source)
    return load_pretrained(source)


def _member(net: nn.Module, source: str, member: int | None) -> nn.Module:
    members = getattr(net, "members", None)
    if member is None:
        if members is not None:
            raise WarmStartError(
                f"init_from={source} averages {len(members)} networks; pick the one to start from with "
                f"init_member=0..{len(members) - 1}"
            )
        return net
    if members is None:
        raise WarmStartError(
            f"init_member={member}, but init_from={source} is a single network; leave init_member unset"
        )
    if not 0 <= member < len(members):
        raise WarmStartError(
            f"init_member={member} is out of range: init_from={source} has members 0..{len(members) - 1}"
        )
    return members[member]


HEAD = "head."


def _without_head(state: dict) -> dict:
    return {k: v for k, v in state.items() if not k.startswith(HEAD)}


def warm_start(net: nn.Module, source: str, member: int | None = None, body_only: bool = False) -> nn.Module:
    """Load the weights of ``source`` (member ``member`` of an average) into ``net``, in place.

    Returns ``net``. Nothing is loaded unless every parameter and buffer name and shape matches; with
    ``body_only`` the weights under ``head.`` are left out on both sides and ``net``'s head keeps its start.

    Raises:
        WarmStartError: a member choice that does not fit the source, weights of another model, or
            ``body_only`` for a network without a ``head``.
    """
    src = _member(source_net(source), source, member).state_dict()
    dst = net.state_dict()
    if body_only:
        if not any(k.startswith(HEAD) for k in dst):
            raise WarmStartError(
                f"init_body_only=true keeps the head of the model being trained, but it has no 'head' module; "
                f"drop init_body_only to load all of init_from={source}"
            )
        src, dst = _without_head(src), _without_head(dst)
    missing = sorted(set(dst) - set(src))
    extra = sorted(set(src) - set(dst))
    shapes = sorted(k for k in set(src) & set(dst) if src[k].shape != dst[k].shape)
    if missing or extra or shapes:
        first = (missing or extra or shapes)[0]
        raise WarmStartError(
            f"init_from={source}: its weights do not fit the model being trained ({len(missing)} missing, "
            f"{len(extra)} unexpected, {len(shapes)} of another shape, e.g. {first!r}); train the same model "
            "with the same settings as the source (its card's 'spec' or checkpoint's net)"
        )
    net.load_state_dict(src, strict=not body_only)
    return net
