"""Frame.save: atomic, with the file mode the user's umask asks for, never touching the umask."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import pbrwarp as pw

ROOT = Path(pw.__file__).resolve().parent.parent


def grey_frame(height=6, width=8) -> pw.Frame:
    return pw.Frame(rgb=np.full((height, width, 3), 0.18, np.float32), depth=np.ones((height, width), np.float32),
                    normal=np.zeros((height, width, 3), np.float32), alpha=np.ones((height, width), np.float32))


def test_saved_files_get_0666_less_the_umask():
    """Each umask is set in a fresh process, so the test's own umask stays as it was."""
    program = (
        "import os, sys, tempfile, numpy as np, pbrwarp as pw\n"
        "frame = pw.Frame(rgb=np.zeros((2, 2, 3), np.float32), depth=np.ones((2, 2), np.float32),\n"
        "                 normal=np.zeros((2, 2, 3), np.float32), alpha=np.ones((2, 2), np.float32))\n"
        "folder = tempfile.mkdtemp()\n"
        "for mask in (0o022, 0o077, 0o002, 0o027, 0o000):\n"
        "    os.umask(mask)\n"
        "    for name in ('x.png', 'x.npy'):\n"
        "        path = os.path.join(folder, f'{mask:03o}-{name}')\n"
        "        frame.save(path)\n"
        "        print(f'{mask:o} {os.stat(path).st_mode & 0o777:o}')\n"
        "        frame.save(path)  # replacing a file: the new one gets the same mode\n"
        "        print(f'{mask:o} {os.stat(path).st_mode & 0o777:o}')\n")
    done = subprocess.run([sys.executable, "-c", program], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split()
    masks, modes = [int(m, 8) for m in lines[0::2]], [int(m, 8) for m in lines[1::2]]
    assert len(masks) == 20
    for mask, mode in zip(masks, modes):
        assert mode == 0o666 & ~mask, (oct(mask), oct(mode))


def test_save_never_calls_umask(tmp_path, monkeypatch):
    """Setting the umask, even for an instant, would let a file another thread creates then get
    the wrong mode: save leaves it to the kernel."""
    def umask(mask):
        raise AssertionError("Frame.save called os.umask")

    monkeypatch.setattr(os, "umask", umask)
    frame = grey_frame()
    for name in ("x.png", "x.npy", "x.jpg"):
        frame.save(tmp_path / name)
    assert sorted(os.listdir(tmp_path)) == ["x.jpg", "x.npy", "x.png"]


def test_failed_write_leaves_the_old_file_and_no_temporary_file(tmp_path, monkeypatch):
    out = tmp_path / "x.png"
    grey_frame().save(out)
    before = out.read_bytes()

    def broken_save(self, fp, format=None, **params):
        fp.write(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(OSError, match="disk full"):
        grey_frame(3, 3).save(out)
    assert os.listdir(tmp_path) == ["x.png"] and out.read_bytes() == before


@pytest.mark.parametrize("kind", ["file", "symlink"])
def test_temporary_file_never_overwrites_an_existing_file(kind, tmp_path, monkeypatch):
    """The hidden file is created exclusively: a file, or a link to one, already at its name is left alone."""
    import secrets

    target = tmp_path / "target.txt"
    target.write_text("someone else's")
    taken = tmp_path / ".pbrwarp-0000000000000000.png"
    if kind == "file":
        taken.write_text("someone else's")
    else:
        taken.symlink_to(target)
    monkeypatch.setattr(secrets, "token_hex", lambda n: "0" * 2 * n)
    with pytest.raises(FileExistsError):
        grey_frame().save(tmp_path / "x.png")
    assert taken.read_text() == "someone else's" and target.read_text() == "someone else's"
    assert sorted(os.listdir(tmp_path)) == sorted([taken.name, target.name])


@pytest.mark.parametrize("exposure", [2000, -65, 64.5, float("nan"), float("inf"), 10**400])
def test_exposure_out_of_range_is_refused(exposure, tmp_path):
    """2^2000 overflows; the range keeps 2^EV and 2^-EV finite in the float32 the tone map uses."""
    frame = grey_frame()
    with pytest.raises(pw.InputError, match="from -64 to 64 stops"):
        frame.save(tmp_path / "x.png", exposure=exposure)
    with pytest.raises(pw.InputError, match="from -64 to 64 stops"):
        frame.to_srgb8(exposure=exposure)
    assert os.listdir(tmp_path) == []


def test_exposure_limits_give_finite_scales():
    """At +-64 stops a mid grey is still tone mapped, to white and to black."""
    frame = grey_frame()
    assert frame.to_srgb8(exposure=64).min() == 255
    assert frame.to_srgb8(exposure=-64).max() == 0
    with pytest.raises(pw.InputTypeError):
        frame.to_srgb8(exposure="bright")
