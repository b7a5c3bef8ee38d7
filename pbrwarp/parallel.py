"""Spreading Warp launches over cores: a CPU launch runs on one thread and releases the GIL, so
launches from a pool of threads run in parallel.

The calling thread runs no launch itself (but the first of a short run_together call, with
``caller_first``): it waits for the pool's, interruptibly, since a launch in C cannot be
interrupted and Python runs signal handlers (Ctrl-C's KeyboardInterrupt) on the main thread only. When the wait ends in an exception (an interrupt, or an error of one of
the launches), no further job is handed out, the call's ``cancel`` hook tells the launches
running to stop early (the render kernel's stop flag, the raster's abort flag), and the caller
waits for them to return before it raises: nothing of the call keeps running, so the next call
finds the process as before. Every job must therefore be short (a fraction of a second), or
stop when its ``cancel`` hook asks.

One pool serves the whole process, its threads started as calls need them, up to
:func:`max_threads`, and kept for later calls."""

from __future__ import annotations

import functools
import os
import queue
import threading
from concurrent.futures import FIRST_EXCEPTION, Future, wait

import numpy as np

from .errors import InputError, ResourceError

# Largest ``threads`` a call may ask for, per core: more threads than cores cost little (the
# raster's waiting launches yield their core), but past a few per core they gain nothing.
MAX_THREADS_PER_CORE = 4


def cores() -> int:
    """The machine's logical cores (os.cpu_count), the default thread count."""
    return os.cpu_count() or 1


def max_threads() -> int:
    """The most threads a call may use (MAX_THREADS_PER_CORE per core), and so the most threads
    the pool ever holds."""
    return MAX_THREADS_PER_CORE * cores()


def thread_count(threads) -> int:
    """``threads`` checked (a whole number in 1..max_threads()), or every core for None."""
    if threads is None:
        return cores()
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise InputError(f"threads must be a whole number >= 1, got {threads!r}")
    if threads > max_threads():
        raise InputError(f"threads must be at most {max_threads()} ({MAX_THREADS_PER_CORE} per core on this "
                         f"machine's {cores()}), got {threads}; more threads than cores do not render faster")
    return int(threads)


class _Pool:
    """Threads running queued (future, task) pairs, at most max_threads(): started when a call
    needs more idle ones than there are, kept for later calls. A call's tasks are queued only
    once as many threads are idle as there are tasks queued, so that they all run at once
    (run_together's launches wait for each other). Each task queued wakes one idle thread, not
    all of them: on a machine with few cores, threads woken for nothing take the cores from the
    launches that are waiting for each other."""

    def __init__(self):
        self._changed = threading.Condition()  # callers waiting for idle threads wait on it
        self._tasks = queue.SimpleQueue()  # each put wakes one thread waiting in get
        self._queued = 0  # tasks put and not yet taken
        self._threads = 0
        self._idle = 0  # threads not running a task (waiting for one, or about to)

    def threads(self) -> int:
        with self._changed:
            return self._threads

    def start(self, items: list):
        """Queues ``items``, (Future, task) pairs, once enough threads are idle to run them all at
        once (waiting for threads of other calls while the pool is full). A ResourceError, nothing
        queued, if the system refuses a thread."""
        with self._changed:
            while self._idle - self._queued + max_threads() - self._threads < len(items):
                self._changed.wait()
            while self._idle - self._queued < len(items):
                self._start_thread()
            self._queued += len(items)
            for item in items:  # no interrupt is taken between these puts: nothing in them runs Python
                self._tasks.put(item)

    def _start_thread(self):
        thread = threading.Thread(target=self._serve, name=f"pbrwarp-{self._threads}", daemon=True)
        self._threads += 1
        self._idle += 1
        try:
            thread.start()
        except RuntimeError as error:  # "can't start new thread": none was started
            self._threads -= 1
            self._idle -= 1
            raise ResourceError(f"could not start a thread ({error}); the system limits threads: pass fewer "
                                "threads= or free some") from error

    def drop(self, futures: list[Future]):
        """Cancels those of ``futures`` whose task no thread has taken (queued, or never queued):
        the thread that takes a cancelled one skips it."""
        with self._changed:
            for future in futures:
                # a task is taken under this lock, and its future marked running at once
                if not future.done() and future.cancel():
                    future.set_running_or_notify_cancel()

    def _serve(self):
        while True:
            future, task = self._tasks.get()
            with self._changed:
                self._queued -= 1
                self._idle -= 1
                # drop() cancelled it (and notified its waiters): skip it
                runs = not future.cancelled() and future.set_running_or_notify_cancel()
            if runs:
                self._run(future, task)
            else:
                self._now_idle()

    def _run(self, future: Future, task):
        """task() for ``future``; the thread counts as idle again before the caller learns the
        outcome (lest a caller's next call, finding too few idle threads, start more)."""
        try:
            result = task()
        except BaseException as error:  # noqa: BLE001 - handed to the waiting caller
            self._now_idle()
            future.set_exception(error)
        else:
            self._now_idle()
            future.set_result(result)

    def _now_idle(self):
        with self._changed:
            self._idle += 1
            self._changed.notify_all()


_pool = _Pool()


def pool_threads() -> int:
    """How many threads the pool holds (at most max_threads())."""
    return _pool.threads()


def _launch(tasks: list, stop, first_only: bool = False) -> list[Future]:
    """Runs every task of ``tasks`` at once, each on a pool thread of its own, and waits for them
    (for the first only if ``first_only``); their futures. See :func:`_wait`."""
    futures = [Future() for _ in tasks]
    _wait(futures, stop, tasks, first_only)
    return futures


def _wait(futures: list[Future], stop, tasks=(), first_only: bool = False):
    """Queues ``tasks`` (one per future; none: already running) and waits for the futures, or the
    first only if ``first_only``. If the wait ends in an exception, the caller's (an interrupt)
    or a waited-for task's, :func:`_stop_all` and raise it."""
    watched = futures[:1] if first_only else futures
    try:
        if tasks:
            _pool.start(list(zip(futures, tasks)))
        wait(watched, return_when=FIRST_EXCEPTION)
    except BaseException:
        _stop_all(futures, stop)
        raise
    for future in watched:
        if future.done() and future.exception() is not None:
            _stop_all(futures, stop)
            raise future.exception()


def _stop_all(futures: list[Future], stop):
    """stop() (the call's cancel hook: no further job handed out, the running launches told to
    stop early), the tasks not yet started dropped, then a wait for those running. A further
    interrupt meanwhile does not end the wait, which lasts one job at most: the process is left
    with nothing of the call running."""
    stop()
    _pool.drop(futures)
    while True:
        try:
            wait(futures)
            return
        except KeyboardInterrupt:
            continue


class _Handout:
    """Job indices 0..n-1, each given once to whichever pool thread asks next, until stop()."""

    def __init__(self, n: int, cancel=None):
        self._n = n
        self._next = 0
        self._lock = threading.Lock()
        self._cancel = cancel

    def __iter__(self):
        return self

    def __next__(self) -> int:
        with self._lock:
            index = self._next
            self._next += 1
        if index >= self._n:
            raise StopIteration
        return index

    def stop(self):
        with self._lock:
            self._next = self._n
        if self._cancel is not None:
            self._cancel()


def run(fn, jobs, threads: int | None, cancel=None) -> list:
    """[fn(job) for job in jobs], the jobs taken in turn by min(threads, len(jobs)) pool threads,
    the caller waiting (see the module's text on interrupts and errors: ``cancel``, if given, is
    called to make the running jobs stop early)."""
    jobs = list(jobs)
    workers = min(thread_count(threads), len(jobs))
    results = [None] * len(jobs)
    handout = _Handout(len(jobs), cancel)

    def work():
        for index in handout:
            results[index] = fn(jobs[index])

    if workers:
        _launch([work] * workers, handout.stop)
    return results


def run_all(fn, jobs, threads: int | None, cancel=None):
    """fn(job) for every job on ``threads`` pool threads, waiting for all (see :func:`run`)."""
    run(fn, jobs, threads, cancel)


_together_turn = threading.Lock()


def run_together(fn, threads: int, join: bool = True, cancel=None, caller_first: bool = False):
    """fn(k) for k = 0..threads-1 all at once, each on a pool thread of its own, for launches that
    wait for each other (see kernels/barriers.py's all_arrived), so none may queue behind another.
    Concurrent calls take turns, lest one call's launches hold the pool while the others' wait
    for theirs. If one raises, or the caller is interrupted, ``cancel()`` must release the others
    (the raster sets its abort flag); it is called at once, from the failing launch's thread;
    the first exception is raised here once every thread is done.

    ``join`` False returns as soon as fn(0) has (unless it raised), for launches of which the
    first returns only once the others are done (the raster's): the pool threads' way back to
    Python then overlaps the caller's; the returned callable waits for them and re-raises the
    first of their errors (for a caller that found their launches aborted).

    ``caller_first`` True runs fn(0) on the calling thread rather than a pool thread's, for calls
    short enough that an interrupt may wait for their launch to return (the raster's, when its
    cost model gives a few tens of milliseconds): it saves waking a pool thread and then the
    caller, which on a small virtual machine costs as much as a frame's rasterization."""
    stop = cancel if cancel is not None else _nothing

    def launch(k):
        try:
            fn(k)
        except BaseException:
            stop()  # at once: the others may be waiting for this one
            raise

    n = thread_count(threads)
    with _together_turn:
        if caller_first:
            futures = [Future() for _ in range(1, n)]
            try:
                if futures:
                    _pool.start([(future, functools.partial(launch, k)) for k, future in enumerate(futures, 1)])
                launch(0)
            except BaseException:
                _stop_all(futures, stop)
                raise
            if join:
                _wait(futures, stop)
        else:
            futures = _launch([functools.partial(launch, k) for k in range(n)], stop, first_only=not join)
    if join:
        return _nothing

    return functools.partial(_wait, futures, stop)


def _nothing():
    pass


def _after_fork_in_child():
    # the parent's pool threads do not exist in a forked child
    global _pool, _together_turn
    _pool = _Pool()
    _together_turn = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def progress_bar(enabled, **options):
    """A tqdm progress bar made with ``options``, or None where ``enabled`` is False or tqdm (an
    optional dependency) is not installed."""
    if enabled is False:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(**options)
