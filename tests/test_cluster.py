"""executor=dask: a LocalCluster renders what the local pool renders; dead workers and clients lose nothing.

The first test reaches its cluster through ``executor.address`` (a running scheduler), the others
let data_gen start its own LocalCluster (no address).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mitsuba")
distributed = pytest.importorskip("distributed", reason="executor=dask needs the extra: pip install 'nriqa[cluster]'")
import dask  # noqa: E402
import psutil  # noqa: E402 (a dependency of distributed)
from conftest import REPO, run_data_gen  # noqa: E402

from data_gen import executors  # noqa: E402
from data_gen.plan import plan_dataset  # noqa: E402
from nriqa.io.exr import read_exr  # noqa: E402
from nriqa.io.manifest import read_manifest  # noqa: E402

TINY = dict(resolution=(32, 32), ladder_top=16)


def planned(scenes: list[str]) -> set[str]:
    return {t.id for j in plan_dataset(scenes, 1, **TINY) for t in j.tasks}


def same_as_tiny(out: Path, tiny: Path, scenes: list[str]) -> None:
    """``out``'s manifest lists the plan's images, each bit-identical to the local pool's (``tiny``)."""
    records, _ = read_manifest(out)
    assert {r.id for r in records} == planned(scenes)
    for r in records:
        assert (out / r.path).read_bytes() == (tiny / r.path).read_bytes(), r.path
    assert not list(out.rglob("*.partial*"))


def start(out: Path, *overrides: str) -> subprocess.Popen:
    args = [sys.executable, "-m", "data_gen", "preset=tiny", f"out={out}", "executor=dask", *overrides]
    return subprocess.Popen(
        args, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )


def wait_for_records(out: Path, n: int, proc: subprocess.Popen, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while len(list(out.rglob("*.exr.json"))) < n:
        assert proc.poll() is None, "the run ended before it could be interrupted"
        assert time.monotonic() < deadline, f"fewer than {n} images after {timeout} s"
        time.sleep(0.05)


def dask_workers(proc: subprocess.Popen) -> list[psutil.Process]:
    """The LocalCluster's worker processes (spawned by the nannies inside the data_gen process)."""
    children = psutil.Process(proc.pid).children(recursive=True)
    return [c for c in children if any("spawn_main" in arg for arg in c.cmdline())]


def test_local_cluster_renders_the_same_dataset_as_the_local_pool(tiny, tmp_path):
    """Through a running scheduler (executor.address): its two workers probe LLVM and set up Mitsuba."""
    scenes = ["cornell", "glossy"]
    with (
        dask.config.set(executors.NO_WORKER_PROFILE),  # as data_gen starts its own workers (executors.py)
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster,
    ):
        address = cluster.scheduler_address
        proc = run_data_gen(
            "preset=tiny",
            f"out={tmp_path}",
            f"scenes=[{','.join(scenes)}]",
            "executor=dask",
            f"executor.address={address}",
        )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"executor dask: {address}" in proc.stdout + proc.stderr
    records, meta = read_manifest(tmp_path)
    pool_records, pool_meta = read_manifest(tiny)
    assert meta["config"]["executor"]["name"] == "dask" and pool_meta["config"]["executor"]["name"] == "local"
    untimed = lambda rs: sorted({**r.to_dict(), "render_seconds": None}.items() for r in rs)  # noqa: E731
    assert untimed(records) == untimed([r for r in pool_records if r.scene in scenes])
    same_as_tiny(tmp_path, tiny, scenes)
    for r in records:
        assert np.array_equal(read_exr(tmp_path / r.path), read_exr(tiny / r.path))


def test_run_survives_a_killed_worker_and_sweeps_its_temp_file(tiny, tmp_path):
    proc = start(tmp_path, "scenes=[cornell]", "jobs=2")
    try:
        wait_for_records(tmp_path, 2, proc)
        workers = dask_workers(proc)
        assert len(workers) == 2, [w.cmdline() for w in workers]
        workers[0].send_signal(signal.SIGKILL)  # both are busy: 3 of the 5 jobs are left
        # What a worker killed while writing an image leaves behind:
        stray = tmp_path / "cornell" / "v000" / ".spp00016_a.dead.partial.exr"
        stray.write_bytes(b"half an image")
        output, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, output[-2000:]
    assert not workers[0].is_running()
    assert not stray.exists()
    same_as_tiny(tmp_path, tiny, ["cornell"])


def test_killed_client_leaves_nothing_half_written_and_a_rerun_completes(tiny, tmp_path):
    proc = start(tmp_path, "scenes=[cornell]", "jobs=2")
    try:
        wait_for_records(tmp_path, 3, proc)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the client and its LocalCluster at once
        proc.wait()
    assert not (tmp_path / "manifest.json").exists()
    done = list(tmp_path.rglob("*.exr.json"))
    assert 3 <= len(done) < len(planned(["cornell"]))
    for rec in done:
        image = tmp_path / json.loads(rec.read_text())["path"]
        assert image.read_bytes() == (tiny / image.relative_to(tmp_path)).read_bytes()
    proc = run_data_gen("preset=tiny", f"out={tmp_path}", "scenes=[cornell]", "executor=dask")
    assert proc.returncode == 0, proc.stderr[-2000:]
    same_as_tiny(tmp_path, tiny, ["cornell"])


# --- errors and cluster configs (no rendering) ---------------------------------------------------


def die(*args) -> None:
    """A task that kills its worker process, as a crash in Mitsuba would."""
    os._exit(3)


def test_workers_that_keep_dying_stop_the_run_with_one_line(tmp_path):
    import dask

    job = plan_dataset(["cornell"], 1, **TINY)[0]
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with distributed.LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
            with distributed.Client(cluster) as client:
                with pytest.raises(executors.ExecutorError) as info:
                    executors.run_dask(client, tmp_path, [job], "scalar_rgb", 1, False, print, task=die)
    message = str(info.value)
    assert "workers kept dying" in message and "rerun to continue" in message and "\n" not in message


def fails(*args) -> None:
    """A task that raises, as a scene Mitsuba cannot load would."""
    raise RuntimeError("[parser.cpp:1718] failed to instantiate bsdf")


def test_a_job_that_raises_on_a_worker_is_one_line_naming_it(tmp_path):
    job = plan_dataset(["cornell"], 1, **TINY)[0]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            with pytest.raises(executors.ExecutorError) as info:
                executors.run_dask(client, tmp_path, [job], "scalar_rgb", 1, False, print, task=fails)
    message = str(info.value)
    assert message.startswith(f"rendering cornell v000 {job.algorithm} failed: RuntimeError: [parser.cpp:1718]")
    assert "rerun the same command to resume" in message and "\n" not in message


def test_unreachable_scheduler_is_one_line(tmp_path):
    proc = run_data_gen(
        "preset=tiny",
        f"out={tmp_path}",
        "scenes=[cornell]",
        "backend=scalar_rgb",
        "executor=dask",
        "executor.address=tcp://127.0.0.1:9",
        "executor.timeout=1",
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "no Dask scheduler answered at tcp://127.0.0.1:9" in lines[0], proc.stderr
    assert not list(tmp_path.rglob("*.exr*"))


def test_without_dask_the_error_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(executors.ExecutorError, match=r"pip install 'nriqa\[cluster\]'"):
        executors.render_dask(tmp_path, [], "scalar_rgb", 1, {"address": None, "cluster": {}}, print)


def test_worker_without_llvm_refuses_the_llvm_variant(monkeypatch):
    monkeypatch.setattr(executors, "_WORKER_SETUP", None)
    monkeypatch.setattr(executors, "probe_variant", lambda variant: (False, "LLVM probe failed (abort)"))
    monkeypatch.setattr(executors, "init_worker", lambda *a: pytest.fail("Mitsuba set up despite a failed probe"))
    with pytest.raises(executors.ExecutorError, match="backend llvm_ad_rgb unusable on worker .*backend=scalar_rgb"):
        executors.render_on_worker("unused", None, "llvm_ad_rgb", threads=1, verify=True)


@pytest.mark.parametrize(("preset", "directive"), [("slurm", "#SBATCH"), ("pbs", "#PBS")])
def test_batch_queue_presets_build_a_job_script(preset, directive):
    pytest.importorskip("dask_jobqueue", reason="executor=slurm|pbs needs dask-jobqueue (the cluster extra)")
    import hydra
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(REPO / "data_gen" / "configs"), version_base="1.3"):
        cfg = compose("config", overrides=[f"executor={preset}", "executor.cluster.n_workers=0"])
    assert cfg.executor.name == "dask" and cfg.executor.address is None
    cluster = hydra.utils.instantiate(cfg.executor.cluster, _convert_="all")  # submits nothing with 0 workers
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    assert directive in script and cluster.scheduler_address.split(":")[-1] in script
    processes = cfg.executor.cluster.processes
    threads = cfg.executor.cluster.cores // processes
    assert f"--nworkers {processes}" in script and f"--nthreads {threads}" in script
