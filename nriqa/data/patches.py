"""Random training patches and fixed validation patches cut from tone-mapped image pairs.

Training patch ``k`` is a pure function of ``(seed, k)``: its own generator picks the image, the
position and the jitter. An :class:`EpochSampler` hands out indices ``k`` that are fresh every
epoch (and distinct per DDP rank), so runs are reproducible whatever the number of workers.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch
import torch.distributed as dist
from torch import Tensor
from torch.utils.data import Dataset, Sampler, TensorDataset

from nriqa.core.display import Display, DisplayMix, apply_display
from nriqa.data.albedo import LINE_PERIOD, check_albedo_lines, check_albedo_p, check_line_period, check_min_spp, sample_albedo, texture
from nriqa.data.anchors import NO_ANCHORS, Anchors, check_anchors
from nriqa.data.coarse import check_coarse_p, coarse_batch, sample_coarse
from nriqa.data.converged import check_converged_p, converged_batch, sample_converged
from nriqa.data.cutmix import Box, check_cutmix_p, partner_generator, paste_batch, sample_box
from nriqa.data.pixel_filter import (
    SIGMA_RANGE,
    apply_pixel_filter,
    check_pixel_filter,
    rendered_sigma,
    sample_pixel_filter,
)
from nriqa.data.images import ImagePair
from nriqa.data.jitter import JitterParams, check_value_mode, sample_jitter, shift_hsv
from nriqa.data.ladders import check_span, ladder_partners, pick_partner
from nriqa.data.targets import check_target, compute_target

# The display renders go through at inference (EXR input): the package tone map.
TONEMAP = Display("tonemap")


def item_generator(seed: int, index: int) -> torch.Generator:
    """A generator for item ``index`` of stream ``seed``; well mixed, so nearby indices are unrelated."""
    state = np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint64)[0]
    return torch.Generator().manual_seed(int(state))


def check_patch_size(pairs: list[ImagePair], patch_size: int) -> None:
    """Raise a one-line ``ValueError`` if any image is smaller than a patch."""
    for p in pairs:
        h, w = p.noisy.shape[-2:]
        if h < patch_size or w < patch_size:
            raise ValueError(f"{p.record.path} is {h}x{w}, smaller than patch_size={patch_size}; lower data.patch_size")


def cut_all(
    pair: ImagePair, generator: torch.Generator, size: int, twins: bool = False, albedo_pass: bool = False
) -> list[Tensor]:
    """Cut one ``size`` x ``size`` patch at a uniformly random position, the same from noisy, ref (twin, albedo pass)."""
    h, w = pair.noisy.shape[-2:]
    y = int(torch.randint(0, h - size + 1, (1,), generator=generator))
    x = int(torch.randint(0, w - size + 1, (1,), generator=generator))
    images = members_of(pair, twins, albedo_pass)
    return [img[:, y : y + size, x : x + size] for img in images]


def members_of(pair: ImagePair, twins: bool, albedo_pass: bool) -> list[Tensor]:
    """The images a patch is cut from alike: noisy, reference, then the twin and the albedo pass where asked."""
    return [pair.noisy, pair.ref] + ([pair.twin] if twins else []) + ([pair.albedo] if albedo_pass else [])


def cut(pair: ImagePair, generator: torch.Generator, size: int) -> tuple[Tensor, Tensor]:
    """Cut one ``size`` x ``size`` patch at a uniformly random position, the same from noisy and ref."""
    noisy, ref = cut_all(pair, generator, size)
    return noisy, ref


def displayed(pair: ImagePair, patches: tuple[Tensor, ...], display: Display) -> list[Tensor]:
    """LDR patches of ``pair`` through ``display``; tone-mapped pairs pass through unchanged.

    Linear pairs (loaded with ``linear=True``) are displayed with the image's key exposure, the same
    for every member, so a noisy patch, its twin and its reference stay comparable.
    """
    if not pair.linear:
        if display != TONEMAP:
            raise ValueError("display transforms need linear image pairs; load them with linear=True")
        return list(patches)
    return [apply_display(p, display, pair.key) for p in patches]


def network_input(noisy: Tensor, twin: Tensor | None, albedo: Tensor | None = None) -> Tensor:
    """What a model sees: the image ``(3,P,P)``, stacked on its channels with its twin and/or its albedo pass."""
    extra = [t for t in (twin, albedo) if t is not None]
    return torch.cat([noisy, *extra], dim=-3) if extra else noisy


class TrainPatches(Dataset):
    """Random jittered training patches; item ``k`` is ``(input, target)`` drawn from ``(seed, k)``.

    The image is picked (uniformly, or by :meth:`set_weights`), then the position, then (with
    ``display``) a display transform, then the jitter, then (with ``albedo_p``) an albedo texture, then
    (with ``pixel_filter_p``) a pixel filter (:mod:`nriqa.data.pixel_filter`; never on images the manifest
    says were rendered through one), each applied to noisy image, twin and reference alike (with ``converged_p``
    the noisy image of a share of the items is the reference itself: :mod:`nriqa.data.converged`; with ``cutmix_p``
    a share of the items get a rectangle of a partner item of their own, made alike: :mod:`nriqa.data.cutmix`; with
    ``coarse_p`` a share carry a half-size copy of their cut at half the resolution, right after the cut:
    :mod:`nriqa.data.coarse`), and
    the target is computed from the textured, filtered, displayed, jittered (pasted) pair. The texture and the filter act on the linear radiance, before the display (a tone-mapped pair:
    on its displayed values). With ``albedo_pass`` the scene's albedo pass is cut,
    textured and jittered alike, but not displayed: it stays a reflectance. ``input`` is the noisy patch
    ``(3,P,P)``, or with ``twins`` the noisy patch and its twin's ``(6,P,P)``, or with ``albedo_pass``
    the noisy patch and its albedo's ``(6,P,P)`` (both: ``(9,P,P)``). With ``anchors`` each item
    is ``(input, target, anchored)``, ``anchored`` true where the image is one of them (:mod:`nriqa.data.anchors`)
    and the item is neither a converged, a pasted nor a coarse one (these learn their own target): the
    training module then learns the starting network's map there instead of the target
    (:class:`nriqa.training.module.NRIQAModule`). With ``ladder_pairs`` every odd item ``k`` is item ``k - 1``'s
    cut, display, jitter, texture and filter taken from another rung of its ladder within ``ladder_span``
    doublings of its sample count (:mod:`nriqa.data.ladders`; the same image where there is none), so a batch
    of even size holds pairs ``(2i, 2i + 1)`` of one view at two sample counts. Any ``k >= 0`` is valid; ``len``
    is the number of items per epoch.
    """

    def __init__(
        self,
        pairs: list[ImagePair],
        patch_size: int,
        target: str,
        length: int,
        seed: int,
        hsv: bool = True,
        geometric: bool = True,
        display: DisplayMix | None = None,
        value: bool | str = "add",
        twins: bool = False,
        albedo_p: float = 0.0,
        albedo_pass: bool = False,
        albedo_lines: float = 0.0,
        albedo_line_period: tuple[float, float] = LINE_PERIOD,
        albedo_min_spp: int = 0,
        pixel_filter_p: float = 0.0,
        pixel_filter_sigma: tuple[float, float] = SIGMA_RANGE,
        anchors: Anchors = NO_ANCHORS,
        ladder_pairs: bool = False,
        ladder_span: int = 2,
        converged_p: float = 0.0,
        cutmix_p: float = 0.0,
        coarse_p: float = 0.0,
    ) -> None:
        if not pairs:
            raise ValueError("TrainPatches needs at least one image pair")
        self.cutmix_p = check_cutmix_p(cutmix_p, ladder_pairs)
        if ladder_pairs and length % 2:
            raise ValueError(f"ladder pairs need an even number of items per epoch, got {length}")
        check_patch_size(pairs, patch_size)
        check_pairs(pairs, display is not None, twins, albedo_pass)
        self.pairs = pairs
        self.patch_size = patch_size
        self.target = check_target(target)
        self.length = length
        self.seed = seed
        self.hsv = hsv
        self.geometric = geometric
        self.value = check_value_mode(value)
        self.display = display
        self.twins = twins
        self.albedo_p = check_albedo_p(albedo_p)
        self.albedo_pass = albedo_pass
        self.albedo_lines = check_albedo_lines(albedo_lines)
        self.albedo_line_period = check_line_period(albedo_line_period)
        self.albedo_min_spp = check_min_spp(albedo_min_spp)
        self.pixel_filter_p, self.pixel_filter_sigma = check_pixel_filter(pixel_filter_p, pixel_filter_sigma)
        self.converged_p = check_converged_p(converged_p, twins)
        self.coarse_p = check_coarse_p(coarse_p, patch_size)
        self.anchors = check_anchors(anchors, pairs, converged=self.converged_p > 0)
        self.cdf: Tensor | None = None
        self.ladder_pairs = bool(ladder_pairs)
        span = check_span(ladder_span)
        self.partners = ladder_partners([p.record for p in pairs], span) if self.ladder_pairs else []

    def __len__(self) -> int:
        return self.length

    def set_weights(self, weights: Tensor | None) -> None:
        """Draw image ``i`` with probability ``weights[i] / sum(weights)`` from now on; ``None``: uniformly.

        Item ``k`` stays a pure function of ``(seed, k)`` and the weights.

        Raises:
            ValueError: not one weight per image, a negative or non-finite weight, or all zero.
        """
        if weights is None:
            self.cdf = None
            return
        w = torch.as_tensor(weights, dtype=torch.float64).flatten()
        if w.numel() != len(self.pairs):
            raise ValueError(f"set_weights needs one weight per training image ({len(self.pairs)}), got {w.numel()}")
        if not bool(torch.isfinite(w).all()) or bool((w < 0).any()) or float(w.sum()) <= 0.0:
            raise ValueError("set_weights needs finite, non-negative weights with a positive sum")
        self.cdf = torch.cumsum(w, 0) / w.sum()

    def pick(self, g: torch.Generator) -> ImagePair:
        """The image of one draw: uniform, or by the weights of :meth:`set_weights`."""
        return self.pairs[self.pick_index(g)]

    def pick_index(self, g: torch.Generator) -> int:
        """The index of :meth:`pick`'s image."""
        if self.cdf is None:
            return int(torch.randint(0, len(self.pairs), (1,), generator=g))
        u = torch.rand(1, generator=g, dtype=torch.float64)
        return min(int(torch.searchsorted(self.cdf, u, right=True)), len(self.pairs) - 1)

    def draw(self, index: int) -> Draw:
        """The random choices of item ``index``: image, position, display, jitter and albedo, from ``(seed, index)``.

        With ``ladder_pairs`` an odd ``index`` takes item ``index - 1``'s choices to another rung of its ladder.
        With ``cutmix_p`` the rectangle its partner (:meth:`partner`) fills is drawn last.
        """
        if self.ladder_pairs and index % 2:
            first = self.draw(index - 1)
            own = first.image
            other = pick_partner(self.partners[own], own, item_generator(self.seed, index))
            return dataclasses.replace(first, pair=self.pairs[other], image=other)
        g = item_generator(self.seed, index)
        own = self.draw_from(g)
        box = sample_box(g, self.cutmix_p, self.patch_size)  # drawn last: the rest as before
        return own if box is None else dataclasses.replace(own, cutmix=box)

    def partner(self, index: int) -> Draw:
        """The random choices of the item whose rectangle item ``index`` carries, from a stream of its own."""
        return self.draw_from(partner_generator(self.seed, index))

    def draw_from(self, g: torch.Generator) -> Draw:
        """One item's choices (image, position, display, jitter, albedo, filter, converged), drawn from ``g``."""
        image = self.pick_index(g)
        pair = self.pairs[image]
        h, w = pair.noisy.shape[-2:]
        y = int(torch.randint(0, h - self.patch_size + 1, (1,), generator=g))
        x = int(torch.randint(0, w - self.patch_size + 1, (1,), generator=g))
        display = self.display.sample(g) if self.display is not None else TONEMAP
        jitter = (
            sample_jitter(g, hsv=self.hsv, geometric=self.geometric, value=self.value)
            if self.hsv or self.geometric
            else None
        )
        albedo = sample_albedo(g, self.albedo_p)
        if pair.record.spp < self.albedo_min_spp:
            albedo = None  # too few samples for a texture (drawn all the same: the other draws stay as they were)
        sigma = sample_pixel_filter(g, self.pixel_filter_p, self.pixel_filter_sigma)  # drawn after: the rest as before
        if pair.record.pixel_filter != "box":
            sigma = None  # rendered through a filter already (drawn all the same: the other images' draws stay)
        converged = sample_converged(g, self.converged_p)
        coarse = sample_coarse(g, self.coarse_p, self.patch_size)  # drawn after: the rest as before
        return Draw(pair, y, x, display, jitter, albedo, sigma, image, converged, coarse=coarse)

    def __getitem__(self, index: int) -> tuple[Tensor, ...]:
        return self.__getitems__([index])[0]

    def __getitems__(self, indices: list[int]) -> list[tuple[Tensor, ...]]:
        """Items ``indices`` made together: each drawn alone, then cut, displayed, jittered and scored as one batch.

        The DataLoader calls this with a batch's indices; the result equals ``[self[k] for k in indices]``
        (the draws are the same, only the arithmetic is batched), at a fraction of the per-item cost.
        """
        draws = [self.draw(int(k)) for k in indices]
        pasted = [i for i, d in enumerate(draws) if d.cutmix is not None]
        boxes = {i: (draws[i].cutmix, len(draws) + n) for n, i in enumerate(pasted)}
        draws = draws + [self.partner(int(indices[i])) for i in pasted]  # partners made alike, then pasted
        size = self.patch_size
        sources = [members_of(d.pair, self.twins, self.albedo_pass) for d in draws]
        members = [
            torch.stack([src[j][:, d.y : d.y + size, d.x : d.x + size] for src, d in zip(sources, draws)])
            for j in range(len(sources[0]))
        ]
        members = converged_batch([i for i, d in enumerate(draws) if d.converged], members)
        members = coarse_batch({i: d.coarse for i, d in enumerate(draws) if d.coarse is not None}, members)
        members = albedo_batch(draws, members, self.albedo_lines, self.albedo_line_period)
        members = pixel_filter_batch(draws, members)
        shown = len(members) - int(self.albedo_pass)  # the albedo pass is a reflectance: not displayed
        members = display_batch(draws, members[:shown]) + members[shown:]
        members = jitter_batch(draws, members)
        members = [m[: len(indices)] for m in paste_batch(boxes, members)]
        draws = draws[: len(indices)]
        noisy, ref = members[0], members[1]
        target = compute_target(self.target, noisy, ref)
        inputs = network_input(noisy, members[2] if self.twins else None, members[-1] if self.albedo_pass else None)
        if self.anchors:
            anchored = [
                torch.tensor(self.anchors(d.pair.record) and not d.learns_own_target) for d in draws
            ]
            return [(inputs[i].contiguous(), target[i], anchored[i]) for i in range(len(draws))]
        return [(inputs[i].contiguous(), target[i]) for i in range(len(draws))]


@dataclasses.dataclass(frozen=True)
class Draw:
    """The random choices of one training item (:meth:`TrainPatches.draw`)."""

    pair: ImagePair
    y: int
    x: int
    display: Display
    jitter: JitterParams | None
    albedo: int | None = None  # the seed of the patch's albedo texture (nriqa.data.albedo), or none
    pixel_sigma: float | None = None  # the pixel filter's standard deviation (nriqa.data.pixel_filter), or none
    image: int = -1  # the index of ``pair`` among the training images
    converged: bool = False  # the input is the reference itself (nriqa.data.converged)
    cutmix: Box | None = None  # the rectangle a partner item fills (nriqa.data.cutmix), or none
    coarse: Box | None = None  # the square the item's own coarse copy fills (nriqa.data.coarse), or none

    @property
    def learns_own_target(self) -> bool:
        """True for a converged, pasted or coarse item: made to teach its own target, never anchored."""
        return self.converged or self.cutmix is not None or self.coarse is not None


def albedo_batch(
    draws: list[Draw], members: list[Tensor], lines: float = 0.0, period: tuple[float, float] = LINE_PERIOD
) -> list[Tensor]:
    """Each item of the ``(B, C, P, P)`` member stacks multiplied by its draw's albedo texture, the same for every member.

    ``lines``: the share of those textures that are grilles of thin lines, their spacing uniform in ``period``
    pixels (:func:`nriqa.data.albedo.texture`).
    A render made through a Gaussian filter already gets its texture through the same filter (emulated), as
    the renderer would have drawn the texture; other renders get it as it is.
    """
    rows = [i for i, d in enumerate(draws) if d.albedo is not None]
    if not rows:
        return members
    size = members[0].shape[-1]
    textures = torch.stack([rendered_texture(draws[i], size, lines, period) for i in rows]).to(members[0])
    out = [m.clone() for m in members]
    for o in out:
        o[rows] = o[rows] * textures
    return out


def rendered_texture(draw: Draw, size: int, lines: float, period: tuple[float, float] = LINE_PERIOD) -> Tensor:
    """Draw ``draw``'s ``(C, size, size)`` albedo texture, through its render's own filter where it has one."""
    tex = texture(draw.albedo, size, lines, period)
    sigma = rendered_sigma(draw.pair.record.pixel_filter)
    return tex if sigma is None else apply_pixel_filter(tex[None], sigma)[0]


def pixel_filter_batch(draws: list[Draw], members: list[Tensor]) -> list[Tensor]:
    """Each item of the ``(B, C, P, P)`` member stacks through its draw's pixel filter, the same for every member
    (the albedo pass too: a renderer filters its passes with the image's film)."""
    rows = [i for i, d in enumerate(draws) if d.pixel_sigma is not None]
    if not rows:
        return members
    out = [m.clone() for m in members]
    for i in rows:
        for o in out:
            o[i : i + 1] = apply_pixel_filter(o[i : i + 1], draws[i].pixel_sigma)
    return out


def display_batch(draws: list[Draw], members: list[Tensor]) -> list[Tensor]:
    """Each item of the ``(B, 3, P, P)`` member stacks through its own display, batched by curve and bits.

    Tone-mapped pairs pass through unchanged (only the tone map is allowed for them). For linear
    pairs, items that share a curve and quantisation go through :func:`apply_display` together, each
    with its own exposure ``key * 2 ** stops``, the same for every member of an item.
    """
    linear = [d.pair.linear for d in draws]
    if not any(linear):
        if any(d.display != TONEMAP for d in draws):
            raise ValueError("display transforms need linear image pairs; load them with linear=True")
        return members
    if not all(linear):
        raise ValueError("training pairs mix tone-mapped and linear images; load them all alike (linear=True or not)")
    out = [torch.empty_like(m) for m in members]
    groups: dict[tuple[str, int | None], list[int]] = {}
    for i, d in enumerate(draws):
        groups.setdefault((d.display.curve, d.display.bits), []).append(i)
    for (curve, bits), rows in groups.items():
        scale = [draws[i].pair.key * 2.0 ** draws[i].display.stops for i in rows]
        scale = torch.tensor(scale, dtype=members[0].dtype, device=members[0].device).view(-1, 1, 1, 1)
        for m, o in zip(members, out):
            o[rows] = apply_display(m[rows], Display(curve, 0.0, bits), scale)
    return out


def jitter_batch(draws: list[Draw], members: list[Tensor]) -> list[Tensor]:
    """Each item's jitter (:func:`nriqa.data.jitter.apply_jitter`) on the member stacks: colour batched, then flip/turns."""
    params = [d.jitter for d in draws]
    if all(p is None for p in params):
        return members
    colour = [i for i, p in enumerate(params) if p is not None and p.has_hsv]
    if colour:
        shifts = torch.tensor(
            [[params[i].hue_shift, params[i].sat_shift, params[i].val_shift, params[i].val_scale] for i in colour],
            dtype=torch.float64,
        ).view(-1, 4, 1, 1)
        hue, sat, val, scale = shifts[:, 0], *(shifts[:, j].to(members[0]) for j in (1, 2, 3))
        members = [m.clone() for m in members]
        for m in members:
            m[colour] = shift_hsv(m[colour], hue, sat, val, scale)
    out = []
    for m in members:
        items = []
        for i, p in enumerate(params):
            item = m[i]
            if p is not None and p.flip:
                item = item.flip(-1)
            if p is not None and p.rot_k % 4:
                item = torch.rot90(item, p.rot_k % 4, dims=(-2, -1))
            items.append(item)
        out.append(torch.stack(items))
    return out


class EpochSampler(Sampler[int]):
    """Indices ``[(epoch * world + rank) * n, ... + n)``: new patches each epoch and on each rank.

    Lightning calls :meth:`set_epoch` before every training epoch.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return self.n

    def __iter__(self):
        rank, world = (
            (dist.get_rank(), dist.get_world_size()) if dist.is_available() and dist.is_initialized() else (0, 1)
        )
        start = (self.epoch * world + rank) * self.n
        return iter(range(start, start + self.n))


def check_pairs(pairs: list[ImagePair], linear: bool, twins: bool, albedo_pass: bool = False) -> None:
    """Raise a one-line ``ValueError`` if the pairs lack what display transforms, twin or albedo inputs need."""
    if linear and not all(p.linear for p in pairs):
        raise ValueError("display transforms need linear image pairs; load them with linear=True")
    missing = [p.record.path for p in pairs if twins and p.twin is None]
    if missing:
        raise ValueError(f"{missing[0]} has no twin image; twin inputs need a dataset rendered with twins")
    missing = [p.record.path for p in pairs if albedo_pass and p.albedo is None]
    if missing:
        raise ValueError(f"{missing[0]} has no albedo pass; load the pairs with albedo=True")


def fixed_patches(
    pairs: list[ImagePair],
    n: int,
    patch_size: int,
    target: str,
    seed: int,
    twins: bool = False,
    albedo_pass: bool = False,
) -> TensorDataset:
    """``n`` patches at seeded random positions, no jitter: a fixed evaluation set ``(input, target)``.

    Images are visited round-robin (so each held-out image contributes alike), positions drawn
    from one generator seeded with ``seed``. Linear pairs go through the package tone map, as
    renders do at inference; ``input`` holds the twin too with ``twins``, the albedo pass (as it is)
    with ``albedo_pass``.
    """
    if not pairs:
        raise ValueError("fixed_patches needs at least one image pair")
    check_patch_size(pairs, patch_size)
    check_pairs(pairs, False, twins, albedo_pass)
    g = torch.Generator().manual_seed(int(seed))
    cuts = []
    for i in range(n):
        pair = pairs[i % len(pairs)]
        members = cut_all(pair, g, patch_size, twins, albedo_pass)
        shown = len(members) - int(albedo_pass)
        cuts.append(displayed(pair, tuple(members[:shown]), TONEMAP) + members[shown:])
    noisy = torch.stack([c[0] for c in cuts])
    ref = torch.stack([c[1] for c in cuts])
    twin = torch.stack([c[2] for c in cuts]) if twins else None
    inputs = network_input(noisy, twin, torch.stack([c[-1] for c in cuts]) if albedo_pass else None)
    return TensorDataset(inputs, compute_target(target, noisy, ref))
