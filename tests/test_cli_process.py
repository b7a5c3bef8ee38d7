"""pbrwarp as a user runs it, in a fresh process: a quiet start, and a command line that ends
every failure (signals, memory) with one line, a documented exit status and no file left behind."""

import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from PIL import Image

import pbrwarp as pw

ROOT = Path(pw.__file__).resolve().parent.parent  # the checkout, so that its pbrwarp is imported
TIMEOUT = 600

BANNER = re.compile(r"^Warp \S+ initialized:", re.MULTILINE)
MODULE_LOAD = re.compile(r"^Module \S+ .*load on device 'cpu'", re.MULTILINE)

RENDER_A_SPHERE = (
    "import pbrwarp as pw, trimesh\n"
    "scene = pw.Scene()\n"
    "scene.add_mesh(trimesh.creation.icosphere(subdivisions=1))\n"
    "scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=3))\n"
    "frame = pw.render(scene, pw.Camera.frame(scene), width=16, height=16, progress=False)\n"
    "assert frame.alpha.max() == 1\n")


def environment(verbose=None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PBRWARP_VERBOSE"}
    if verbose is not None:
        env["PBRWARP_VERBOSE"] = verbose
    return env


def python(*args, verbose=None, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=environment(verbose), capture_output=True,
                          text=True, timeout=TIMEOUT, **kwargs)


# ---------------------------------------------------------------------- a quiet start
@pytest.mark.parametrize("verbose", [None, "0"])
def test_import_and_render_print_nothing(verbose):
    done = python("-c", RENDER_A_SPHERE, verbose=verbose)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "" and done.stderr == ""


@pytest.mark.parametrize("value,verbose", [("1", True), ("yes", True), ("on", True), ("TRUE", True),
                                           ("", False), ("0", False), ("false", False), ("no", False), ("off", False)])
def test_environment_variable_values(value, verbose, monkeypatch):
    from pbrwarp.startup import verbose_from_environment

    monkeypatch.setenv("PBRWARP_VERBOSE", value)
    assert verbose_from_environment() is verbose


def test_environment_variable_brings_warps_messages_back():
    done = python("-c", RENDER_A_SPHERE, verbose="1")
    assert done.returncode == 0, done.stderr
    assert BANNER.search(done.stdout), done.stdout
    assert MODULE_LOAD.search(done.stdout), done.stdout  # kernels load (from the cache or compiled)


def test_real_messages_while_warp_starts_still_show():
    """Only Warp's CUDA-driver note is held back from what is written to stderr while Warp starts."""
    program = (
        "import os, warp as wp\n"
        "start = wp.init\n"
        "def init():\n"
        "    os.write(2, b'Warp CUDA warning: Could not find or load the NVIDIA CUDA driver. GPU execution...\\n'\n"
        "                b'something real\\n')\n"
        "    start()\n"
        "wp.init = init\n"
        "import pbrwarp\n")
    done = python("-c", program)
    assert done.returncode == 0, done.stderr
    assert done.stderr == "something real\n" and done.stdout == ""


def test_import_without_a_stderr():
    """Python started with descriptor 2 closed has no sys.stderr; the quiet start copes."""
    done = subprocess.run([sys.executable, "-c", "import pbrwarp; print('imported')"], cwd=ROOT, env=environment(),
                          stdout=subprocess.PIPE, text=True, timeout=TIMEOUT, preexec_fn=lambda: os.close(2))
    assert done.returncode == 0 and done.stdout == "imported\n"


def test_warnings_still_show_after_a_quiet_import():
    done = python("-c", "import warnings, pbrwarp; warnings.warn('about your file')")
    assert "UserWarning: about your file" in done.stderr


def test_cli_render_and_demo_are_quiet(tmp_path):
    import trimesh

    model = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=1).export(model)
    demo = python("-m", "pbrwarp", "demo", "-o", str(tmp_path / "demo.png"), "--size", "32x18")
    assert demo.returncode == 0, demo.stderr
    assert demo.stdout == "" and demo.stderr == ""
    render = python("-m", "pbrwarp", "render", str(model), "-o", str(tmp_path / "ball.png"), "--size", "32x24",
                    "--light", "dir:0,0,-1:3")
    assert render.returncode == 0, render.stderr
    assert render.stdout == "" and render.stderr == ""
    assert Image.open(tmp_path / "ball.png").size == (32, 24)


@pytest.mark.parametrize("verbose", ["option", "environment"])
def test_cli_verbose_brings_warps_messages_back(verbose, tmp_path):
    args = ["-m", "pbrwarp", "demo", "-o", str(tmp_path / "demo.png"), "--size", "32x18"]
    done = python(*args, "--verbose") if verbose == "option" else python(*args, verbose="1")
    assert done.returncode == 0, done.stderr
    assert BANNER.search(done.stdout) and MODULE_LOAD.search(done.stdout), done.stdout


@pytest.mark.parametrize("args,verbose", [(["demo", "-o", "x.png"], False), (["-v", "demo", "-o", "x.png"], True),
                                          (["demo", "-o", "x.png", "--verbose"], True),
                                          (["render", "m.glb", "-o", "x.png", "-v"], True)])
def test_verbose_option_before_or_after_the_command(args, verbose):
    from pbrwarp.cli import build_parser

    assert build_parser().parse_args(args).verbose is verbose


# ---------------------------------------------------------------------- failures
def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def cli_program(hook: str, args: list[str]) -> str:
    """Python that applies ``hook`` (which prints a line when the moment to signal comes) and runs the CLI."""
    return f"import sys\n{hook}\nfrom pbrwarp.cli import main\nsys.exit(main({args!r}))\n"


# The save writes part of the image into its hidden file, then waits there.
SLOW_SAVE = """
import time
from PIL import Image
def save(self, fp, format=None, **params):
    fp.write(b"\\x89PNG\\r\\n\\x1a\\n part of an image")
    fp.flush()
    print("saving", flush=True)
    time.sleep(120)
Image.Image.save = save
"""

# The render starts, then takes its time (how fast a real render stops is render()'s concern).
SLOW_RENDER = """
import time
import pbrwarp
def render(*args, **kwargs):
    print("rendering", flush=True)
    time.sleep(120)
sys.modules["pbrwarp.render"].render = render
"""

SIGNALS = {"Ctrl-C": (signal.SIGINT, 130, "pbrwarp: interrupted"),
           "SIGTERM": (signal.SIGTERM, 143, "pbrwarp: terminated")}


def signal_when(program: str, ready: str, signum, folder: Path, expect_hidden_file: bool):
    process = subprocess.Popen([sys.executable, "-c", program], cwd=ROOT, env=environment(), text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        line = process.stdout.readline()
        assert line.strip() == ready, (line, process.stderr.read() if process.poll() is not None else "")
        if expect_hidden_file:
            assert [n for n in leftovers(folder) if n.startswith(".pbrwarp-")]  # the partial file is there
        process.send_signal(signum)
        out, err = process.communicate(timeout=TIMEOUT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, out, err


@pytest.mark.parametrize("name", list(SIGNALS))
@pytest.mark.parametrize("phase", ["saving", "rendering"])
def test_signal_leaves_no_file(name, phase, tmp_path):
    signum, status, message = SIGNALS[name]
    slow = SLOW_SAVE if phase == "saving" else SLOW_RENDER
    program = cli_program(slow, ["demo", "-o", str(tmp_path / "demo.png"), "--size", "32x18"])
    code, out, err = signal_when(program, phase, signum, tmp_path, expect_hidden_file=phase == "saving")
    assert (code, err) == (status, message + "\n"), err
    assert out == "" and leftovers(tmp_path) == []


def test_sigterm_during_a_real_save_removes_the_hidden_file(tmp_path):
    """No hook in the save: a large noisy PNG takes seconds to encode, in chunks between which
    the CLI's SIGTERM handler raises; the save's cleanup removes its hidden file on the way out."""
    out = tmp_path / "noise.png"
    program = (
        "import sys, numpy as np, pbrwarp as pw\n"
        "from pbrwarp.cli import Terminated, _sigterm_raises_terminated\n"
        "rng = np.random.default_rng(1)\n"
        "n = 2048\n"
        "frame = pw.Frame(rgb=rng.random((n, n, 3), dtype=np.float32), depth=np.ones((n, n), np.float32),\n"
        "                 normal=np.zeros((n, n, 3), np.float32), alpha=np.ones((n, n), np.float32))\n"
        "try:\n"
        "    with _sigterm_raises_terminated():\n"
        f"        frame.save({str(out)!r})\n"
        "except Terminated:\n"
        "    sys.exit(143)\n")
    process = subprocess.Popen([sys.executable, "-c", program], cwd=ROOT, env=environment(), text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + TIMEOUT
        while not any(n.startswith(".pbrwarp-") for n in leftovers(tmp_path)):
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.001)
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=TIMEOUT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 143 and "Traceback" not in err, err
    assert leftovers(tmp_path) == []


def test_out_of_memory_under_an_address_space_limit_is_one_line_exit_2(tmp_path):
    """16384 x 16384 pixels at 64 samples do not fit in 3 GiB: a clear line, not a traceback or a crash."""
    def limit_memory():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    done = python("-m", "pbrwarp", "demo", "-o", str(tmp_path / "big.png"), "--size", "16384x16384", "--spp", "64",
                  preexec_fn=limit_memory)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("pbrwarp: error: "), done.stderr
    assert "memory" in done.stderr or "16384" in done.stderr
    assert leftovers(tmp_path) == []
