"""scripts/gpu/loso.sh, the leave-one-scene-out script for a lent GPU machine, run on the CPU: folds, their
evaluation by the folds that held each scene out, and the packed runs."""

import os
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "gpu" / "loso.sh"


def run_script(tmp_path: Path, data: Path, **env: str) -> subprocess.CompletedProcess:
    settings = {
        "OUT": str(tmp_path / "out"),
        "WORK": str(tmp_path / "work"),
        "DATA": str(data),
        "PY": sys.executable,
        "TRAINER": "cpu",
        "DEVICE": "cpu",
        "EPOCHS": "1",
        "SCENES": "alpha beta",
        "EXTRA": "schedule.map.batches_per_epoch=2 schedule.map.val_patches=8 crossval.eval_patches=8",
        **env,
    }
    return subprocess.run(
        ["bash", str(SCRIPT)], cwd=ROOT, env={**os.environ, **settings}, capture_output=True, text=True, timeout=600
    )


def test_every_fold_trains_and_each_scene_is_scored_by_its_own_fold(tmp_path, synthetic_dataset):
    proc = run_script(tmp_path, synthetic_dataset, PARALLEL="1")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "fold alpha rc=0" in log and "fold beta rc=0" in log and "evaluate rc=0" in log
    assert "all-cv" in log and "scenes: alpha, beta" in log  # the evaluation's table, in the log
    # the machine's cores, not nproc's answer to the OMP_NUM_THREADS=1 the script sets for its folds (which gave
    # a stacked run one loader process)
    assert f" {len(os.sched_getaffinity(0))} cores" in log.splitlines()[0]
    with tarfile.open(tmp_path / "out" / "loso_runs.tgz") as tar:
        names = tar.getnames()
        table = tar.extractfile("eval/comparison.md").read().decode()
    assert "all-cv" in table and "scenes: alpha, beta" in table
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["loso.log", "loso_runs.tgz"]
    assert any(n.endswith("alpha/checkpoints/last.ckpt") for n in names)
    assert any(n.endswith("beta/checkpoints/last.ckpt") for n in names)
    assert not any(n.endswith(".ckpt") and "last" not in n for n in names)


def test_a_missing_dataset_stops_before_any_fold(tmp_path):
    proc = run_script(tmp_path, tmp_path / "nothing")
    assert proc.returncode == 2
    assert "no dataset at" in proc.stdout and "carry one or render it first" in proc.stdout
    assert not (tmp_path / "work").exists()


def test_a_fold_that_fails_early_with_patches_on_the_accelerator_runs_again_on_the_cpu(tmp_path, synthetic_dataset):
    # This machine has no CUDA device, so data.device=cuda fails at the fold's start, as a broken
    # accelerator path would on the lent machine.
    proc = run_script(tmp_path, synthetic_dataset, PARALLEL="1", DEVICE="cuda")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "fold alpha failed with data.device=cuda" in log and "again with patches on the CPU" in log
    assert "fold alpha rc=0" in log and "fold beta rc=0" in log and "evaluate rc=0" in log
    assert "steps" in log


def test_a_fold_that_fails_late_is_not_run_again(tmp_path, synthetic_dataset):
    run_script(tmp_path, synthetic_dataset, DEVICE="cuda", RETRY_WITHIN="0", SCENES="alpha")
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "fold alpha rc=1" in log and "again with patches on the CPU" not in log
    assert "fold alpha left no run" in log


def test_stacked_trains_every_fold_in_one_process_and_packs_no_state(tmp_path, synthetic_dataset):
    proc = run_script(tmp_path, synthetic_dataset, STACKED="1", WORKERS="1", BENCH="cpu")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "stacked rc=0 stacked: epoch 0 done, step 2" in log and "evaluate rc=0" in log
    assert "2 folds stacked (one vmapped unet_fast)" in log  # BENCH: the step benchmark's table first
    assert "fold alpha: val PCC" in log and "fold beta: val PCC" in log and "fold alpha rc=" not in log
    assert "all-cv" in log and "scenes: alpha, beta" in log
    with tarfile.open(tmp_path / "out" / "loso_runs.tgz") as tar:
        names = tar.getnames()
    assert any(n.endswith("stacked/folds/alpha/checkpoints/last.ckpt") for n in names)
    assert any(n.endswith("stacked/folds/beta/checkpoints/last.ckpt") for n in names)
    assert not any(n.endswith("stacked_state.pt") for n in names)


def test_a_stacked_step_that_fails_its_benchmark_leaves_the_folds_to_processes(tmp_path, synthetic_dataset):
    proc = run_script(tmp_path, synthetic_dataset, STACKED="1", WORKERS="1", BENCH="no_such_device", PARALLEL="2")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "the stacked step failed on no_such_device" in log and "stacked rc=" not in log
    assert "fold alpha rc=0" in log and "fold beta rc=0" in log and "evaluate rc=0" in log
    with tarfile.open(tmp_path / "out" / "loso_runs.tgz") as tar:
        names = tar.getnames()
    assert any(n.endswith("cv/alpha/folds/alpha/checkpoints/last.ckpt") for n in names)
    assert "logs/bench.txt" in names


def test_a_stacked_run_that_fails_early_leaves_the_folds_to_processes(tmp_path, synthetic_dataset):
    # gradient clipping is refused by the stacked path and allowed for a run of its own
    extra = "schedule.map.batches_per_epoch=2 schedule.map.val_patches=8 crossval.eval_patches=8"
    proc = run_script(
        tmp_path,
        synthetic_dataset,
        STACKED="1",
        WORKERS="1",
        PARALLEL="2",
        EXTRA=f"{extra} +trainer.gradient_clip_val=1.0",
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "stacked failed early" in log and "gradient" in log.split("stacked failed early")[1].splitlines()[0]
    assert "fold alpha rc=0" in log and "fold beta rc=0" in log and "evaluate rc=0" in log


def test_render_makes_the_slice_first_and_packs_its_logs(tmp_path):
    pytest.importorskip("mitsuba")
    settings = dict(
        RENDER="1", BACKEND="scalar_rgb", JOBS="1", RES="64", TOP="2", STAGES="1", RENDER_SCENES="[cornell,door]"
    )
    proc = run_script(tmp_path, tmp_path / "slice", STACKED="1", WORKERS="0", SCENES="", **settings)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    log = (tmp_path / "out" / "loso.log").read_text()
    assert "render rc=0" in log and "stage variants=1 rc=0" in log and "dataset: 1 variants" in log
    assert "fold cornell: val PCC" in log and "fold door: val PCC" in log and "evaluate rc=0" in log
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["loso.log", "loso_runs.tgz"]
    with tarfile.open(tmp_path / "out" / "loso_runs.tgz") as tar:
        names = tar.getnames()
    assert "render/device.log" in names and "render/manifest.json" in names


def test_editing_the_script_during_a_run_leaves_that_run_as_it_was(tmp_path):
    # bash reads a script as it goes; one written over in place mid-run would run the new text from the old offset.
    # The first call of PY (the package check, which passes) writes over the copy the run reads, as an editor saving
    # it would; later calls fail, as a fold with no package would.
    script = tmp_path / "loso.sh"
    script.write_bytes(SCRIPT.read_bytes())
    fake = tmp_path / "python"
    fake.write_text(
        "#!/usr/bin/env bash\n"
        f'if [ ! -f "{tmp_path}/edited" ]; then touch "{tmp_path}/edited"\n'
        f'  printf "%0{len(SCRIPT.read_bytes())}d\\necho EDITED; exit 99\\n" 0 | tr 0 "#" > "{script}"; exit 0; fi\n'
        "exit 1\n"
    )
    fake.chmod(0o755)
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "manifest.json").write_text("{}")
    settings = {"OUT": str(tmp_path / "out"), "WORK": str(tmp_path / "work"), "DATA": str(tmp_path / "data")}
    proc = subprocess.run(
        ["bash", str(script)],
        cwd=ROOT,
        env={**os.environ, **settings, "PY": str(fake), "SCENES": "alpha"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert (tmp_path / "edited").exists() and "EDITED" in script.read_text()
    assert "EDITED" not in proc.stdout and proc.returncode == 0, proc.stdout[-2000:]
    assert "fold alpha rc=1" in proc.stdout and "evaluate rc=1" in proc.stdout  # the run went on to its end
