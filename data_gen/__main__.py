"""``python -m data_gen preset=tiny out=DIR``: render a dataset (resumable) and write its manifest."""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from data_gen.executors import EXECUTORS, ExecutorError, local_threads, log_progress, render_dask, run_local
from data_gen.plan import Job, PlanError, plan_dataset
from data_gen.render import load_record
from nriqa.data.options import check_names, check_whole
from nriqa.io.atomic import sweep_partials
from nriqa.io.manifest import write_manifest
from nriqa.render.backend import select_backend

log = logging.getLogger("data_gen")
CONFIG_DIR = str(Path(__file__).resolve().parent / "configs")


def fail(message: str) -> None:
    print(f"data_gen: error: {message}", file=sys.stderr)
    sys.exit(2)


def names(key: str, value) -> list[str] | None:
    """``value`` as a list of names (one bare name is a list of one); else fail with one line naming ``key``."""
    try:
        return check_names(value, key)
    except ValueError as exc:
        fail(str(exc))


def whole(key: str, value) -> int:
    """``value`` as an int where it is a whole number (not a boolean); else fail with one line naming ``key``."""
    try:
        return check_whole(value, key)
    except ValueError as exc:
        fail(str(exc))


def resolution(value) -> tuple[int, int] | None:
    """``resolution=[width, height]`` as two ints, or ``None`` (each scene's own); else one line."""
    if value is None:
        return None
    if not OmegaConf.is_list(value) or len(value) != 2:
        fail(f"resolution={value}: give [width, height], each >= 8")
    return whole("resolution", value[0]), whole("resolution", value[1])


def check_writable(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        fail(f"output dir {out} is not writable ({exc.strerror}); choose another with out=DIR")


def check_film(out: Path, jobs: list[Job]) -> None:
    """Refuse to render over images of another pixel filter or zoom: they would all be rendered again."""
    for job in jobs:
        for task in job.tasks:
            rec = load_record(out, task, pixel_filter=None, zoom=None)
            if rec is None:
                continue
            checks = (("pixel_filter", rec.pixel_filter, job.pixel_filter), ("zoom", rec.zoom, job.zoom))
            for key, had, wanted in checks:
                if had != wanted:
                    fail(
                        f"{out} holds images rendered with {key}={had}, not {wanted}; "
                        f"pass {key}={had} to resume it, or another out=DIR"
                    )
            return


def render_all(out: Path, jobs: list[Job], backend: str, workers: int, executor: DictConfig) -> None:
    """Run the jobs on the executor ``executor.name`` names (:mod:`data_gen.executors`)."""
    on_done = log_progress(len(jobs))
    if executor.name == "local":
        log.info("executor local: %d worker processes, %d Mitsuba threads each", workers, local_threads(workers))
        run_local(out, jobs, backend, workers, on_done)
    else:
        spec = OmegaConf.to_container(executor, resolve=True)
        render_dask(out, jobs, backend, workers, spec, on_done)


@hydra.main(config_path=CONFIG_DIR, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    out = Path(cfg.out).expanduser().resolve()
    try:
        jobs = plan_dataset(
            scenes=names("scenes", cfg.scenes),
            variants=whole("variants", cfg.variants),
            first_variant=whole("first_variant", cfg.first_variant),
            seed=whole("seed", cfg.seed),
            resolution=resolution(cfg.resolution),
            ladder_top=None if cfg.ladder_top is None else whole("ladder_top", cfg.ladder_top),
            reference_factor=whole("reference_factor", cfg.reference_factor),
            algorithms=None if cfg.algorithms is None else names("algorithms", cfg.algorithms),
            pixel_filter=str(cfg.pixel_filter),
            zoom=cfg.zoom,
        )
    except PlanError as exc:
        fail(str(exc))
    if whole("jobs", cfg.jobs) < 1:
        fail(f"jobs={cfg.jobs}: need at least 1 worker")
    if cfg.executor.name not in EXECUTORS:
        fail(f"executor.name={cfg.executor.name}: choose one of {', '.join(EXECUTORS)} (executor=local|dask)")
    check_writable(out)
    check_film(out, jobs)
    swept = sweep_partials(out)
    if swept:
        log.info("removed %d partial files left by an interrupted run", swept)
    pending = [j for j in jobs if any(load_record(out, t, j.pixel_filter, j.zoom) is None for t in j.tasks)]
    n_images = sum(len(j.tasks) for j in jobs)
    log.info("%s: %d images in %d jobs, %d jobs to do", out, n_images, len(jobs), len(pending))
    start = time.perf_counter()
    if pending:
        try:
            backend = select_backend(str(cfg.backend))
        except (ValueError, RuntimeError) as exc:
            fail(str(exc))
        log.info("backend %s", backend)
        try:
            render_all(out, pending, backend, min(int(cfg.jobs), len(pending)), cfg.executor)
        except ExecutorError as exc:
            fail(str(exc))
        # A worker that died mid-image (the run went on without it) left its temp file behind.
        swept = sweep_partials(out)
        if swept:
            log.info("removed %d partial files left by workers that died", swept)
    records = [load_record(out, t, j.pixel_filter, j.zoom) for j in jobs for t in j.tasks]
    missing = [j.scene for j, r in zip([j for j in jobs for _ in j.tasks], records) if r is None]
    if missing:
        fail(f"{len(missing)} images missing after rendering (scenes {sorted(set(missing))}); rerun to finish them")
    nonfinite = sum(r.nonfinite for r in records)
    meta = {
        "preset": cfg.preset_name,
        "config": OmegaConf.to_container(cfg, resolve=True),
        "wall_seconds": round(time.perf_counter() - start, 2),
    }
    path = write_manifest(out, records, meta)
    log.info(
        "wrote %s: %d images, %d non-finite pixels replaced by 0, %.1f s",
        path,
        len(records),
        nonfinite,
        meta["wall_seconds"],
    )


if __name__ == "__main__":
    main()
