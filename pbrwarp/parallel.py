"""Spreading Warp launches over cores: a CPU launch runs on one thread and releases the GIL, so
launches from a pool of threads run in parallel."""

from __future__ import annotations

import functools
import os
import threading
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


def run_all(fn, jobs, threads: int):
    """fn(job) for every job on ``threads`` pool threads (see :func:`run`), waiting for all."""
    for _ in run(fn, jobs, threads):
        pass


def thread_count(threads) -> int:
    """``threads``, or every core for None."""
    if threads is None:
        return os.cpu_count() or 1
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise InputError(f"threads must be a whole number >= 1, got {threads!r}")
    return int(threads)



_together_turn = threading.Lock()


def run_together(fn, threads: int, join: bool = True):
    """fn(k) for k = 0..threads-1 all at once: k = 0 on the calling thread (which is awake
    already), the others on threads - 1 pool threads, for launches that wait for each other
    (see kernels/barriers.py's all_arrived), so none may queue behind another. Concurrent calls take
    turns, lest one call's launches hold the pool while the others' wait for theirs. fn must see to
    it that an error before its launch releases the others (the raster sets an abort flag). The
    first exception raised is re-raised here, once every thread is done.

    ``join`` False returns as soon as fn(0) has (unless it raised), for launches of which the
    calling thread's returns only once the others are done (the raster's): the pool threads'
    way back to Python then overlaps the caller's; the returned callable waits for them and
    re-raises the first of their errors (for a caller that found their launches aborted)."""
    if threads == 1:
        fn(0)
        return _nothing_to_join
    errors = []
    with _together_turn:
        helpers = [thread_pool(threads - 1).submit(fn, k) for k in range(1, threads)]
        try:
            fn(0)
        except BaseException as error:  # noqa: BLE001 - re-raised below, once every thread is done
            errors.append(error)
        if join or errors:
            _collect(helpers, errors)
    if errors:
        raise errors[0]

    def join_helpers():
        failures = []
        _collect(helpers, failures)
        if failures:
            raise failures[0]

    return join_helpers


def _collect(helpers, errors: list):
    for helper in helpers:
        try:
            helper.result()
        except BaseException as error:  # noqa: BLE001 - the caller re-raises the first
            errors.append(error)


def _nothing_to_join():
    pass
