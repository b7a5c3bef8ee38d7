"""Shared bench helpers: timing (median after warm-up), machine description, result files."""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def _arithmetic_kernel():
    import warp as wp

    from pbrwarp.kernels.barriers import all_done

    @wp.kernel(enable_backward=False, module="unique")
    def dependent_arithmetic(steps: int, launch: int, launches: int, finished: wp.array(dtype=wp.int32),
                             out: wp.array(dtype=float)):
        # a chain of dependent square roots: compute only, nothing read or written on the way
        x = float(1.0)
        for _ in range(steps):
            x = wp.sqrt(x * x * 0.999999 + 1.0e-7)
        out[0] = x
        # as the raster's launches end: launch 0 returns once every launch is done (slot 0 of
        # ``finished`` counts them, slot 1 is the abort flag, never set)
        all_done(finished, 0, 1, wp.where(launch == 0, launches, 0), 1, 1024, wp.uint64(0))

    return dependent_arithmetic


class DivisibleWork:
    """The machine's own yardstick for multicore speedups: a compute-only Warp kernel lasting
    ``seconds`` on one thread (calibrated), or split in equal parts over ``threads`` launches side
    by side, dispatched and ended as the raster's are (pbrwarp.parallel.run_together without
    joining, launch 0 returning once all are done). Its speedup is what a perfectly divisible
    kernel of that length gets here, the pool thread's start and this shared machine's noise
    included."""

    def __init__(self, seconds: float, threads: int):
        import warp as wp

        self.kernel = _arithmetic_kernel()
        self.threads = threads
        self.outs = [wp.zeros(1, dtype=float, device="cpu") for _ in range(threads)]
        self.finished = wp.zeros(2, dtype=wp.int32, device="cpu")
        self.finished_view = self.finished.numpy()
        self.steps = 1 << 16
        self.one()  # compiled or loaded
        calibration = 1 << 20
        t0 = time.perf_counter()
        self._run(1, calibration)
        self.steps = max(threads, round(seconds * calibration / (time.perf_counter() - t0)))

    def _run(self, threads: int, steps: int):
        import warp as wp

        from pbrwarp.parallel import run_together

        self.finished_view.fill(0)
        run_together(lambda k: wp.launch(self.kernel, dim=1, device="cpu",
                                         inputs=[steps // threads, k, threads, self.finished, self.outs[k]]),
                     threads, join=False)

    def one(self):
        self._run(1, self.steps)

    def split(self):
        self._run(self.threads, self.steps)

    def wake(self):
        """Run a moment on every thread, so that the pool thread is awake for the next call."""
        self._run(self.threads, self.threads)


def median_time(fn, repeats: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``fn()`` over ``repeats`` runs after ``warmup`` untimed runs."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def interleaved_medians(fns: dict, repeats: int = 5, warmup: int = 1) -> dict:
    """Median wall time of each of ``fns`` (name -> callable), timed in turn, one call each per
    round, after ``warmup`` untimed rounds: a burst of load on a shared machine then slows every
    variant alike rather than one of them, which keeps their ratios meaningful."""
    samples = {name: [] for name in fns}
    for round_ in range(warmup + repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            if round_ >= warmup:
                samples[name].append(time.perf_counter() - t0)
    return {name: statistics.median(times) for name, times in samples.items()}


def rebuilt(scene, slot: str, fn):
    """fn() with the scene cache's ``slot`` ("light buffers", "shadow maps") emptied, so that fn
    builds it anew, and the old value put back afterwards: variants timed in turn with it keep
    what they measure (light buffers reused for a while have their interiors marked)."""
    with scene.cache.dropped(slot):
        return fn()


def machine() -> dict:
    import numpy
    import warp

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent).stdout.strip()
    except OSError:
        commit = ""
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "warp": warp.__version__,
            "numpy": numpy.__version__, "commit": commit, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def command_line(parser, args) -> str:
    """The command that reproduces a bench run: the script (the parser's prog, in bench/) and every
    option whose value differs from its default, in the parser's order."""
    parts = [f"python bench/{parser.prog}"]
    for action in parser._actions:
        if not action.option_strings or action.dest == "help":
            continue
        value = getattr(args, action.dest)
        if value == action.default:
            continue
        if isinstance(value, (list, tuple)):
            value = " ".join(str(v) for v in value)
        parts.append(action.option_strings[0] if value is True else f"{action.option_strings[0]} {value}")
    return " ".join(parts)


def write_results(name: str, command: str, payload: dict, markdown: str, directory: Path = RESULTS) -> None:
    """Write ``directory``/name.json and name.md (bench/results by default) and print the markdown."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    info = machine()
    payload = {"command": command, "machine": info, **payload}
    (directory / f"{name}.json").write_text(json.dumps(payload, indent=2) + "\n")
    header = (f"Command: `{command}`\n\nMachine: {info['cpu']}, {info['cores']} cores; Python {info['python']}, "
              f"warp {info['warp']}; commit {info['commit']}; {info['date']}.\n\n")
    (directory / f"{name}.md").write_text(header + markdown)
    print(header + markdown, file=sys.stdout)
