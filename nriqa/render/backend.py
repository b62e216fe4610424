"""Choose the Mitsuba variant: ``llvm_ad_rgb`` when a working LLVM is present, else ``scalar_rgb``.

An old libLLVM makes Dr.Jit abort the whole process (SIGABRT, uncatchable), so the LLVM variant is
probed in a subprocess before any worker uses it. ``cuda_ad_rgb`` (an NVIDIA GPU with its driver)
is only taken when asked for by name, after the same probe; ``auto`` never picks it, so a dataset
renders the same way on every CPU machine. Images from different variants agree statistically,
not bit for bit: keep one backend per dataset. :func:`ensure_variant` does the same for a render
loop when the caller has set no variant; :func:`is_jit_variant` tells whether the variant traces
wavefronts, as :class:`~nriqa.render.pixel_renderer.PixelRenderer` needs.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

log = logging.getLogger(__name__)

LLVM_VARIANT = "llvm_ad_rgb"
CUDA_VARIANT = "cuda_ad_rgb"
SCALAR_VARIANT = "scalar_rgb"
BACKENDS = ("auto", LLVM_VARIANT, CUDA_VARIANT, SCALAR_VARIANT)
# Variants that abort or fail without their native library, so they are probed in a subprocess first.
PROBED_VARIANTS = (LLVM_VARIANT, CUDA_VARIANT)
# Dr.Jit needs LLVM >= 11 but aborts with some older builds; Debian ships 19 as libllvm19.
LLVM_CANDIDATES = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
# Largest wavefront (pixels x samples in one pass) the LLVM backend gets; bounds its memory.
MAX_WAVEFRONT = 1 << 22

_PROBE = (
    "import sys\n"
    "import mitsuba as mi\n"
    "mi.set_variant(sys.argv[1])\n"
    "s = mi.cornell_box(); s['sensor']['film']['width'] = s['sensor']['film']['height'] = 8\n"
    "img = mi.render(mi.load_dict(s), spp=1)\n"
    "print(float(mi.TensorXf(img).numpy().mean()))\n"
)
_HOW_TO_FIX = {
    LLVM_VARIANT: "install libllvm19 or use backend=scalar_rgb",
    CUDA_VARIANT: "it needs an NVIDIA GPU with its driver; use backend=auto on a CPU machine",
}


def llvm_env() -> dict[str, str]:
    """Environment additions that point Dr.Jit at LLVM 19 when it is installed."""
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        return {}
    for candidate in LLVM_CANDIDATES:
        if Path(candidate).exists():
            return {"DRJIT_LIBLLVM_PATH": candidate}
    return {}


def probe_variant(variant: str, timeout: float = 120.0) -> tuple[bool, str]:
    """Render one tiny image with ``variant`` in a subprocess; return ``(ok, reason)``."""
    env = {**os.environ, **llvm_env()}
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE, variant], env=env, capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return False, f"{variant} probe timed out after {timeout:.0f} s"
    if proc.returncode == 0:
        return True, "ok"
    last = (proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"])[-1]
    return False, f"{variant} probe failed ({last})"


def probe_llvm(timeout: float = 120.0) -> tuple[bool, str]:
    """:func:`probe_variant` for ``llvm_ad_rgb``."""
    return probe_variant(LLVM_VARIANT, timeout)


def unusable(variant: str, reason: str, where: str = "") -> str:
    """The one-line message for a probed variant that does not work (``where``: e.g. " on worker N")."""
    return f"backend {variant} unusable{where}: {reason}; {_HOW_TO_FIX[variant]}"


def select_backend(requested: str = "auto") -> str:
    """Resolve ``auto``/``llvm_ad_rgb``/``cuda_ad_rgb``/``scalar_rgb`` to a variant that works here.

    ``auto`` tries ``llvm_ad_rgb`` and falls back to ``scalar_rgb`` with one warning line; a variant
    asked for by name that does not work raises ``RuntimeError`` (one line: why, and what to do).
    """
    if requested not in BACKENDS:
        raise ValueError(f"unknown backend {requested!r}; choose one of {', '.join(BACKENDS)}")
    if requested == SCALAR_VARIANT:
        return SCALAR_VARIANT
    variant = LLVM_VARIANT if requested == "auto" else requested
    ok, reason = probe_variant(variant)
    if ok:
        return variant
    if requested != "auto":
        raise RuntimeError(unusable(variant, reason))
    log.warning(
        "%s; falling back to %s (slower on large renders). Install libllvm19 for the fast variant.",
        reason,
        SCALAR_VARIANT,
    )
    return SCALAR_VARIANT


def init_worker(variant: str, threads: int) -> None:
    """Set up Mitsuba in a worker process: LLVM path, variant, and its thread count."""
    os.environ.update(llvm_env())
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(variant)
    dr.set_thread_count(max(1, threads))
    mi.set_log_level(mi.LogLevel.Error)


def ensure_variant(requested: str = "auto", threads: int | None = None) -> str:
    """Set a Mitsuba variant with :func:`select_backend` unless one is already set; return the variant."""
    import mitsuba as mi

    if mi.variant() is not None:
        return mi.variant()
    variant = select_backend(requested)
    init_worker(variant, threads or os.cpu_count() or 1)
    return variant


def is_jit_variant() -> bool:
    """Whether the current Mitsuba variant traces wavefronts (llvm/cuda), as per-pixel sampling needs."""
    import mitsuba as mi

    return mi.variant() is not None and mi.variant().startswith(("llvm_", "cuda_"))
