"""Warp's start-up, kept quiet unless asked for.

Initialising Warp prints a greeting (its version, devices and kernel cache) at log level INFO; its
native library writes "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver" straight to
the process's stderr on every machine without a GPU, which is every machine pbrwarp is for; and
each kernel module it loads prints a "Module ... load" line at INFO. None of it helps someone
rendering on the CPU. So ``import pbrwarp`` initialises Warp with those messages held back and
raises Warp's log level to WARNING: Warp's warnings and errors still show, and so do pbrwarp's own.

``PBRWARP_VERBOSE=1`` in the environment leaves Warp as it is (greeting, CUDA note, module loads);
so does a Warp log level below INFO set before pbrwarp is imported. The command line's
``--verbose`` calls :func:`show_warp_messages`, which prints what was held back and lowers the
level to INFO.
"""

from __future__ import annotations

import os
import sys
import tempfile

import warp as wp

VERBOSE_ENV = "PBRWARP_VERBOSE"
"""Environment variable: any value but empty, 0, false, no or off shows Warp's messages."""

# What Warp's native library writes when it finds no CUDA driver (not a problem on the CPU).
_NO_CUDA_DRIVER = "Could not find or load the NVIDIA CUDA driver"

_held_back: list[tuple[str, str]] = []  # ("stdout" or "stderr", text) Warp wrote while starting quietly


def verbose_from_environment() -> bool:
    """True when ``PBRWARP_VERBOSE`` asks for Warp's messages."""
    return os.environ.get(VERBOSE_ENV, "").strip().lower() not in ("", "0", "false", "no", "off")


class _Collector:
    """A Warp logger that keeps Warp's information messages and passes warnings and errors on."""

    def __init__(self, passed_to):
        self.info_lines: list[str] = []
        self.passed_to = passed_to

    def debug(self, message: str) -> None:
        self.info_lines.append(message)

    def info(self, message: str) -> None:
        self.info_lines.append(message)

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        self.passed_to.warning(message, category=category, stacklevel=stacklevel + 1)

    def error(self, message: str) -> None:
        self.passed_to.error(message)


def _flush(stream) -> None:
    if stream is not None:  # None when Python started without that descriptor
        stream.flush()


def _init_capturing_stderr() -> str:
    """``wp.init()`` with file descriptor 2 pointed at a temporary file; returns what was written
    there. Native code writes to the descriptor, not to ``sys.stderr``, so only the descriptor can
    catch it. Other threads' stderr output in that instant is caught too and written back after."""
    _flush(sys.stderr)
    try:
        sink = tempfile.TemporaryFile()
    except OSError:  # nowhere to hold it: start Warp as it is
        wp.init()
        return ""
    with sink:
        try:
            saved = os.dup(2)
        except OSError:  # no stderr to keep quiet
            wp.init()
            return ""
        try:
            os.dup2(sink.fileno(), 2)
            try:
                wp.init()
            finally:
                _flush(sys.stderr)
                os.dup2(saved, 2)
        finally:
            os.close(saved)
        sink.seek(0)
        return sink.read().decode("utf-8", errors="replace")


def start_warp() -> None:
    """Initialise Warp (see the module's docstring for what is kept quiet and how to see it)."""
    if verbose_from_environment() or wp.config.log_level < wp.LOG_INFO:
        wp.init()
        return
    collector = _Collector(wp.get_logger())
    with wp.ScopedLogger(collector):
        captured = _init_capturing_stderr()
    wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    noise = "".join(line for line in captured.splitlines(keepends=True) if _NO_CUDA_DRIVER in line)
    kept = "".join(line for line in captured.splitlines(keepends=True) if _NO_CUDA_DRIVER not in line)
    if kept:
        try:
            os.write(2, kept.encode("utf-8", errors="replace"))
        except OSError:  # stderr closed
            pass
    if noise:
        _held_back.append(("stderr", noise))
    if collector.info_lines:
        _held_back.append(("stdout", "".join(line + "\n" for line in collector.info_lines)))


def show_warp_messages() -> None:
    """Print what Warp said while starting quietly (once) and show its later information messages
    (module loads) from now on: the command line's ``--verbose``."""
    while _held_back:
        name, text = _held_back.pop(0)
        stream = getattr(sys, name)
        if stream is not None:  # None when Python started without that descriptor
            stream.write(text)
            stream.flush()
    wp.config.log_level = min(wp.config.log_level, wp.LOG_INFO)
