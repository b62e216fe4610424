"""Shared fixtures: a tiny synthetic dataset in the manifest format (no renderer needed), and the
tiny preset rendered by data_gen once per test session.

Smooth references + Gaussian noise per spp; used by the data, training, cross-validation and
stability tests.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nriqa.io.exr import read_exr, write_exr
from nriqa.io.manifest import ALBEDO_FILE, Record, write_manifest

SCENES = ("alpha", "beta", "gamma")
SPPS = (1, 4, 16, 64)
CONSTANT = (0.3, 0.5, 0.7)  # an albedo the tone map or a display would change


def make_dataset(root: Path, size: int = 80, scenes=SCENES, spps=SPPS, twins: bool = True) -> Path:
    """Write ``len(scenes)`` scenes x (1 reference + a noisy test (and twin) per spp) under ``root``."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:size, 0:size] / size
    records = []
    for si, scene in enumerate(scenes):
        freq = 2 + si
        ref = np.stack([np.sin(freq * np.pi * xx + c) * np.cos(freq * np.pi * yy) + 1.2 for c in range(3)], axis=2)
        ref = (ref * (0.5 + si)).astype(np.float32)
        ref_path = f"{scene}/reference.exr"
        write_exr(root / ref_path, ref)
        common = dict(
            scene=scene, variant=0, algorithm="path", width=size, height=size, render_seconds=0.1, backend="synthetic"
        )
        records.append(
            Record(id=f"{scene}-ref", role="reference", spp=1024, seed=99, path=ref_path, reference=ref_path, **common)
        )
        for spp in spps:
            roles = ("test", "twin") if twins else ("test",)
            for k, role in enumerate(roles):
                noisy = np.clip(ref + rng.normal(0, 1.5 / np.sqrt(spp), ref.shape) * ref, 0, None).astype(np.float32)
                path = f"{scene}/path-{spp:04d}-{role}.exr"
                write_exr(root / path, noisy)
                twin = f"{scene}-{spp}-{roles[1 - k]}" if twins else None
                records.append(
                    Record(
                        id=f"{scene}-{spp}-{role}",
                        role=role,
                        spp=spp,
                        seed=k,
                        path=path,
                        reference=ref_path,
                        twin=twin,
                        **common,
                    )
                )
    write_manifest(root, records, {"synthetic": True})
    return root


def with_albedo(src: Path, dst: Path, constant: bool = False) -> Path:
    """A copy of the synthetic dataset with an albedo pass beside each reference: stripes, or CONSTANT."""
    shutil.copytree(src, dst)
    for k, ref in enumerate(sorted(dst.glob("*/reference.exr"))):
        h, w = read_exr(ref).shape[:2]
        if constant:
            albedo = np.broadcast_to(np.array(CONSTANT, dtype=np.float32), (h, w, 3))
        else:
            xx = np.arange(w)[None, :, None] + np.zeros((h, 1, 3))
            albedo = 0.2 + 0.6 * ((xx // (3 + k)) % 2) * np.array([1.0, 0.7, 0.4])
        write_exr(ref.parent / ALBEDO_FILE, albedo.astype(np.float32))
    return dst


@pytest.fixture(scope="session")
def synthetic_dataset(tmp_path_factory) -> Path:
    """3 scenes (alpha, beta, gamma) x (reference + test and twin at 1, 4, 16, 64 spp), 80x80."""
    return make_dataset(tmp_path_factory.mktemp("synthetic"))


@pytest.fixture(scope="session")
def striped_dataset(synthetic_dataset, tmp_path_factory) -> Path:
    """The synthetic dataset with a striped albedo pass beside each reference."""
    return with_albedo(synthetic_dataset, tmp_path_factory.mktemp("albedo") / "d")


REPO = Path(__file__).resolve().parents[1]


def load_script(relative: str):
    """A script of the repository (``benchmarks/scorer.py``, ``train.py``) loaded as a module, to call its ``main``."""
    path = REPO / relative
    spec = importlib.util.spec_from_file_location(f"script_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def one_thread():
    """One torch intra-op thread: faster and steadier for tiny inputs on a shared 2-core machine."""
    import torch

    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def run_data_gen(*overrides: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """``python -m data_gen OVERRIDES...`` from the repository root."""
    return subprocess.run(
        [sys.executable, "-m", "data_gen", *overrides], cwd=REPO, capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> Path:
    """The tiny preset (every scene family, one variant, 32x32), rendered once per test session."""
    pytest.importorskip("mitsuba")
    out = tmp_path_factory.mktemp("tiny")
    proc = run_data_gen("preset=tiny", f"out={out}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out


@pytest.fixture
def seen_pairs(monkeypatch) -> list:
    """The ``(noisy, reference)`` batches training items' targets are computed from, in order (recorded only)."""
    from nriqa.data import patches
    from nriqa.data.targets import compute_target

    seen = []

    def recording(kind, noisy, ref):
        seen.append((noisy.clone(), ref.clone()))
        return compute_target(kind, noisy, ref)

    monkeypatch.setattr(patches, "compute_target", recording)
    return seen
