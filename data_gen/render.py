"""Render one job's images in a worker process; each image is written atomically, then its record.

An image counts as done when its record (``<image>.json``) exists; the record is written after the
EXR, so a run killed at any point and rerun redoes at most the images that were in flight.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from data_gen.algorithms import get_algorithm
from data_gen.plan import ImageTask, Job, derive_seed
from data_gen.scenes import get_scene
from nriqa.io.atomic import write_text_atomic
from nriqa.io.exr import write_exr
from nriqa.io.manifest import Record
from nriqa.render.backend import MAX_WAVEFRONT

log = logging.getLogger(__name__)


def record_path(root: Path, task: ImageTask) -> Path:
    return root / (task.path + ".json")


def load_record(root: Path, task: ImageTask, pixel_filter: str | None = "box", zoom: int | None = 1) -> Record | None:
    """The finished record of ``task``, or ``None`` if it has not been rendered completely (or was
    rendered through another pixel filter than ``pixel_filter``, or at another ``zoom``; ``None``: any)."""
    rec_path = record_path(root, task)
    if not rec_path.is_file() or not (root / task.path).is_file():
        return None
    try:
        rec = Record(**json.loads(rec_path.read_text(encoding="utf-8")))
    except (ValueError, TypeError):
        return None
    # A record from another plan (other seed, spp or reference) is stale: render again.
    if (rec.seed, rec.spp, rec.role, rec.reference) != (task.seed, task.spp, task.role, task.reference):
        return None
    if pixel_filter is not None and rec.pixel_filter != pixel_filter:
        return None
    if zoom is not None and rec.zoom != zoom:
        return None
    return rec


def samples_per_pass(spp: int, pixels: int) -> int:
    """The largest power-of-two divisor of ``spp`` that keeps a pass within ``MAX_WAVEFRONT``."""
    per_pass = spp
    while per_pass > 1 and per_pass * pixels > MAX_WAVEFRONT and per_pass % 2 == 0:
        per_pass //= 2
    return per_pass


def crop_offset(variant_seed: int, zoom: int, resolution: tuple[int, int]) -> tuple[int, int]:
    """Where a ``zoom``-times film's crop of ``resolution`` lies: the same for every image of a variant
    (its reference too), drawn from the variant's seed; ``(0, 0)`` at zoom 1."""
    if zoom == 1:
        return 0, 0
    rng = np.random.default_rng(derive_seed(variant_seed, "crop", zoom))
    width, height = resolution
    return int(rng.integers(0, width * (zoom - 1) + 1)), int(rng.integers(0, height * (zoom - 1) + 1))


def film_dict(job: Job) -> dict:
    """The film of a job's images: ``resolution`` pixels through ``pixel_filter``; at ``zoom`` > 1 the crop
    (:func:`crop_offset`) of a film ``zoom`` times as wide and high, so each pixel sees ``1/zoom^2`` of the area
    a pixel of the whole view would, at the cost of the crop's pixels alone."""
    width, height = job.resolution
    # The box filter (the default) keeps each pixel's noise independent of its neighbours'.
    film = {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": job.pixel_filter}}
    if job.zoom > 1:
        x, y = crop_offset(job.variant_seed, job.zoom, job.resolution)
        film.update(
            width=width * job.zoom,
            height=height * job.zoom,
            crop_offset_x=x,
            crop_offset_y=y,
            crop_width=width,
            crop_height=height,
        )
    return film


def scene_dict(job: Job, task: ImageTask) -> dict:
    """The full Mitsuba scene of one image: the variant's scene plus film, sampler, integrator."""
    spec = get_scene(job.scene)
    alg = get_algorithm(job.algorithm)
    scene = spec.build(np.random.default_rng(job.variant_seed))
    width, height = job.resolution
    film = film_dict(job)
    scene["sensor"]["film"] = film
    scene["sensor"]["sampler"] = alg.sampler_dict(task.spp)
    per_pass = samples_per_pass(task.spp, width * height) if not alg.square_spp else None
    scene["integrator"] = alg.integrator_dict(job.max_depth, per_pass)
    return scene


def loop_scene(scene: str, resolution: tuple[int, int], variant_seed: int = 1234, spp: int = 4) -> dict:
    """A scene of the catalogue as a dict for ``nriqa.render.loop`` and the benchmarks: the variant
    of ``variant_seed``, rendered by the scene's reference algorithm at its max depth into a
    box-filtered film of ``resolution``; ``spp`` sets the sampler's count (the loops pass their own)."""
    spec = get_scene(scene)
    job = Job(scene, 0, variant_seed, spec.reference_algorithm, tuple(resolution), spec.max_depth, ())
    return scene_dict(job, ImageTask("loop", "test", spp, 1, "loop.exr", "reference.exr"))


def sanitize(image: np.ndarray) -> tuple[np.ndarray, int]:
    """Replace NaN/Inf samples by 0; return the image and how many pixels had any."""
    bad = ~np.isfinite(image)
    count = int(bad.any(axis=2).sum())
    if count:
        image = np.where(bad, np.float32(0), image)
    return image, count


def render_task(root: Path, job: Job, task: ImageTask, backend: str) -> Record:
    """Render, sanitise and write one image and its record; return the record."""
    import mitsuba as mi

    scene = mi.load_dict(scene_dict(job, task))
    actual = scene.sensors()[0].sampler().sample_count()
    if actual != task.spp:
        raise RuntimeError(f"{task.id}: sampler {job.algorithm} renders {actual} spp, not {task.spp}")
    start = time.perf_counter()
    image = np.array(mi.render(scene, seed=task.seed), dtype=np.float32)
    seconds = time.perf_counter() - start
    image, nonfinite = sanitize(image)
    if nonfinite:
        log.warning(
            "%s: %d non-finite pixels from the renderer, written as 0 and counted in the manifest", task.id, nonfinite
        )
    write_exr(root / task.path, image)
    rec = Record(
        id=task.id,
        scene=job.scene,
        variant=job.variant,
        algorithm=job.algorithm,
        role=task.role,
        spp=task.spp,
        seed=task.seed,
        path=task.path,
        reference=task.reference,
        width=image.shape[1],
        height=image.shape[0],
        render_seconds=round(seconds, 4),
        backend=backend,
        twin=task.twin,
        nonfinite=nonfinite,
        pixel_filter=job.pixel_filter,
        zoom=job.zoom,
    )
    write_text_atomic(record_path(root, task), json.dumps(rec.to_dict()) + "\n")
    return rec


def run_job(root: str, job: Job, backend: str) -> tuple[int, int]:
    """Render the unfinished images of ``job`` under ``root``; return ``(rendered, skipped)``."""
    root_path = Path(root)
    rendered = skipped = 0
    for task in job.tasks:
        if load_record(root_path, task, job.pixel_filter, job.zoom) is not None:
            skipped += 1
            continue
        render_task(root_path, job, task, backend)
        rendered += 1
    return rendered, skipped
