"""pbrwarp as a user runs it, in a fresh process: a quiet start."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

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


def test_warnings_still_show_after_a_quiet_import():
    done = python("-c", "import warnings, pbrwarp; warnings.warn('about your file')")
    assert "UserWarning: about your file" in done.stderr
