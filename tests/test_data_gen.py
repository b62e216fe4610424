"""data_gen: planning, backend fallback, rendering the tiny preset, resume after kill, convergence."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from conftest import REPO, run_data_gen

from data_gen.algorithms import ALGORITHMS, get_algorithm
from data_gen.convergence import block_inflation, convergence, dataset_verdicts, pixel_variance, top_rungs
from data_gen.plan import MIN_REFERENCE_FACTOR, PlanError, ladder, plan_dataset
from data_gen.render import sanitize
from data_gen.scenes import get_scene, list_scenes
from nriqa.io.exr import read_exr
from nriqa.io.manifest import read_manifest
from nriqa.render import backend

# --- planning -------------------------------------------------------------------------------


def test_at_least_eight_scene_families_each_with_a_converging_reference():
    scenes = list_scenes()
    assert len(scenes) >= 8
    for name in scenes:
        spec = get_scene(name)
        assert spec.algorithms, name
        assert all(a in ALGORITHMS for a in spec.algorithms)
        assert spec.reference_algorithm.endswith("_independent")
        assert ("volpath" in spec.reference_algorithm) == spec.medium


def test_only_the_medium_scene_uses_the_volumetric_integrator():
    for name in list_scenes():
        spec = get_scene(name)
        uses_volpath = any(get_algorithm(a).integrator == "volpath" for a in spec.algorithms)
        assert uses_volpath == spec.medium, name


def test_plan_ladder_twins_and_seeds():
    jobs = plan_dataset(["cornell", "caustic"], variants=2, seed=7, resolution=(16, 16), ladder_top=8)
    tasks = [t for j in jobs for t in j.tasks]
    assert len({t.seed for t in tasks}) == len(tasks), "every image has its own seed"
    assert len({t.path for t in tasks}) == len(tasks)
    by_id = {t.id: t for t in tasks}
    for t in tasks:
        if t.role == "reference":
            assert t.spp == 8 * MIN_REFERENCE_FACTOR
            continue
        twin = by_id[t.twin]
        assert twin.twin == t.id and twin.spp == t.spp and twin.seed != t.seed
        assert {t.role, twin.role} == {"test", "twin"}
        assert t.spp in (2, 4, 8)
    assert plan_dataset(["cornell"], variants=1, seed=7, ladder_top=8) == plan_dataset(
        ["cornell"], variants=1, seed=7, ladder_top=8
    )


def test_first_variant_plans_the_same_images_a_full_run_gives_those_variants():
    full = plan_dataset(["cornell", "dim_interior"], variants=4, seed=3, resolution=(16, 16), ladder_top=8)
    tail = plan_dataset(
        ["cornell", "dim_interior"], variants=4, seed=3, resolution=(16, 16), ladder_top=8, first_variant=2
    )
    assert {j.variant for j in tail} == {2, 3}
    assert sorted(tail, key=repr) == sorted([j for j in full if j.variant >= 2], key=repr)


def test_square_samplers_take_only_powers_of_four():
    jobs = plan_dataset(["cornell"], variants=1, ladder_top=64)
    spps = {j.algorithm: sorted({t.spp for t in j.tasks}) for j in jobs}
    assert spps["path_independent"] == [2, 4, 8, 16, 32, 64]
    assert spps["path_ldsampler"] == [4, 16, 64]
    assert spps["path_multijitter"] == [4, 16, 64]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scenes": ["nowhere"]}, "unknown scene 'nowhere'"),
        ({"ladder_top": 48}, "not a power of two"),
        ({"ladder_top": 1}, "not a power of two"),
        ({"reference_factor": 8}, ">= 16x"),
        ({"variants": 0}, "at least 1 variant"),
        ({"variants": 2, "first_variant": 2}, "0 <= first_variant < variants"),
        ({"first_variant": -1}, "0 <= first_variant < variants"),
        ({"algorithms": ["path_magic"]}, "unknown algorithm"),
        ({"pixel_filter": "gauss"}, "pixel_filter=gauss: choose one of box, tent, gaussian"),
        ({"zoom": 0}, "zoom=0: give a whole number >= 1"),
        ({"zoom": 1.5}, "zoom=1.5: give a whole number >= 1"),
    ],
)
def test_plan_rejects_bad_configuration(kwargs, message):
    args = {"scenes": ["cornell"], "variants": 1, **kwargs}
    with pytest.raises(PlanError, match=message):
        plan_dataset(**args)


def test_ladder():
    assert ladder(2) == [2]
    assert ladder(16) == [2, 4, 8, 16]


# --- command line errors ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("scenes=[nowhere]", "unknown scene"),
        ("ladder_top=12", "not a power of two"),
        ("reference_factor=4", ">= 16x"),
        ("first_variant=1", "first_variant=1 with variants=1"),
        # the wrong type of value: one line naming the key, not a traceback
        ("resolution=5", "resolution=5: give [width, height], each >= 8"),
        ("resolution=[64,wide]", "resolution=wide: give a whole number"),
        ("ladder_top=abc", "ladder_top=abc: give a whole number"),
        ("variants=2.5", "variants=2.5: give a whole number"),
        ("seed=true", "seed=True: give a whole number"),
        ("scenes=5", "scenes=5: give a list of names"),
        ("jobs=many", "jobs=many: give a whole number"),
        ("zoom=abc", "zoom=abc: give a whole number >= 1"),
    ],
)
def test_cli_bad_configuration_is_one_line(tmp_path, override, message):
    proc = run_data_gen("preset=tiny", f"out={tmp_path}", override)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_cli_unwritable_out_nonroot(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    proc = run_data_gen("preset=tiny", f"out={locked / 'x'}")
    assert proc.returncode == 2 and "not writable" in proc.stderr


def test_cli_unwritable_out(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    proc = run_data_gen("preset=tiny", f"out={blocker / 'data'}")
    assert proc.returncode == 2
    assert "not writable" in proc.stderr and "Traceback" not in proc.stderr


# --- backend ------------------------------------------------------------------------------------


def test_backend_falls_back_to_scalar_with_one_warning(monkeypatch, caplog):
    monkeypatch.setattr(backend, "probe_variant", lambda variant: (False, f"{variant} probe failed (abort)"))
    with caplog.at_level("WARNING"):
        assert backend.select_backend("auto") == backend.SCALAR_VARIANT
    assert len(caplog.records) == 1 and "falling back" in caplog.text
    with pytest.raises(RuntimeError, match="unusable"):
        backend.select_backend(backend.LLVM_VARIANT)
    assert backend.select_backend(backend.SCALAR_VARIANT) == backend.SCALAR_VARIANT
    with pytest.raises(ValueError, match="unknown backend"):
        backend.select_backend("cuda")


def test_cuda_backend_is_probed_and_refused_with_one_line_without_a_gpu(monkeypatch):
    asked = []
    monkeypatch.setattr(backend, "probe_variant", lambda variant: asked.append(variant) or (False, "no GPU"))
    with pytest.raises(RuntimeError, match="backend cuda_ad_rgb unusable: no GPU; it needs an NVIDIA GPU"):
        backend.select_backend(backend.CUDA_VARIANT)
    assert asked == [backend.CUDA_VARIANT]
    monkeypatch.setattr(backend, "probe_variant", lambda variant: (True, "ok"))
    assert backend.select_backend(backend.CUDA_VARIANT) == backend.CUDA_VARIANT
    assert backend.select_backend("auto") == backend.LLVM_VARIANT  # auto never picks the GPU


def test_data_gen_cuda_backend_on_a_cpu_machine_is_one_line(tmp_path):
    proc = run_data_gen("preset=tiny", "scenes=[cornell]", "backend=cuda_ad_rgb", f"out={tmp_path / 'd'}")
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert "backend cuda_ad_rgb unusable" in proc.stderr and len(proc.stderr.strip().splitlines()) <= 2


def test_llvm_probe_survives_a_broken_libllvm(monkeypatch):
    """A bad libLLVM may abort the interpreter; the probe runs in a subprocess, so we live on."""
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "/nonexistent/libLLVM.so")
    ok, reason = backend.probe_llvm(timeout=60)
    assert not ok and "llvm_ad_rgb probe" in reason


def test_a_local_worker_that_dies_stops_the_run_with_one_line():
    import concurrent.futures as cf

    from data_gen.executors import ExecutorError, collect

    job = plan_dataset(["cornell"], 1, resolution=(32, 32), ladder_top=16)[0]
    done = []
    with cf.ProcessPoolExecutor(1) as pool:
        futures = {pool.submit(os._exit, 3): job}  # the worker dies, as a crash in Mitsuba kills it
        with pytest.raises(ExecutorError) as info:
            collect(futures, lambda *a: done.append(a))
    message = str(info.value)
    assert f"cornell v000 {job.algorithm}" in message and "rerun the same command to resume" in message
    assert "\n" not in message and not done


def _raise_in_worker(message: str, user_facing: bool = False):
    from data_gen.executors import ExecutorError

    raise (ExecutorError if user_facing else RuntimeError)(message)


def test_a_job_that_raises_in_its_worker_stops_the_run_with_one_line():
    """A scene that fails to load in Mitsuba (here: any exception of a job) is one line naming the job."""
    import concurrent.futures as cf

    from data_gen.executors import ExecutorError, collect

    job = plan_dataset(["cornell"], 1, resolution=(32, 32), ladder_top=16)[0]
    done = []
    with cf.ProcessPoolExecutor(1) as pool:
        futures = {pool.submit(_raise_in_worker, "[parser.cpp:1718] failed to instantiate bsdf\nmore detail"): job}
        with pytest.raises(ExecutorError) as info:
            collect(futures, lambda *a: done.append(a))
    message = str(info.value)
    assert message.startswith(f"rendering cornell v000 {job.algorithm} failed: RuntimeError: [parser.cpp:1718]")
    assert "rerun the same command to resume" in message and "\n" not in message and not done
    with cf.ProcessPoolExecutor(1) as pool:
        futures = {pool.submit(_raise_in_worker, "backend llvm_ad_rgb unusable", True): job}
        with pytest.raises(ExecutorError, match="^backend llvm_ad_rgb unusable$"):
            collect(futures, lambda *a: done.append(a))  # already one line for the user: kept as it is


def test_sanitize_counts_and_zeroes_nonfinite_pixels():
    img = np.ones((4, 5, 3), dtype=np.float32)
    img[0, 0, 0] = np.nan
    img[1, 2, :] = np.inf
    img[3, 4, 2] = -np.inf
    out, count = sanitize(img)
    assert count == 3
    assert np.isfinite(out).all() and out[0, 0, 0] == 0 and out[2, 2, 1] == 1


# --- the tiny preset ----------------------------------------------------------------------------


def test_tiny_dataset_is_complete_and_valid(tiny):
    records, meta = read_manifest(tiny)
    assert meta["preset"] == "tiny"
    assert {r.scene for r in records} == set(list_scenes())
    by_id = {r.id: r for r in records}
    refs = {r.path: r for r in records if r.role == "reference"}
    for r in records:
        assert (tiny / r.path).is_file()
        assert r.reference in refs
        assert r.backend in (backend.LLVM_VARIANT, backend.SCALAR_VARIANT)
        assert r.render_seconds > 0 and (r.width, r.height) == (32, 32)
        if r.role != "reference":
            assert by_id[r.twin].spp == r.spp and by_id[r.twin].seed != r.seed
            assert refs[r.reference].spp >= MIN_REFERENCE_FACTOR * 16
    assert not list(tiny.rglob("*.partial*"))
    img = read_exr(tiny / records[0].path)
    assert img.dtype == np.float32 and img.shape == (32, 32, 3) and np.isfinite(img).all()


def test_rerun_skips_finished_images(tiny):
    before = {p: p.stat().st_mtime_ns for p in tiny.rglob("*.exr")}
    proc = run_data_gen("preset=tiny", f"out={tiny}")
    assert proc.returncode == 0, proc.stderr
    assert "0 jobs to do" in proc.stdout + proc.stderr
    assert {p: p.stat().st_mtime_ns for p in tiny.rglob("*.exr")} == before


def test_every_declared_algorithm_converges_to_its_reference(tiny):
    records, _ = read_manifest(tiny)
    verdicts = dataset_verdicts(tiny, records)
    failing = [v for v in verdicts if not v["converged"]]
    assert not failing, failing
    declared = {(s, a) for s in list_scenes() for a in get_scene(s).algorithms}
    assert {(v["scene"], v["algorithm"]) for v in verdicts} == declared


@pytest.mark.parametrize(("scene", "algorithm"), [("caustic", "ptracer_independent"), ("medium", "path_independent")])
def test_convergence_check_rejects_a_biased_algorithm(tiny, tmp_path, scene, algorithm):
    """Negative controls: particle tracing cannot see glass; a surface path tracer ignores fog."""
    import pickle

    from data_gen.plan import ImageTask, Job, derive_seed

    out = tmp_path / "biased"
    spec = get_scene(scene)
    # The same variant as the tiny preset's (seed 0, variant 0), with an algorithm it does not declare.
    tasks = tuple(ImageTask(f"x/{k}", "test", 16, 100 + k, f"x/{k}.exr", "ref.exr") for k in range(2))
    job = Job(scene, 0, derive_seed(0, scene, 0), algorithm, (32, 32), spec.max_depth, tasks)
    code = (
        "import sys, pickle; from pathlib import Path\n"
        "from nriqa.render.backend import init_worker, select_backend\n"
        "v = select_backend('auto'); init_worker(v, 2)\n"
        "from data_gen.render import run_job\n"
        "run_job(sys.argv[2], pickle.loads(bytes.fromhex(sys.argv[1])), v)\n"
    )
    subprocess.run(
        [sys.executable, "-c", code, pickle.dumps(job).hex(), str(out)], cwd=REPO, check=True, capture_output=True
    )
    records, _ = read_manifest(tiny)
    ref = next(r for r in records if r.scene == scene and r.role == "reference")
    ind = top_rungs(records)[(scene, 0, ref.algorithm)]
    ref_var = (
        pixel_variance(read_exr(tiny / ind.path), read_exr(tiny / ind.path.replace("_a.exr", "_b.exr")))
        * ind.spp
        / ref.spp
    )
    result = convergence(read_exr(out / "x/0.exr"), read_exr(out / "x/1.exr"), read_exr(tiny / ref.path), ref_var)
    assert not result.converged, result


def test_same_seed_same_images(tiny, tmp_path):
    proc = run_data_gen("preset=tiny", f"out={tmp_path}", "scenes=[cornell]", "algorithms=[path_independent]", "jobs=1")
    assert proc.returncode == 0, proc.stderr
    records, _ = read_manifest(tmp_path)
    for r in records:
        np.testing.assert_array_equal(read_exr(tmp_path / r.path), read_exr(tiny / r.path))


def test_killed_run_resumes_to_a_complete_uncorrupted_dataset(tiny, tmp_path):
    out = tmp_path / "killed"
    args = [sys.executable, "-m", "data_gen", "preset=tiny", f"out={out}", "scenes=[cornell,glossy]", "jobs=2"]
    proc = subprocess.Popen(
        args, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(out.rglob("*.exr.json"))) < 5:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "manifest.json").exists(), "killed before the end: no manifest yet"
    for exr in out.rglob("*.exr"):
        if ".partial" not in exr.name:
            read_exr(exr)  # every completed file is whole
    proc = run_data_gen("preset=tiny", f"out={out}", "scenes=[cornell,glossy]")
    assert proc.returncode == 0, proc.stderr
    records, _ = read_manifest(out)
    assert len(records) == len(
        [t for j in plan_dataset(["cornell", "glossy"], 1, resolution=(32, 32), ladder_top=16) for t in j.tasks]
    )
    assert not list(out.rglob("*.partial*"))
    for r in records:
        np.testing.assert_array_equal(read_exr(out / r.path), read_exr(tiny / r.path))


def test_report_writes_plots_and_numbers(tiny, tmp_path):
    from data_gen.report import main as report_main

    assert report_main([str(tiny), "--out", str(tmp_path)]) == 0
    for scene in list_scenes():
        assert (tmp_path / f"{scene}_error.png").stat().st_size > 1000
        assert (tmp_path / f"{scene}_contact.png").stat().st_size > 1000
    rows = (tmp_path / "convergence.csv").read_text().splitlines()
    assert rows[0] == "scene,algorithm,spp,images,seconds,mse,one_minus_ssim"
    mse = {
        int(line.split(",")[2]): float(line.split(",")[5])
        for line in rows[1:]
        if line.startswith("cornell,path_independent,")
    }
    assert mse[16] < mse[2], "error falls with samples"
    assert "False" not in (tmp_path / "verdicts.csv").read_text()


def test_report_without_manifest_is_one_line(tmp_path, capsys):
    from data_gen.report import main as report_main

    assert report_main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no manifest" in err[0]


def test_stale_record_is_rendered_again(tiny, tmp_path):
    import json
    import shutil

    out = tmp_path / "stale"
    shutil.copytree(tiny / "cornell", out / "cornell")
    rec_file = out / "cornell/v000/reference.exr.json"
    body = json.loads(rec_file.read_text())
    body["spp"] = 4096
    rec_file.write_text(json.dumps(body))
    proc = run_data_gen("preset=tiny", f"out={out}", "scenes=[cornell]")
    assert proc.returncode == 0, proc.stderr
    assert "1 jobs to do" in proc.stdout + proc.stderr
    assert json.loads(rec_file.read_text())["spp"] == 256


def test_the_bias_test_allows_for_noise_a_pixel_filter_spreads():
    """Unbiased images whose noise neighbours share (as through a Gaussian pixel filter): without ``spread``
    the block z-scores are inflated; with it they are N(0, 1)-like again. Independent noise: inflation ~1."""
    import torch

    from nriqa.data.pixel_filter import apply_pixel_filter

    rng = np.random.default_rng(0)
    truth = np.full((128, 128, 3), 0.5)

    def noisy(seed):
        n = torch.from_numpy(np.random.default_rng(seed).normal(0, 0.05, (1, 3, 128, 128)))
        return truth + apply_pixel_filter(n, 0.6)[0].permute(1, 2, 0).numpy()

    a, b, ref = noisy(1), noisy(2), noisy(3)
    ref_var = pixel_variance(noisy(4), noisy(5))
    plain = convergence(a, b, ref, ref_var)
    spread = convergence(a, b, ref, ref_var, spread=True)
    assert plain.median_abs_z > 1.0 and 0.5 < spread.median_abs_z < 0.85, (plain, spread)
    white = rng.normal(0, 1, (256, 256))
    assert block_inflation(white, 4) == pytest.approx(1.0, abs=0.1)


def neighbour_correlation(noisy: np.ndarray, ref: np.ndarray) -> float:
    """Correlation of the noise (image minus reference, grey) of horizontally adjacent pixels."""
    noise = (noisy - ref).mean(axis=2)
    return float(np.corrcoef(noise[:, :-1].ravel(), noise[:, 1:].ravel())[0, 1])


def test_a_pixel_filter_spreads_the_noise_and_its_dataset_keeps_to_it(tiny, tmp_path):
    """``pixel_filter=gaussian``: every record says so, the noise of neighbours correlates (box: it does not),
    each algorithm still converges to its reference, and a rerun with another filter is refused in one line."""
    out = tmp_path / "gaussian"
    args = ("preset=tiny", "scenes=[cornell]", "algorithms=[path_independent]", "jobs=1")
    proc = run_data_gen(*args, f"out={out}", "pixel_filter=gaussian")
    assert proc.returncode == 0, proc.stderr
    records, _ = read_manifest(out)
    assert {r.pixel_filter for r in records} == {"gaussian"}
    box, _ = read_manifest(tiny)
    assert {r.pixel_filter for r in box} == {"box"}

    def top_corr(root, recs):
        rec = max((r for r in recs if r.scene == "cornell" and r.role == "test"), key=lambda r: r.spp)
        return neighbour_correlation(read_exr(root / rec.path), read_exr(root / rec.reference))

    assert top_corr(out, records) > 0.3 > abs(top_corr(tiny, box)), (top_corr(out, records), top_corr(tiny, box))
    assert all(v["converged"] for v in dataset_verdicts(out, records))

    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")}
    proc = run_data_gen(*args, f"out={out}")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "rendered with pixel_filter=gaussian, not box" in lines[0], proc.stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")} == before


def test_a_zoomed_image_is_the_crop_of_the_whole_view_at_its_pixel_size():
    """``zoom=2``: a 16x16 crop of a 32x32 film, where :func:`crop_offset` puts it, the same for every image
    of the variant; it matches that region of the whole 32x32 render (within its noise), not another."""
    mi = pytest.importorskip("mitsuba")
    from data_gen.plan import ImageTask, Job
    from data_gen.render import crop_offset, scene_dict

    if mi.variant() is None:  # as the scene tests: leave another test's variant as it is, never switch it
        mi.set_variant(backend.SCALAR_VARIANT)
    task = ImageTask("x", "reference", 256, 3, "x.exr", "x.exr")
    whole = Job("cornell", 0, 7, "path_independent", (32, 32), 6, ())
    crop = Job("cornell", 0, 7, "path_independent", (16, 16), 6, (), "box", 2)
    assert crop_offset(7, 2, (16, 16)) == crop_offset(7, 2, (16, 16)) != (0, 0)
    assert crop_offset(7, 1, (16, 16)) == (0, 0)
    x, y = crop_offset(7, 2, (16, 16))
    assert 0 <= x <= 16 and 0 <= y <= 16
    full = np.array(mi.render(mi.load_dict(scene_dict(whole, task)), seed=1))
    part = np.array(mi.render(mi.load_dict(scene_dict(crop, task)), seed=2))
    assert full.shape == (32, 32, 3) and part.shape == (16, 16, 3)
    here = np.abs(full[y : y + 16, x : x + 16] - part).mean()
    elsewhere = min(
        np.abs(full[j : j + 16, i : i + 16] - part).mean() for i in (0, 16) for j in (0, 16) if (i, j) != (x, y)
    )
    assert here < 0.1 * full.mean() and here < 0.5 * elsewhere, (here, elsewhere, full.mean())


def test_a_zoomed_dataset_says_so_and_keeps_to_it(tmp_path):
    """``zoom=2``: images of the preset's size, every record with ``zoom`` 2, each algorithm converging to its
    reference; a rerun at another zoom is refused in one line and touches nothing."""
    out = tmp_path / "zoom"
    args = ("preset=tiny", "scenes=[cornell]", "algorithms=[path_independent]", "jobs=1", f"out={out}")
    proc = run_data_gen(*args, "zoom=2")
    assert proc.returncode == 0, proc.stderr
    records, meta = read_manifest(out)
    assert {r.zoom for r in records} == {2} and {(r.width, r.height) for r in records} == {(32, 32)}
    assert meta["config"]["zoom"] == 2
    assert all(v["converged"] for v in dataset_verdicts(out, records))
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")}
    proc = run_data_gen(*args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "rendered with zoom=2, not 1" in lines[0], proc.stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.exr")} == before


@pytest.mark.slow
@pytest.mark.parametrize("scene", list_scenes())
def test_default_preset_scene_converges_at_full_size(tmp_path, scene):
    """One variant of a scene at the default preset's size; every declared algorithm converges."""
    proc = run_data_gen("preset=default", f"out={tmp_path}", f"scenes=[{scene}]", "variants=1")
    assert proc.returncode == 0, proc.stderr
    records, _ = read_manifest(tmp_path)
    verdicts = dataset_verdicts(tmp_path, records)
    assert {v["algorithm"] for v in verdicts} == set(get_scene(scene).algorithms)
    assert all(v["converged"] for v in verdicts), verdicts


def test_loop_scene_is_the_reference_setup_at_any_resolution():
    mi = pytest.importorskip("mitsuba")
    from data_gen.render import loop_scene
    from data_gen.scenes import get_scene
    from nriqa.render.backend import SCALAR_VARIANT

    if mi.variant() is None:  # scenes are built with Mitsuba's transforms
        mi.set_variant(SCALAR_VARIANT)
    scene = loop_scene("medium", (24, 16), spp=8)
    film = scene["sensor"]["film"]
    assert (film["width"], film["height"]) == (24, 16) and film["rfilter"] == {"type": "box"}
    assert scene["integrator"]["max_depth"] == get_scene("medium").max_depth
    assert scene["integrator"]["type"] == "volpath"  # the fog scene's reference integrator
    assert loop_scene("medium", (24, 16), spp=8) == scene  # the same variant every time


def test_one_bare_scene_name_is_a_list_of_one():
    from omegaconf import OmegaConf

    from data_gen.__main__ import names, resolution

    assert names("scenes", "cornell") == ["cornell"]
    assert names("scenes", OmegaConf.create({"s": ["cornell", "door"]}).s) == ["cornell", "door"]
    assert resolution(OmegaConf.create({"r": [64, "32"]}).r) == (64, 32) and resolution(None) is None
