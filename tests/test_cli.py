"""The pbrwarp command line, run in-process through cli.main."""

import base64
import json
import re
import sys

import numpy as np
import pytest
import trimesh
from PIL import Image

import pbrwarp as pw
from pbrwarp.cli import main
from pbrwarp.meshes import DEMO_BACKGROUND, demo_scene


@pytest.fixture
def obj_file(tmp_path):
    path = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2).export(path)
    return path


@pytest.fixture
def out_dir(tmp_path):
    folder = tmp_path / "out"
    folder.mkdir()
    return folder


def test_demo_writes_png_of_requested_size(out_dir):
    out = out_dir / "demo.png"
    assert main(["demo", "-o", str(out), "--size", "64x36", "--spp", "1"]) == 0
    with Image.open(out) as im:
        assert im.size == (64, 36)
        assert im.mode == "RGB"
        assert np.asarray(im).max() > 100


def test_render_obj_adds_default_light_and_says_so(obj_file, out_dir, capsys):
    out = out_dir / "ball.png"
    assert main(["render", str(obj_file), "-o", str(out), "--size", "64x48"]) == 0
    err = capsys.readouterr().err
    assert "no lights" in err and "3 lux" in err
    pixels = np.asarray(Image.open(out))
    assert pixels.shape == (48, 64, 3)
    assert pixels[24, 32].mean() > 60  # the ball, lit, in the middle of the frame
    assert pixels[0, 0].max() == 0  # black background


def test_render_with_lights_camera_and_npy_output(obj_file, out_dir, capsys):
    out = out_dir / "ball.npy"
    code = main(["render", str(obj_file), "-o", str(out), "--size", "32x24", "--spp", "2",
                 "--camera", "-3,1,2,0,0,0", "--fov", "50", "--light", "point:-3,3,3:40:1,0.5,0.5",
                 "--light", "spot:0,4,0:0,-1,0:100:10,30", "--no-shadows", "--threads", "1",
                 "--background", "0.1,0.2,0.3"])
    assert code == 0
    assert "no lights" not in capsys.readouterr().err
    rgba = np.load(out)
    assert rgba.shape == (24, 32, 4) and rgba.dtype == np.float32
    assert np.all(np.isfinite(rgba))
    np.testing.assert_allclose(rgba[0, 0], [0.1, 0.2, 0.3, 0.0], atol=1e-6)
    centre = rgba[12, 16]
    assert centre[3] == 1.0 and centre[0] > centre[2]  # the reddish point light dominates


def test_shadow_maps_raster_and_quality_options(out_dir, capsys):
    out = out_dir / "demo.png"
    assert main(["demo", "-o", str(out), "--size", "48x36", "--shadow-maps", "--visibility", "raster",
                 "--quality", "fast", "--explain"]) == 0
    text = capsys.readouterr().out
    assert "shadow maps" in text and "visibility='raster'" in text and "implicit geometry" in text
    assert np.asarray(Image.open(out)).shape == (36, 48, 3)


def test_environment_option(out_dir, capsys):
    from assets import hdr

    venice = hdr("venice_sunset")
    out = out_dir / "demo.png"
    assert main(["demo", "-o", str(out), "--size", "48x27", "--env", str(venice), "--env-intensity", "0.5", "--explain"]) == 0
    assert "environment lighting" in capsys.readouterr().out
    assert np.asarray(Image.open(out))[0, 0].max() > 0  # the sky behind the spheres
    assert main(["demo", "-o", str(out), "--env", str(out_dir / "missing.hdr")]) == 2
    assert "missing.hdr" in capsys.readouterr().err


def test_transparent_png_has_alpha(obj_file, out_dir):
    out = out_dir / "ball.png"
    assert main(["render", str(obj_file), "-o", str(out), "--size", "32x24", "--transparent",
                 "--tonemap", "reinhard", "--exposure", "-1"]) == 0
    rgba = np.asarray(Image.open(out))
    assert rgba.shape == (24, 32, 4)
    assert rgba[0, 0, 3] == 0 and rgba[12, 16, 3] == 255


def test_help_exits_zero_and_documents_exit_statuses(capsys):
    assert main(["render", "--help"]) == 0
    text = capsys.readouterr().out
    assert "point:X,Y,Z:CANDELA" in text
    for words in ("--verbose", "exit status", "130", "143", "PBRWARP_VERBOSE"):
        assert words in text


BAD_INPUTS = {
    "missing input": (["render", "{missing}", "-o", "{out}"], "not found"),
    "size 0x10": (["render", "{obj}", "-o", "{out}", "--size", "0x10"], "WIDTHxHEIGHT|640x480"),
    "size abc": (["render", "{obj}", "-o", "{out}", "--size", "abc"], "WIDTHxHEIGHT"),
    "size 10x": (["demo", "-o", "{out}", "--size", "10x"], "WIDTHxHEIGHT"),
    "fov 0": (["render", "{obj}", "-o", "{out}", "--fov", "0"], "between 0 and 180"),
    "fov 180": (["render", "{obj}", "-o", "{out}", "--fov", "180"], "between 0 and 180"),
    "negative light": (["render", "{obj}", "-o", "{out}", "--light", "point:0,0,5:-10"], ">= 0"),
    "short light position": (["render", "{obj}", "-o", "{out}", "--light", "dir:0,-1:3"], "3 comma-separated"),
    "unknown light type": (["render", "{obj}", "-o", "{out}", "--light", "laser:0,0,0:1"], "point, dir, spot, sphere or rect"),
    "bad spot cone": (["render", "{obj}", "-o", "{out}", "--light", "spot:0,1,0:0,-1,0:5:40,20"], "INNER <= OUTER"),
    "unknown tonemap": (["render", "{obj}", "-o", "{out}", "--tonemap", "filmic"], "invalid choice"),
    "missing folder": (["render", "{obj}", "-o", "{missing_dir_out}"], "does not exist"),
    "unknown extension": (["demo", "-o", "{out_xyz}"], "unknown image extension"),
    "spp 0": (["demo", "-o", "{out}", "--spp", "0"], ">= 1"),
    "eye is target": (["render", "{obj}", "-o", "{out}", "--camera", "1,1,1,1,1,1"], "must differ"),
    "transparent jpeg": (["render", "{obj}", "-o", "{out_jpg}", "--transparent"], "transparency"),
    "no command": ([], "required"),
    "not a scene": (["render", "{text}", "-o", "{out}"], "cannot read|contains no triangles"),
    # 2^2000 overflows a float; the exposure range keeps 2^EV finite in float32 both ways
    "exposure 2000": (["render", "{obj}", "-o", "{out}", "--exposure", "2000"], "from -64 to 64"),
    "exposure -65": (["demo", "-o", "{out}", "--exposure", "-65"], "from -64 to 64"),
    "exposure nan": (["demo", "-o", "{out}", "--exposure", "nan"], "from -64 to 64"),
    "negative env intensity": (["demo", "-o", "{out}", "--env-intensity", "-1"], "from 0 to"),
    # finite in float64 but not in the float32 the kernels compute in
    "background beyond float32": (["demo", "-o", "{out}", "--background", "1e39,0,0"], "finite numbers"),
    "camera beyond float32": (["render", "{obj}", "-o", "{out}", "--camera", "1e39,0,0,0,0,0"], "finite numbers"),
    "light beyond float32": (["render", "{obj}", "-o", "{out}", "--light", "point:1e39,0,0:5"], "finite numbers"),
    "fov beyond float32": (["render", "{obj}", "-o", "{out}", "--fov", "1e39"], "between 0 and 180"),
}


@pytest.mark.parametrize("name", list(BAD_INPUTS))
def test_bad_input_is_one_line_exit_2_and_no_output(name, obj_file, out_dir, tmp_path, capsys):
    args, expected = BAD_INPUTS[name]
    (tmp_path / "notes.obj").write_text("this is not a mesh\n")
    values = {
        "obj": str(obj_file), "missing": str(tmp_path / "nope.obj"), "out": str(out_dir / "x.png"),
        "missing_dir_out": str(tmp_path / "no-such-folder" / "x.png"), "out_xyz": str(out_dir / "x.xyz"),
        "out_jpg": str(out_dir / "x.jpg"), "text": str(tmp_path / "notes.obj"),
    }
    code = main([a.format(**values) for a in args])
    assert code == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("pbrwarp: error: ")
    assert "Traceback" not in captured.err and captured.out == ""
    assert re.search(expected, lines[0]), lines[0]
    assert list(out_dir.iterdir()) == []
    assert not (tmp_path / "no-such-folder").exists()


def test_demo_scene_renders_finite_and_lit():
    scene, camera = demo_scene()
    assert len(scene.lights) >= 2
    frame = pw.render(scene, camera, width=96, height=54, spp=1, background=DEMO_BACKGROUND, progress=False)
    assert np.all(np.isfinite(frame.rgb))
    assert 0.25 < frame.alpha.mean() < 0.9  # spheres and torus fill much of the frame, not all
    srgb = frame.to_srgb8()
    hit = frame.alpha > 0
    assert srgb[hit].mean() > 40
    # well exposed: almost nothing clips to white under the default ACES tone map
    assert np.mean(srgb.min(axis=2) == 255) < 0.01


def test_python_m_pbrwarp_runs_from_the_checkouts_root_without_an_editable_install(tmp_path):
    """The README's first set-up command runs ``python -m pbrwarp`` in the checkout's root, where
    the local pbrwarp/ folder shadows the installed package and lacks the kernels/ and meshes/
    that pyproject.toml maps into it: the package loads them from the checkout. Here with the
    editable install's finder removed, as after a plain ``pip install .``."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(pw.__file__).resolve().parent.parent
    program = (
        "import runpy, sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower()]\n"
        "sys.path.insert(0, '')\n"
        "import pbrwarp.kernels, pbrwarp.meshes\n"
        "print('loaded:', pbrwarp.kernels.__file__, pbrwarp.meshes.__file__, flush=True)\n"
        f"sys.argv = ['pbrwarp', 'demo', '-o', {str(tmp_path / 'demo.png')!r}, '--size', '64x36', '--spp', '1']\n"
        "runpy.run_module('pbrwarp', run_name='__main__', alter_sys=True)\n")
    done = subprocess.run([sys.executable, "-c", program], cwd=root, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    loaded = done.stdout.split("loaded:")[-1].split()[:2]
    assert loaded == [str(root / "kernels" / "__init__.py"), str(root / "meshes" / "__init__.py")]
    assert Image.open(tmp_path / "demo.png").size == (64, 36)


def fail_render_with(monkeypatch, error):
    """Make the CLI's render raise ``error`` (the CLI looks render up in its module when it runs)."""
    def render(*args, **kwargs):
        raise error

    monkeypatch.setattr(sys.modules["pbrwarp.render"], "render", render)


@pytest.mark.parametrize("error", [
    MemoryError("Unable to allocate 3.3 GiB for an array with shape (30000, 30000) and data type float32"),
    RuntimeError("Failed to allocate 3221225472 bytes on device 'cpu'"),  # Warp's wording
])
def test_out_of_memory_is_one_line_exit_2(error, out_dir, monkeypatch, capsys):
    fail_render_with(monkeypatch, error)
    assert main(["demo", "-o", str(out_dir / "x.png")]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert captured.err.startswith("pbrwarp: error: not enough memory (") and str(error) in captured.err
    assert "--size or --spp" in captured.err
    assert list(out_dir.iterdir()) == []


def test_internal_error_is_one_line_exit_1_and_verbose_shows_the_traceback(out_dir, monkeypatch, capsys):
    fail_render_with(monkeypatch, ZeroDivisionError("float division by zero"))
    assert main(["demo", "-o", str(out_dir / "x.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("pbrwarp: internal error: ZeroDivisionError: float division by zero")
    assert "--verbose" in err
    assert main(["demo", "-o", str(out_dir / "x.png"), "--verbose"]) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last):" in err and "in render" in err
    assert err.splitlines()[-1].startswith("pbrwarp: internal error: ZeroDivisionError")
    assert list(out_dir.iterdir()) == []


def test_warnings_about_the_users_file_show_as_one_line(out_dir, tmp_path, capsys):
    """A glTF camera pbrwarp cannot use is named in a warning, on one line, and the render goes on."""
    triangle = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    document = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 3]}],
        "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": len(triangle)}],
        "buffers": [{"byteLength": len(triangle),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(triangle).decode()}],
    }
    model = tmp_path / "triangle.gltf"
    model.write_text(json.dumps(document))
    assert main(["render", str(model), "-o", str(out_dir / "t.png"), "--size", "16x16"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "orthographic" in line]
    assert len(warned) == 1 and warned[0].startswith("pbrwarp: warning: ") and "triangle.gltf" in warned[0]
