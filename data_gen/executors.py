"""Where render jobs run: a local process pool (``executor=local``) or a Dask cluster (``executor=dask``).

Both call :func:`data_gen.render.run_job` once per job, in a process whose Mitsuba was set up once
(:func:`nriqa.render.backend.init_worker`: LLVM path, variant, thread count). A job writes each image
and then its record atomically, so whatever dies (a worker, the client) a rerun skips the finished
images; the temp files of a dead writer are swept by the caller (:func:`nriqa.io.atomic.sweep_partials`).

The Dask engine (``pip install 'nriqa[cluster]'``) runs on a ``LocalCluster``, an existing scheduler
(``address``), or any cluster class Hydra can build (``dask_jobqueue.SLURMCluster``, ``PBSCluster``);
docs/cluster.md says how.
"""

from __future__ import annotations

import concurrent.futures as cf
import gc
import logging
import multiprocessing
import os
import threading
from collections.abc import Callable, Mapping
from pathlib import Path

from data_gen.plan import Job
from data_gen.render import run_job
from nriqa.errors import NriqaError
from nriqa.render.backend import PROBED_VARIANTS, init_worker, llvm_env, probe_variant, unusable

log = logging.getLogger("data_gen")

EXECUTORS = ("local", "dask")
CLUSTER_EXTRA = "pip install 'nriqa[cluster]'"

# What a finished job reports: (job, images rendered, images already done).
OnDone = Callable[[Job, int, int], None]


class ExecutorError(NriqaError):
    """An executor that cannot run (engine missing, scheduler unreachable, workers dying); one line."""


def local_threads(workers: int) -> int:
    """Mitsuba threads per worker when ``workers`` share this machine: cores // workers, at least 1."""
    return max(1, (os.cpu_count() or 1) // workers)


def log_progress(total: int) -> OnDone:
    """An :data:`OnDone` that logs ``[done/total] scene vNNN algorithm: n rendered, m already done``."""
    count = 0

    def on_done(job: Job, rendered: int, skipped: int) -> None:
        nonlocal count
        count += 1
        what = "reference" if job.tasks[0].role == "reference" else job.algorithm
        log.info(
            "[%d/%d] %s v%03d %s: %d rendered, %d already done",
            count,
            total,
            job.scene,
            job.variant,
            what,
            rendered,
            skipped,
        )

    return on_done


def run_local(out: Path, jobs: list[Job], backend: str, workers: int, on_done: OnDone) -> None:
    """Run the jobs in a process pool of ``workers``; each worker's Mitsuba gets cores // workers threads."""
    ctx = multiprocessing.get_context("spawn")  # no fork after Dr.Jit has started threads
    args = (backend, local_threads(workers))
    with cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=init_worker, initargs=args) as pool:
        futures = {pool.submit(run_job, str(out), job, backend): job for job in jobs}
        collect(futures, on_done)


def job_failed(job: Job, exc: BaseException) -> ExecutorError:
    """One line for a job that raised inside its worker (a scene that does not build or load, an error of
    Mitsuba's): the job, the error's first line, and that a rerun resumes."""
    first = next((line.strip() for line in str(exc).splitlines() if line.strip()), "")
    return ExecutorError(
        f"rendering {job.scene} v{job.variant:03d} {job.algorithm} failed: {type(exc).__name__}"
        f"{': ' + first if first else ''}; finished images are kept, so rerun the same command to resume"
    )


def collect(futures: Mapping[cf.Future, Job], on_done: OnDone) -> None:
    """Report each job as it finishes; a worker that died takes the pool with it: one line naming a job it held;
    a job that raised: one line naming it (:func:`job_failed`)."""
    for fut in cf.as_completed(futures):
        try:
            result = fut.result()
        except cf.process.BrokenProcessPool:
            job = futures[fut]
            raise ExecutorError(
                f"a render worker died abruptly (a crash inside Mitsuba, or killed, e.g. out of memory) with "
                f"{job.scene} v{job.variant:03d} {job.algorithm} or a job beside it in flight; finished images are "
                "kept, so rerun the same command to resume; if it dies again there, try backend=scalar_rgb or jobs=1"
            ) from None
        except NriqaError:
            raise  # already one line for the user
        except Exception as exc:
            raise job_failed(futures[fut], exc) from None
        on_done(futures[fut], *result)


# --- Dask ---------------------------------------------------------------------------------------

# Per worker process: Mitsuba is set up by the first job and not driven from two threads at once
# (its maintainers support processes, not threads, for parallel renders), so a worker with several
# Dask threads still renders one job at a time.
_WORKER_LOCK = threading.Lock()
_WORKER_SETUP: tuple[str, int] | None = None


def _setup_worker(backend: str, threads: int | None, verify: bool) -> None:
    """Set up this worker's Mitsuba once per (variant, threads); ``threads=None`` takes the Dask worker's
    own thread count. A long-lived worker serving a later run with other settings is set up again."""
    global _WORKER_SETUP
    if threads is None:
        from distributed import get_worker

        threads = get_worker().state.nthreads
    if _WORKER_SETUP == (backend, threads):
        return
    if verify and backend in PROBED_VARIANTS:
        # The client probed its own machine; a worker elsewhere may lack LLVM (which would abort it) or a GPU.
        ok, reason = probe_variant(backend)
        if not ok:
            raise ExecutorError(unusable(backend, reason, f" on worker {os.uname().nodename}"))
    init_worker(backend, threads)
    _WORKER_SETUP = (backend, threads)


def render_on_worker(root: str, job: Job, backend: str, threads: int | None, verify: bool) -> tuple[int, int]:
    """The Dask task of one job: set up Mitsuba (first time only), then :func:`run_job`.

    The cyclic garbage collector is held off while the job renders and run at its end, in this thread: a
    Dask worker's event loop runs in another thread of the process, and a collection there that freed the
    previous job's scene took Dr.Jit's lock while holding the GIL, as the render thread held Dr.Jit's lock
    and waited for the GIL -- the worker hung for good (stop 42: the local-cluster test hung in 2 of 13 runs).
    """
    with _WORKER_LOCK:
        _setup_worker(backend, threads, verify)
        gc.disable()
        try:
            return run_job(root, job, backend)
        finally:
            gc.collect()  # this job's Mitsuba objects die here, while no render holds Dr.Jit's lock
            gc.enable()


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise ExecutorError(f"executor=dask needs Dask's distributed scheduler: {CLUSTER_EXTRA}") from None
    return distributed


# Dask's statistical profiler samples each worker's threads every 10 ms, holding the GIL; once (stop 70, the
# cluster test in CI) a worker's main thread sat in it at 100 % for ten minutes while the Mitsuba render on the
# worker's task thread waited. Workers this package starts do not profile; a scheduler of your own can be started
# with the same setting (DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False).
NO_WORKER_PROFILE = {"distributed.worker.profile.enabled": False}


def start_cluster(spec: Mapping):
    """Build the cluster ``spec`` names (``{"_target_": "distributed.LocalCluster", **kwargs}``)."""
    import hydra

    _import_distributed()
    import dask

    os.environ.update(llvm_env())  # workers spawned on this machine inherit the LLVM path
    try:
        with dask.config.set(NO_WORKER_PROFILE):  # the nannies hand the workers this config
            return hydra.utils.instantiate(dict(spec), _convert_="all")
    except Exception as exc:  # hydra wraps ImportError / TypeError / OSError in InstantiationException
        cause = exc.__cause__ or exc
        raise ExecutorError(
            f"cannot start the cluster {spec.get('_target_')}: {cause}; "
            f"check executor.cluster (and {CLUSTER_EXTRA} for dask-jobqueue)"
        ) from None


def connect(address: str | None, cluster, timeout: float):
    """A ``distributed.Client`` on ``address`` or on ``cluster``; ExecutorError if none answers."""
    distributed = _import_distributed()
    try:
        return distributed.Client(address or cluster, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        where = address or getattr(cluster, "scheduler_address", cluster)
        raise ExecutorError(
            f"no Dask scheduler answered at {where} within {timeout:g} s ({exc}); "
            "start one (dask scheduler) or leave executor.address unset for a LocalCluster"
        ) from None


def run_dask(
    client,
    out: Path,
    jobs: list[Job],
    backend: str,
    threads: int | None,
    verify: bool,
    on_done: OnDone,
    task: Callable = render_on_worker,
) -> None:
    """Submit ``task`` (:func:`render_on_worker`) for every job to ``client``'s cluster, longest first,
    and report each job as it finishes.

    A job whose worker died is rerun by Dask on another worker (finished images are skipped); after
    the scheduler's allowed failures the run stops with an ExecutorError and a rerun continues it.
    """
    distributed = _import_distributed()
    futures = {}
    for rank, job in enumerate(jobs):
        fut = client.submit(task, str(out), job, backend, threads, verify, priority=len(jobs) - rank, pure=False)
        futures[fut] = job
    # Leaving early (an error, Ctrl-C) releases the futures: the scheduler drops the jobs not started.
    try:
        for fut in distributed.as_completed(futures):
            try:
                result = fut.result()
            except (distributed.KilledWorker, NriqaError):
                raise
            except Exception as exc:
                raise job_failed(futures[fut], exc) from None
            on_done(futures[fut], *result)
    except distributed.KilledWorker as exc:
        raise ExecutorError(
            f"Dask workers kept dying on a job ({exc}); finished images are kept, rerun to continue"
        ) from None


def render_dask(out: Path, jobs: list[Job], backend: str, workers: int, cfg: Mapping, on_done: OnDone) -> None:
    """Render on Dask as ``cfg`` (the ``executor`` config) says: ``address`` of a running scheduler,
    else a cluster started from ``cfg["cluster"]`` for this run (by default a LocalCluster of ``jobs``
    worker processes of one Dask thread each) and closed at the end.

    Mitsuba threads per worker: ``cfg["threads"]``, else cores // ``workers`` on a LocalCluster (as
    the local pool splits this machine) and each worker's own Dask thread count elsewhere.
    """
    address, threads = cfg.get("address"), cfg.get("threads")
    timeout = float(cfg.get("timeout") or 30)
    distributed = _import_distributed()
    # Dask logs every connection and key at INFO (set when it is imported); its warnings stay.
    logging.getLogger("distributed").setLevel(logging.WARNING)
    cluster = None if address else start_cluster(cfg["cluster"])
    try:
        on_this_machine = isinstance(cluster, distributed.LocalCluster)
        if threads is None and on_this_machine:
            threads = local_threads(workers)
        client = connect(address, cluster, timeout)
        with client:
            where = address or f"{type(cluster).__name__} at {cluster.scheduler_address}"
            log.info(
                "executor dask: %s, %d workers now, Mitsuba threads per worker: %s",
                where,
                len(client.nthreads()),
                threads or "the worker's nthreads",
            )
            run_dask(client, out, jobs, backend, threads, verify=not on_this_machine, on_done=on_done)
    finally:
        if cluster is not None:
            cluster.close()
