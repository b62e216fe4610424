"""Training augmentation: HSV jitter (thesis eq. 5.1) plus horizontal flip and 90-degree rotations.

One draw per example is applied identically to the noisy render and its reference, so the
full-reference target computed afterwards from the jittered pair stays consistent. Training only;
never used at validation or inference.
"""

from __future__ import annotations

import dataclasses
import math

import torch
from kornia.color import hsv_to_rgb, rgb_to_hsv
from torch import Tensor

SAT_RANGE = 0.3
VAL_RANGE = 0.3
VAL_STOPS = 0.7
VALUE_MODES = ("add", "scale", "off")
FLIP_P = 0.5


@dataclasses.dataclass(frozen=True)
class JitterParams:
    """One draw of the augmentation.

    Attributes:
        hue_shift: added to hue in turns, in [0, 1) (eq. 5.1: H' = (H + U(0, 1)) mod 1).
        sat_shift: added to saturation, in [-0.3, 0.3] (S' = clip(S + U(-0.3, 0.3), 0, 1)).
        val_shift: added to value, in [-0.3, 0.3] (V' = clip(V + U(-0.3, 0.3), 0, 1)).
        val_scale: multiplies value first, in [2^-0.7, 2^0.7] with ``value="scale"``
            (V' = clip(V * 2^U(-0.7, 0.7), 0, 1), an exposure change of the displayed image); 1 otherwise.
        flip: mirror left-right.
        rot_k: number of counter-clockwise quarter turns, 0..3 (after the flip).
    """

    hue_shift: float = 0.0
    sat_shift: float = 0.0
    val_shift: float = 0.0
    val_scale: float = 1.0
    flip: bool = False
    rot_k: int = 0

    @property
    def has_hsv(self) -> bool:
        return (self.hue_shift, self.sat_shift, self.val_shift, self.val_scale) != (0.0, 0.0, 0.0, 1.0)


def check_value_mode(value: bool | str) -> str:
    """The value part of the HSV jitter as one of :data:`VALUE_MODES`; ``True`` is ``"add"``, ``False`` is ``"off"``.

    Raises:
        ValueError: anything else, in one line naming the choices.
    """
    if value is True or value is False:
        return "add" if value else "off"
    if isinstance(value, str) and value in VALUE_MODES:
        return value
    raise ValueError(
        f"data.jitter.value must be one of {', '.join(VALUE_MODES)} (or true = add, false = off), got {value!r}"
    )


def sample_jitter(
    generator: torch.Generator, hsv: bool = True, geometric: bool = True, value: bool | str = "add"
) -> JitterParams:
    """Draw one :class:`JitterParams` from ``generator`` (thesis eq. 5.1, flip p = 0.5, k ~ U{0..3}).

    The same number of random values is consumed whatever the flags, so switching one part off
    does not change the draws of the other or of later examples.

    Args:
        generator: the source of randomness (seed it for reproducible training).
        hsv: draw the colour shifts; if False they are 0.
        geometric: draw flip and rotation; if False, no flip and k = 0.
        value: with ``hsv``, how value moves (:func:`check_value_mode`): ``"add"`` (the thesis, ``True``) adds
            U(-0.3, 0.3); ``"off"`` (``False``) leaves it, hue and saturation drawn as before; ``"scale"`` multiplies
            it by 2^U(-0.7, 0.7) from the same random number. An additive value shift lifts a dark render's black
            pixels or clips its dim ones to black in both images, where SSIM is near 1, so a dark, sparse render's
            jittered targets run far above its own (0.35-0.73 against 0.28 for one 2-spp render;
            docs/training.md); a scale keeps black pixels black, as an exposure change does.

    Examples:
        >>> p = sample_jitter(torch.Generator().manual_seed(0))
        >>> 0.0 <= p.hue_shift < 1.0 and p.rot_k in (0, 1, 2, 3)
        True
    """
    if not isinstance(generator, torch.Generator):
        raise TypeError(f"sample_jitter needs a torch.Generator, got {type(generator).__name__}")
    mode = check_value_mode(value)
    u = torch.rand(4, generator=generator, dtype=torch.float64, device=generator.device).tolist()
    k = int(torch.randint(0, 4, (1,), generator=generator, device=generator.device).item())
    params = JitterParams()
    if hsv:
        params = dataclasses.replace(
            params,
            hue_shift=u[0],
            sat_shift=(2.0 * u[1] - 1.0) * SAT_RANGE,
            val_shift=(2.0 * u[2] - 1.0) * VAL_RANGE if mode == "add" else 0.0,
            val_scale=2.0 ** ((2.0 * u[2] - 1.0) * VAL_STOPS) if mode == "scale" else 1.0,
        )
    if geometric:
        params = dataclasses.replace(params, flip=u[3] < FLIP_P, rot_k=k)
    return params


def apply_jitter(img: Tensor, p: JitterParams) -> Tensor:
    """Apply one draw to an LDR image or to every image of a batch.

    Colour first, in HSV (kornia's hue is in radians, so the shift is ``2 pi * hue_shift``), then
    a left-right flip, then ``rot_k`` counter-clockwise quarter turns (``torch.rot90`` on H, W).
    An odd ``rot_k`` swaps H and W.

    Args:
        img: ``(3, H, W)`` or ``(B, 3, H, W)`` RGB in [0, 1] (tone-mapped LDR).
        p: the draw, from :func:`sample_jitter`.

    Returns:
        Tensor of the same dtype, values in [0, 1]; shape ``(..., 3, H, W)``, or ``(..., 3, W, H)``
        for odd ``rot_k``.
    """
    if not isinstance(img, Tensor) or not img.is_floating_point():
        raise TypeError(f"apply_jitter expects a floating-point torch.Tensor, got {getattr(img, 'dtype', type(img).__name__)}")
    if img.ndim not in (3, 4) or img.shape[-3] != 3:
        raise ValueError(f"apply_jitter expects (3, H, W) or (B, 3, H, W) RGB, got {tuple(img.shape)}")
    out = img
    if p.has_hsv:
        out = shift_hsv(img, p.hue_shift, p.sat_shift, p.val_shift, p.val_scale)
    if p.flip:
        out = out.flip(-1)
    if p.rot_k % 4:
        out = torch.rot90(out, p.rot_k % 4, dims=(-2, -1))
    return out


def shift_hsv(
    img: Tensor, hue: float | Tensor, sat: float | Tensor, val: float | Tensor, scale: float | Tensor = 1.0
) -> Tensor:
    """The colour part of the jitter (eq. 5.1): shift hue (in turns, wrapped), saturation and value (clipped).

    Value is multiplied by ``scale`` before ``val`` is added (the ``"scale"`` mode of :func:`sample_jitter`).

    Args:
        img: ``(..., 3, H, W)`` RGB in [0, 1].
        hue, sat, val, scale: the shifts and the value factor, numbers or tensors that broadcast against ``(..., H, W)`` (one per
            image of a batch: shape ``(B, 1, 1)``); a tensor hue is turned into radians in its own
            dtype (give float64 for the same result as a Python number), then moved to the image's
            device and dtype.

    Returns:
        RGB of the same shape and dtype, in [0, 1].
    """
    h, s, v = rgb_to_hsv(img.clamp(0.0, 1.0)).unbind(dim=-3)
    angle = 2.0 * math.pi * hue
    if isinstance(angle, Tensor):
        angle = angle.to(device=h.device, dtype=h.dtype)
    h = torch.remainder(h + angle, 2.0 * math.pi)
    s = (s + sat).clamp(0.0, 1.0)
    v = (v * scale + val).clamp(0.0, 1.0)
    return hsv_to_rgb(torch.stack((h, s, v), dim=-3)).clamp(0.0, 1.0)


def jitter_pair(
    noisy: Tensor, ref: Tensor, generator: torch.Generator, hsv: bool = True, geometric: bool = True
) -> tuple[Tensor, Tensor]:
    """Draw once and apply the same jitter to a (noisy, reference) pair of LDR images.

    Args:
        noisy: ``(3, H, W)`` tone-mapped render in [0, 1].
        ref: ``(3, H, W)`` tone-mapped reference, same shape.
        generator: the source of randomness.
        hsv: apply the HSV jitter (eq. 5.1).
        geometric: apply flip and rotation.

    Returns:
        ``(noisy, ref)`` jittered identically.

    Examples:
        >>> x = torch.rand(3, 8, 8)
        >>> a, b = jitter_pair(x, x.clone(), torch.Generator().manual_seed(1))
        >>> torch.equal(a, b)
        True
    """
    for name, t in (("noisy", noisy), ("ref", ref)):
        if not isinstance(t, Tensor) or t.ndim != 3:
            raise ValueError(f"jitter_pair: {name} must be a (3, H, W) tensor, got {getattr(t, 'shape', type(t).__name__)}")
    if noisy.shape != ref.shape:
        raise ValueError(f"jitter_pair: noisy and ref must have the same shape, got {tuple(noisy.shape)} and {tuple(ref.shape)}")
    params = sample_jitter(generator, hsv=hsv, geometric=geometric)
    return apply_jitter(noisy, params), apply_jitter(ref, params)
