"""Interrupts and threads (pbrwarp/parallel.py): Ctrl-C stops all of a render's work within a
fraction of a second and leaves the process ready for the next render; ``threads=`` is bounded,
and so are the pool's threads; a thread that cannot start, or a launch that fails, stops the
launches already running. Each case runs in a subprocess under a timeout: a launch left spinning
or waiting would otherwise hang the test run, and a signal would reach pytest itself."""

import json
import os
import select
import signal
import subprocess
import sys
import textwrap
import time

from pathlib import Path

import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.parallel import max_threads, thread_count

# What the subprocesses share: the demo scene, a small frame of it, and ways to measure the
# process's CPU time and to interrupt it as Ctrl-C does.
PRELUDE = textwrap.dedent("""
    import json, os, signal, threading, time, traceback
    import numpy as np
    import warp as wp
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    import pbrwarp as pw
    from pbrwarp import parallel
    from pbrwarp.meshes import demo_scene

    SMALL = dict(width=64, height=48, spp=4, progress=False)

    def cpu_used_over(seconds):
        # CPU seconds the whole process uses while its main thread sleeps this long
        before = os.times()
        time.sleep(seconds)
        after = os.times()
        return (after.user + after.system) - (before.user + before.system)

    def os_threads():
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("Threads:"))

    def report(**values):
        print("REPORT " + json.dumps(values), flush=True)
""")

# The checkout, whose pbrwarp the subprocesses import.
ROOT = Path(pw.__file__).resolve().parent.parent
# How far an interrupt may take to reach the caller, and the CPU the process may use in the
# second after it (a launch left running would use a whole core).
INTERRUPT_SECONDS = 1.0
IDLE_CPU_SECONDS = 0.25
# The command line's exit after an interrupt (it exited 12-14 s after Ctrl-C, shading on).
EXIT_SECONDS = 5.0
# A small frame after the interrupt, its caches built (the bug this guards against made it wait
# 8-9 s for the interrupted frame's launches).
NEXT_FRAME_SECONDS = 5.0


def run_child(script: str, *args, timeout: float = 300) -> list[dict]:
    """The REPORT lines of a subprocess running PRELUDE + script, which must exit cleanly."""
    done = subprocess.run([sys.executable, "-c", PRELUDE + textwrap.dedent(script), *map(str, args)],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    return [json.loads(line[len("REPORT "):]) for line in done.stdout.splitlines() if line.startswith("REPORT ")]


def test_threads_past_the_bound_are_refused():
    """threads= is at most MAX_THREADS_PER_CORE per core: more is a clear InputError, before any
    work is started."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))
    camera = pw.Camera.look_at(eye=(0.3, 0.3, 3.0), target=(0.3, 0.3, 0.0))
    assert thread_count(max_threads()) == max_threads()
    for threads in (max_threads() + 1, 1000, 10**9):
        with pytest.raises(pw.InputError, match=f"threads must be at most {max_threads()}"):
            pw.render(scene, camera, width=8, height=8, threads=threads, progress=False)
    assert pw.render(scene, camera, width=8, height=8, threads=max_threads(), progress=False).alpha.max() == 1.0


def test_renders_with_every_thread_count_keep_a_bounded_number_of_threads():
    """After renders with threads = 1 .. max_threads() (rasterized and ray cast, twice over), the
    process holds at most max_threads() threads more than before its first render, Python's and
    the OS's count alike: one pool serves every thread count."""
    reports = run_child("""
        scene, camera = demo_scene()
        before = (threading.active_count(), os_threads())
        for _ in range(2):
            for threads in range(1, parallel.max_threads() + 1):
                for visibility in ("raster", "raycast"):
                    pw.render(scene, camera, threads=threads, visibility=visibility, **SMALL)
        report(before=before, after=(threading.active_count(), os_threads()), pool=parallel.pool_threads(),
               most=parallel.max_threads())
        """)
    (counts,) = reports
    assert counts["pool"] <= counts["most"]
    for before, after in zip(counts["before"], counts["after"]):
        assert after - before <= counts["most"], counts


def test_a_thread_that_cannot_start_or_a_failed_launch_stops_the_launches_already_running():
    """A raster render on three threads when the pool holds one and no thread may start (a short
    raster call runs its first launch on the caller: the other two need a pool thread each): a
    pbrwarp.ResourceError (a PbrwarpError and a RuntimeError) from the raster's run_together;
    and a raster launch that fails on either side: its error. After each, the process uses no
    CPU (no launch left waiting for the other at a barrier) and renders the frame again,
    identical to the one before."""
    reports = run_child("""
        from pbrwarp import raster

        scene, camera = demo_scene()
        reference = pw.render(scene, camera, threads=1, visibility="raster", **SMALL).rgb
        pw.render(scene, camera, threads=1, visibility="raster", **SMALL)  # light buffers marked on reuse
        assert parallel.pool_threads() == 1, parallel.pool_threads()

        def after_failure(case, error):
            report(case=case, error=type(error).__name__, pbrwarp=isinstance(error, pw.PbrwarpError),
                   message=str(error), in_raster="run_together" in "".join(traceback.format_tb(error.__traceback__)),
                   cpu=cpu_used_over(1.0),
                   again=bool(np.array_equal(pw.render(scene, camera, threads=2, visibility="raster", **SMALL).rgb,
                                             reference)))

        start = threading.Thread.start
        def refuse(thread):
            raise RuntimeError("can't start new thread")
        threading.Thread.start = refuse
        try:
            pw.render(scene, camera, threads=3, visibility="raster", **SMALL)
        except Exception as error:
            threading.Thread.start = start
            after_failure("thread start", error)

        replay = raster._replay_launch
        for failing in (0, 1):
            def fail(recorded, key, kernel, inputs):
                if key == ("pipeline", failing):
                    time.sleep(0.05)  # the other launch waits at a barrier meanwhile
                    raise RuntimeError("simulated launch failure")
                replay(recorded, key, kernel, inputs)
            raster._replay_launch = fail
            try:
                pw.render(scene, camera, threads=2, visibility="raster", **SMALL)
            except Exception as error:
                raster._replay_launch = replay
                after_failure(f"launch {failing} fails", error)
        """)
    assert [r["case"] for r in reports] == ["thread start", "launch 0 fails", "launch 1 fails"], reports
    start, *launches = reports
    assert start["error"] == "ResourceError" and start["pbrwarp"] and start["in_raster"], start
    assert "could not start a thread" in start["message"], start
    for failure in launches:
        assert failure["error"] == "RuntimeError" and failure["message"] == "simulated launch failure", failure
    for failure in reports:
        assert failure["cpu"] < IDLE_CPU_SECONDS, failure
        assert failure["again"], failure


# Interrupts while a large frame (demo scene, 1024², spp 64, rasterized: some 10 s of work on two
# cores) is under way, in each part of it: the SIGINT is sent a moment after the part's first call
# into pbrwarp.parallel, and the interrupt's traceback must pass through that part.
INTERRUPTED = """
    import importlib, sys
    from pbrwarp import light_buffers, raster
    render = importlib.import_module("pbrwarp.render")  # pbrwarp.render is the function

    threads = int(sys.argv[1])
    LARGE = dict(width=1024, height=1024, spp=64, threads=threads, visibility="raster", progress=False)
    scene, camera = demo_scene()
    reference = pw.render(scene, camera, threads=threads, **SMALL).rgb

    def interrupted(module, name, delay, where, render_scene):
        # renders LARGE with a SIGINT sent ``delay`` s after module.name is first called
        original, timer, sent = getattr(module, name), [], []

        def send():
            sent.append(time.monotonic())
            os.kill(os.getpid(), signal.SIGINT)  # as Ctrl-C does

        def armed(*args, **kwargs):
            if not timer:
                timer.append(threading.Timer(delay, send))
                timer[0].start()
            return original(*args, **kwargs)

        setattr(module, name, armed)
        try:
            pw.render(render_scene, camera, **LARGE)
        except KeyboardInterrupt as interrupt:
            latency = time.monotonic() - sent[0]
            stack = "".join(traceback.format_tb(interrupt.__traceback__))
        else:
            raise SystemExit(f"{where}: the frame was finished before the interrupt")
        finally:
            setattr(module, name, original)
        cpu = cpu_used_over(1.0)
        clock = time.monotonic()
        again = pw.render(render_scene, camera, threads=threads, **SMALL).rgb
        report(where=where, latency=latency, cpu=cpu, seconds=time.monotonic() - clock,
               reached=f"in {where}" in stack, same=bool(np.array_equal(again, reference)))

    # a fresh scene: its light buffers are being built (the next render builds them again)
    interrupted(light_buffers, "run_all", 0.2, "build", demo_scene()[0])
    # another, its buffers built: their interiors are being marked, on their first reuse (the
    # marks made so far are kept, each valid, and the next render makes the others)
    marked = demo_scene()[0]
    pw.render(marked, camera, threads=threads, **SMALL)
    interrupted(light_buffers, "run_all", 0.1, "mark_interiors", marked)
    # the rest with the scene's caches built: the camera's samples, then its raster, then shading
    interrupted(raster, "run_all", 0.3, "_cached_sample_positions", scene)
    interrupted(raster, "run_together", 0.05, "visibility_buffer", scene)
    interrupted(render, "run_all", 0.5, "_run_with_progress", scene)
"""


@pytest.mark.parametrize("threads", [1, 2])
def test_an_interrupt_stops_every_part_of_a_render_at_once(threads):
    """SIGINT (Ctrl-C) during a large frame's light-buffer build, the marking of their interiors,
    sample positions, raster and shading: KeyboardInterrupt reaches the caller within INTERRUPT_SECONDS, the process then uses
    no CPU (nothing of the frame runs on), and the next frame comes at once and equals the one
    rendered before (an interrupted build is not kept as if complete). threads=1 too: the
    calling thread waits for its launch rather than running it, where no signal reaches it."""
    reports = run_child(INTERRUPTED, threads, timeout=600)
    assert [r["where"] for r in reports] == ["build", "mark_interiors", "_cached_sample_positions",
                                             "visibility_buffer", "_run_with_progress"], reports
    for part in reports:
        assert part["reached"], part
        assert part["latency"] < INTERRUPT_SECONDS, part
        assert part["cpu"] < IDLE_CPU_SECONDS, part
        assert part["seconds"] < NEXT_FRAME_SECONDS, part
        assert part["same"], part


@pytest.mark.parametrize("threads", [1, 2])
def test_the_command_line_stops_at_once_on_ctrl_c(tmp_path, threads):
    """``pbrwarp demo`` of a large frame, sent SIGINT once its progress bar shows the shading under
    way: it says "interrupted" within INTERRUPT_SECONDS and exits with status 130, writing no image,
    within EXIT_SECONDS (the process's teardown, freeing its memory, takes about a second)."""
    pytest.importorskip("tqdm")  # the bar tells when shading has begun
    out = tmp_path / "demo.png"
    process = subprocess.Popen([sys.executable, "-m", "pbrwarp", "demo", "-o", str(out), "--size", "1024x1024",
                                "--spp", "64", "--threads", str(threads)], cwd=ROOT, stderr=subprocess.PIPE)

    def read_until(text: bytes, seen: bytes, seconds: float) -> tuple[bytes, float]:
        deadline = time.monotonic() + seconds
        while text not in seen:
            assert time.monotonic() < deadline, seen.decode(errors="replace")
            if select.select([process.stderr], [], [], 0.01)[0]:
                chunk = os.read(process.stderr.fileno(), 4096)
                assert chunk, seen.decode(errors="replace")  # the process ended
                seen += chunk
        return seen, time.monotonic()

    try:
        seen, _ = read_until(b"render:", b"", 300)
        sent = time.monotonic()
        process.send_signal(signal.SIGINT)
        seen, said = read_until(b"interrupted", seen, 60)
        status = process.wait(timeout=60)
        ended = time.monotonic()
    finally:
        process.kill()
        process.wait()
    assert status == 130, seen.decode(errors="replace")
    assert said - sent < INTERRUPT_SECONDS, said - sent
    assert ended - sent < EXIT_SECONDS, ended - sent
    assert list(tmp_path.iterdir()) == []
