"""Spreading Warp launches over cores: a CPU launch runs on one thread and releases the GIL, so
launches from a pool of threads run in parallel."""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .errors import InputError


@functools.cache
def thread_pool(workers: int) -> ThreadPoolExecutor:
    """One long-lived pool per thread count: starting threads for every frame costs ~1 ms."""
    return ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pbrwarp")


def run(fn, jobs, threads: int):
    """fn(job) for every job, in order, on ``threads`` pool threads (inline for one thread or one
    job); yields each result as it completes in order."""
    if threads == 1 or len(jobs) == 1:
        return map(fn, jobs)
    return thread_pool(threads).map(fn, jobs)


def thread_count(threads) -> int:
    """``threads``, or every core for None."""
    if threads is None:
        return os.cpu_count() or 1
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise InputError(f"threads must be a whole number >= 1, got {threads!r}")
    return int(threads)
