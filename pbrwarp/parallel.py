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



_stages_turn = threading.Lock()


def run_stages(stages, threads: int):
    """Run ``stages`` in order, each on ``threads`` threads, the calling thread and threads - 1
    pool threads, with one pool round trip in all. A stage is (work, then): work(k) runs on
    thread k = 0..threads-1; once every thread has finished it, then() (if not None) runs on one
    of them before any starts the next stage. Between stages the threads meet at a barrier rather
    than returning to the caller, which would wake it and then the pool again: for launches of a
    millisecond those wake-ups took a tenth of the time. Concurrent calls take turns, lest their
    pool threads wait at barriers for threads queued behind each other (a stage must not call
    this itself). The first exception raised is re-raised here."""
    if threads == 1:
        for work, then in stages:
            work(0)
            if then is not None:
                then()
        return
    thens = iter([then for _, then in stages])

    def after_stage():
        then = next(thens)
        if then is not None:
            then()

    barrier = threading.Barrier(threads, action=after_stage)

    def worker(k):
        for work, _ in stages:
            try:
                work(k)
            except BaseException:
                barrier.abort()  # wake the others rather than leave them waiting
                raise
            barrier.wait()

    errors = []
    with _stages_turn:
        helpers = [thread_pool(threads - 1).submit(worker, k) for k in range(1, threads)]
        for outcome in [lambda: worker(0)] + [helper.result for helper in helpers]:
            try:
                outcome()
            except threading.BrokenBarrierError:
                pass  # broken by another thread's error
            except BaseException as error:  # noqa: BLE001 - re-raised below, once every thread is done
                errors.append(error)
    if errors:
        raise errors[0]
