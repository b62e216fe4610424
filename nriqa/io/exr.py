"""Read and write linear HDR images as OpenEXR.

Writes are float32 (float16 overflows at 65504, turning fireflies into Inf) and atomic.
Arrays are ``(H, W, 3)`` float32, linear RGB.

The OpenEXR library reports a damaged file twice: a warning printed from C++ through Python's
``sys.stdout`` (pybind11's ``print``) and error lines written by its C core to file descriptor 2.
Reads therefore run with ``sys.stdout``/``sys.stderr`` and descriptors 1 and 2 sent to nothing
(:func:`library_output_silenced`), so that stdout carries only a program's results and a bad file is
reported once, by :class:`ImageReadError`.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import io
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import OpenEXR

from nriqa.errors import NriqaError
from nriqa.io.atomic import atomic_path

EXR_MAGIC = b"\x76\x2f\x31\x01"
_OUTPUT_LOCK = threading.Lock()  # streams and descriptors are process-wide: one silenced block at a time


class ImageReadError(NriqaError):
    """An image file that cannot be interpreted; the message says which file and why."""


def write_exr(path: str | os.PathLike, rgb: np.ndarray, half: bool = False) -> None:
    """Write an ``(H, W, 3)`` image as a float32 ZIP-compressed scanline EXR, atomically.

    ``half``: half floats, PIZ-compressed (smaller for noisy images); the caller checks the range.
    """
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"write_exr expects an (H, W, 3) array, got shape {rgb.shape} for {path}")
    compression = OpenEXR.PIZ_COMPRESSION if half else OpenEXR.ZIP_COMPRESSION
    header = {"compression": compression, "type": OpenEXR.scanlineimage}
    pixels = np.ascontiguousarray(rgb, dtype=np.float16 if half else np.float32)
    with atomic_path(path) as tmp:
        OpenEXR.File(header, {"RGB": pixels}).write(str(tmp))


@contextlib.contextmanager
def library_output_silenced() -> Iterator[None]:
    """Discard what is printed while the block runs: Python's ``sys.stdout``/``sys.stderr`` and, for
    C/C++ code, file descriptors 1 and 2 (pointed at ``/dev/null``).

    Python's streams are flushed first and C's stdio buffers before the descriptors come back, so
    nothing written inside leaks out later. One silenced block at a time (a lock); the streams are
    process-wide, so what other threads print meanwhile is discarded too: keep the block short.
    """
    with _OUTPUT_LOCK:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(AttributeError, OSError, ValueError):
                stream.flush()
        sink = io.StringIO()
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            try:
                saved = [os.dup(1), os.dup(2)]
            except OSError:  # a descriptor is closed: nothing to protect there
                yield
                return
            null = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(null, 1)
                os.dup2(null, 2)
                yield
            finally:
                _flush_c_stdio()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                for fd in (*saved, null):
                    os.close(fd)


@functools.cache
def _libc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL(None)
    except (OSError, TypeError):  # no process-wide symbol table (Windows)
        return None


def _flush_c_stdio() -> None:
    """``fflush(NULL)``: write out what C/C++ code left in stdio buffers (no-op where libc is not found)."""
    with contextlib.suppress(AttributeError, OSError):
        _libc().fflush(None)


def _damaged(path: Path) -> ImageReadError:
    size = path.stat().st_size
    return ImageReadError(
        f"{path}: truncated or damaged EXR file ({size} bytes; OpenEXR cannot read it); copy or export it again"
    )


def read_exr(path: str | os.PathLike) -> np.ndarray:
    """Read an EXR as ``(H, W, 3)`` float32 linear RGB.

    RGB and RGBA (alpha dropped) and single-channel luminance (``Y``, or one unnamed channel,
    replicated to RGB) are accepted, half or float, scanline or tiled. Deep, multi-part, truncated
    and otherwise damaged files raise :class:`ImageReadError`; the library prints nothing.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageReadError(f"{path}: no such file")
    try:
        with library_output_silenced(), OpenEXR.File(str(path)) as exr:
            parts = exr.parts
            # The library reports a file whose pixel data it cannot read as having no parts.
            if not parts:
                raise _damaged(path)
            if len(parts) != 1:
                raise ImageReadError(
                    f"{path}: multi-part EXR ({len(parts)} parts) is not supported; export a single part"
                )
            kind = exr.header().get("type")
            if kind in (OpenEXR.deepscanline, OpenEXR.deeptile):
                raise ImageReadError(f"{path}: deep EXR is not supported; flatten it first")
            channels = {name: ch.pixels for name, ch in exr.channels().items()}
    except ImageReadError:
        raise
    except Exception as exc:  # OpenEXR raises bare RuntimeError/OSError with C++ messages
        with open(path, "rb") as fh:
            if fh.read(4) == EXR_MAGIC:  # an EXR whose header or offset table is cut or corrupt
                raise _damaged(path) from None
        raise ImageReadError(f"{path}: not a readable EXR file ({exc})") from None
    return _to_rgb(path, channels)


def _to_rgb(path: Path, channels: dict[str, np.ndarray]) -> np.ndarray:
    for name in ("RGB", "RGBA"):
        if name in channels:
            return np.ascontiguousarray(channels[name][..., :3], dtype=np.float32)
    for name in ("Y", "L"):
        if name in channels:
            return np.repeat(channels[name].astype(np.float32)[..., None], 3, axis=2)
    if len(channels) == 1:
        (only,) = channels.values()
        if only.ndim == 2:
            return np.repeat(only.astype(np.float32)[..., None], 3, axis=2)
        if only.ndim == 3 and only.shape[2] >= 3:
            return np.ascontiguousarray(only[..., :3], dtype=np.float32)
    raise ImageReadError(f"{path}: no RGB, RGBA or luminance channels (found {sorted(channels)}); export RGB")
