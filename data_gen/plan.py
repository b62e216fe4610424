"""Plan a dataset: which images to render, with which seeds, where they go.

Per scene variant: one reference (independent-sampler path tracing at ``reference_factor`` times
the ladder's top), and for each algorithm each rung ``2^n`` of the spp ladder twice, a test image
and its independent twin (same spp, another seed). Every image has its own seed. With a
reference of at least ``LIMITS_REFERENCE_SPP`` samples, a scene's ``rung_limits`` end an algorithm's
ladder early where the checks of :mod:`data_gen.convergence` fail against such a reference.
"""

from __future__ import annotations

import dataclasses
import hashlib

from data_gen.algorithms import get_algorithm
from data_gen.scenes import LIMITS_REFERENCE_SPP, get_scene
from nriqa.errors import NriqaError

MIN_REFERENCE_FACTOR = 16  # thesis ch. 4: the reference needs an order of magnitude more samples
# Mitsuba's reconstruction filters. ``box`` (the default) keeps each pixel's noise its own; the others
# spread every sample over neighbouring pixels, as renderers do by default (Mitsuba: gaussian).
PIXEL_FILTERS = ("box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos")


class PlanError(NriqaError):
    """A configuration that cannot be rendered; the message says what to change."""


def derive_seed(*parts: object) -> int:
    """A 31-bit seed from any parts, stable across processes and Python versions."""
    digest = hashlib.blake2b("/".join(map(str, parts)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") & 0x7FFFFFFF


@dataclasses.dataclass(frozen=True)
class ImageTask:
    """One image to render; ``path`` and ``reference`` are relative to the dataset root."""

    id: str
    role: str
    spp: int
    seed: int
    path: str
    reference: str
    twin: str | None = None


@dataclasses.dataclass(frozen=True)
class Job:
    """One worker call: the images of one scene variant and one algorithm."""

    scene: str
    variant: int
    variant_seed: int
    algorithm: str
    resolution: tuple[int, int]
    max_depth: int
    tasks: tuple[ImageTask, ...]
    pixel_filter: str = "box"
    zoom: int = 1

    @property
    def cost(self) -> int:
        """Samples to trace, to start the longest jobs first."""
        return sum(t.spp for t in self.tasks) * self.resolution[0] * self.resolution[1]


def ladder(top: int) -> list[int]:
    """The spp ladder ``2, 4, ..., top``; ``top`` must be a power of two >= 2."""
    if top < 2 or top & (top - 1):
        raise PlanError(f"ladder_top={top} is not a power of two >= 2; use e.g. ladder_top=64")
    return [2**n for n in range(1, top.bit_length())]


def plan_dataset(
    scenes: list[str],
    variants: int,
    seed: int = 0,
    resolution: tuple[int, int] | None = None,
    ladder_top: int | None = None,
    reference_factor: int = MIN_REFERENCE_FACTOR,
    algorithms: list[str] | None = None,
    first_variant: int = 0,
    pixel_filter: str = "box",
    zoom: int = 1,
) -> list[Job]:
    """All jobs of a dataset, variant by variant, longest first within a variant. ``None`` options
    take each scene's own declaration.

    Variant by variant, so that a run stopped early holds whole variants of every scene: rerun with
    ``variants=K`` and the first ``K`` (the same images, seeds do not depend on ``variants``) are a
    complete dataset with a manifest.

    ``algorithms`` restricts every scene to those of its own algorithms named there. ``first_variant``
    skips the variants below it: ``first_variant=46, variants=48`` plans variants 46 and 47 alone, the
    same images a full run would render for them (a fresh test set beside a training set).
    ``pixel_filter`` is the film's reconstruction filter (one of ``PIXEL_FILTERS``), the reference's too.
    ``zoom`` > 1 renders each image as a ``resolution`` crop of a film ``zoom`` times as wide and high (one crop
    per variant, its reference's too): pixels as fine as a ``zoom`` times larger render's, at the crop's cost.
    """
    if variants < 1:
        raise PlanError(f"variants={variants}: need at least 1 variant per scene")
    if not 0 <= first_variant < variants:
        raise PlanError(
            f"first_variant={first_variant} with variants={variants}: "
            "need 0 <= first_variant < variants (variants counts from variant 0)"
        )
    if reference_factor < MIN_REFERENCE_FACTOR:
        raise PlanError(
            f"reference_factor={reference_factor}: the reference needs >= {MIN_REFERENCE_FACTOR}x the ladder's top spp"
        )
    if resolution is not None and (len(resolution) != 2 or min(resolution) < 8):
        raise PlanError(f"resolution={list(resolution)}: give [width, height], each >= 8")
    if isinstance(zoom, bool) or not isinstance(zoom, int) or zoom < 1:
        raise PlanError(f"zoom={zoom}: give a whole number >= 1 (1 renders the whole view)")
    if pixel_filter not in PIXEL_FILTERS:
        raise PlanError(f"pixel_filter={pixel_filter}: choose one of {', '.join(PIXEL_FILTERS)}")
    if not scenes:
        raise PlanError("no scenes selected; name at least one, e.g. scenes=[cornell]")
    for name in [*(algorithms or [])]:
        try:
            get_algorithm(name)
        except KeyError as exc:
            raise PlanError(exc.args[0]) from None
    jobs = []
    for name in scenes:
        try:
            spec = get_scene(name)
        except KeyError as exc:
            raise PlanError(exc.args[0]) from None
        res = tuple(resolution) if resolution is not None else spec.resolution
        rungs = ladder(ladder_top or spec.ladder_top)
        chosen = [a for a in spec.algorithms if algorithms is None or a in algorithms]
        for v in range(first_variant, variants):
            base = f"{name}/v{v:03d}"
            ref = f"{base}/reference.exr"
            vseed = derive_seed(seed, name, v)
            ref_task = ImageTask(
                f"{base}/reference",
                "reference",
                rungs[-1] * reference_factor,
                derive_seed(seed, name, v, "reference"),
                ref,
                ref,
            )
            ref_alg = spec.reference_algorithm
            jobs.append(Job(name, v, vseed, ref_alg, res, spec.max_depth, (ref_task,), pixel_filter, zoom))
            for alg_name in chosen:
                alg = get_algorithm(alg_name)
                tasks = []
                limits = spec.rung_limits if rungs[-1] * reference_factor >= LIMITS_REFERENCE_SPP else {}
                limit = limits.get(alg_name, rungs[-1])
                for spp in (s for s in rungs if alg.accepts(s) and s <= limit):
                    stem = f"{base}/{alg_name}/spp{spp:05d}"
                    ids = (f"{stem}_a", f"{stem}_b")
                    for role, own, other in (("test", ids[0], ids[1]), ("twin", ids[1], ids[0])):
                        tasks.append(ImageTask(own, role, spp, derive_seed(seed, own), own + ".exr", ref, other))
                jobs.append(Job(name, v, vseed, alg_name, res, spec.max_depth, tuple(tasks), pixel_filter, zoom))
    return sorted(jobs, key=lambda j: (j.variant, -j.cost))
