"""What a benchmark runs on: the line above its table (CPU model, torch threads, torch version), and waiting for a
device's queue so that a timing holds the work it started."""

from __future__ import annotations

import platform

import torch


def cpu_name() -> str:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else :func:`platform.processor`, else "unknown CPU"."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def machine_line() -> str:
    """``"<CPU>, <n> torch threads, torch <version>"``."""
    return f"{cpu_name()}, {torch.get_num_threads()} torch threads, torch {torch.__version__}"


def sync(device: str | torch.device) -> None:
    """Wait until ``device`` has finished the work queued on it (CUDA runs asynchronously); on the CPU nothing."""
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)
