"""Render sizes within the limits the kernels index with (docs/limits.md): anything beyond them,
or needing more memory than the frame may take, is refused before anything is allocated."""

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp import validate
from pbrwarp.raster import sample_positions
from pbrwarp.render import _stratification_grid

from scenes import head_on_camera, quad


def simple_scene():
    scene = pw.Scene()
    scene.add_mesh(quad())
    return scene


@pytest.mark.parametrize("size,spp,match", [
    ((4, 4), 2**31, "46340 samples per pixel"),        # wrapped to a negative int32: a black frame
    ((4, 4), 2**32, "46340 samples per pixel"),        # wrapped to 0: NaN alpha
    ((4, 4), 2**32 + 1, "46340 samples per pixel"),    # wrapped to 1
    ((1, 1), validate.MAX_SPP + 1, "46340 samples per pixel"),
    ((65537, 1), 1, "65536 pixels a side"),
    ((1, 65537), 1, "65536 pixels a side"),
    ((65536, 32769), 1, "more than 2\\^31 - 1"),
    ((65536, 1), 4097, "samples a row"),
])
def test_sizes_beyond_the_kernels_int32_indices_are_refused(size, spp, match):
    for call in (lambda: pw.render(simple_scene(), head_on_camera(), width=size[0], height=size[1], spp=spp,
                                   visibility="raycast", aovs=False, progress=False),
                 lambda: pw.explain(simple_scene(), width=size[0], height=size[1], spp=spp, visibility="raycast",
                                    aovs=False)):
        with pytest.raises(pw.InputError, match=match):
            call()


def test_the_limits_are_what_the_kernels_index_with():
    """Each limit is the largest value its int32 quantity allows."""
    assert validate.MAX_SAMPLES == np.iinfo(np.int32).max
    # a visibility-buffer or sample-position row of width * spp 8-byte entries: a byte stride
    assert 8 * validate.MAX_ROW_SAMPLES <= np.iinfo(np.int32).max < 8 * (validate.MAX_ROW_SAMPLES + 1)
    # the sampler's a i + b with a <= n + 1, i and b <= n - 1, n <= spp
    n = validate.MAX_SPP
    assert (n + 1) * (n - 1) + n - 1 <= np.iinfo(np.int32).max < (n + 2) * n + n


@pytest.mark.parametrize("spp", [46337, validate.MAX_SPP])
def test_samples_stay_stratified_up_to_the_spp_limit(spp):
    """46337 is the largest prime below the limit: a 1 x 46337 grid, so the sampler permutes
    46337 strata, its int32 products at their largest. Every pixel's samples keep one per strip
    of width 1/spp in x and in y (multi-jittered sampling's guarantee)."""
    grid_m, grid_n = _stratification_grid(spp)
    for seed in range(8):
        xy = sample_positions(1, 1, spp, grid_m, grid_n, seed).numpy().reshape(-1, 2).astype(np.float64)
        assert xy.min() >= 0.0 and xy.max() < 1.0
        for axis in (0, 1):
            # sorted, sample k lies in strip k (within float32's rounding of x, ~3e-8)
            strips = np.sort(xy[:, axis]) * spp - np.arange(spp)
            assert np.all((strips > -0.01) & (strips < 1.01)), (seed, axis)


def test_a_frame_at_the_spp_limit_renders():
    scene = simple_scene()
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=np.pi))
    frame = pw.render(scene, head_on_camera(), width=1, height=1, spp=validate.MAX_SPP, progress=False)
    np.testing.assert_allclose(frame.rgb[0, 0], 1.0, rtol=1e-4)  # a white Lambert quad under pi lux
    np.testing.assert_allclose(frame.alpha[0, 0], 1.0, rtol=1e-6)  # every sample hit


def test_frame_bytes_counts_the_buffers_a_render_allocates():
    width, height, spp = 7, 5, 6
    frame = pw.render(simple_scene(), head_on_camera(), width=width, height=height, progress=False)
    outputs = frame.rgb.nbytes + frame.alpha.nbytes + frame.depth.nbytes + frame.normal.nbytes + frame.albedo.nbytes
    assert validate.frame_bytes(width, height, 1, aovs=True, rasterized=False) == outputs
    assert validate.frame_bytes(width, height, 1, aovs=False, rasterized=False) == frame.rgb.nbytes + frame.alpha.nbytes
    grid_m, grid_n = _stratification_grid(spp)
    positions = sample_positions(width, height, spp, grid_m, grid_n, 0)
    visibility_entries = width * height * spp * np.dtype(np.uint64).itemsize
    assert (validate.frame_bytes(width, height, spp, aovs=False, rasterized=True)
            - validate.frame_bytes(width, height, spp, aovs=False, rasterized=False)
            == positions.capacity + visibility_entries)


def test_memory_limit_is_a_share_of_this_machines_memory():
    limit, bound = validate.memory_limit()
    if limit is None:
        pytest.skip("this platform reports no memory size")
    import os

    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    assert 0 < limit <= validate.MEMORY_SHARE * physical
    assert bound


def test_a_frame_larger_than_memory_is_refused_naming_its_size_and_memory():
    limit, _ = validate.memory_limit()
    if limit is None:
        pytest.skip("this platform reports no memory size")
    # within every index limit, but needing more than the memory limit (32 bytes a pixel)
    side = min(int(np.sqrt(limit / 32)) + 1024, 46000)
    if validate.frame_bytes(side, side, 1, rasterized=False) <= limit:
        pytest.skip("this machine has more memory than a 46000² frame needs")
    with pytest.raises(pw.InputError, match=f"{side}x{side}.*GiB of buffers"):
        pw.render(simple_scene(), head_on_camera(), width=side, height=side, visibility="raycast", progress=False)


def test_per_sample_buffers_count_unless_ray_cast():
    """The raster's per-sample buffers (16 bytes a sample) count against the memory limit: a
    frame that fits ray cast may not fit rasterized; the error then suggests ray casting."""
    limit, _ = validate.memory_limit()
    if limit is None:
        pytest.skip("this platform reports no memory size")
    spp = 256
    side = int(np.sqrt(limit / (16 * spp))) + 64
    assert validate.frame_bytes(side, side, spp, rasterized=False) < limit < validate.frame_bytes(side, side, spp)
    if side * side * spp > validate.MAX_SAMPLES:
        pytest.skip("this machine has more memory than 2^31 samples need")
    with pytest.raises(pw.InputError, match="raycast"):
        pw.explain(simple_scene(), width=side, height=side, spp=spp)
    pw.explain(simple_scene(), width=side, height=side, spp=spp, visibility="raycast")


HUGE_FRAMES = textwrap.dedent("""
    import resource, sys
    import numpy as np
    import pbrwarp as pw
    from pbrwarp import validate

    scene = pw.Scene()
    scene.add_mesh(pw.Primitive(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]),
                                pw.Material()))
    camera = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0))
    pw.render(scene, camera, width=8, height=8, progress=False)  # kernels loaded
    used = validate._proc_status_bytes("VmSize")
    resource.setrlimit(resource.RLIMIT_AS, (used + (1 << 30), resource.RLIM_INFINITY))
    for width, height, spp in ((100000, 100000, 64), (8000, 8000, 4)):
        try:
            pw.render(scene, camera, width=width, height=height, spp=spp, progress=False)
        except pw.InputError as error:
            print("refused:", error)
        else:
            sys.exit(f"{width}x{height} at spp {spp} rendered")
    frame = pw.render(scene, camera, width=64, height=64, spp=4, progress=False)
    print("rendered:", float(frame.alpha.mean()))
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs Linux's /proc and RLIMIT_AS")
def test_huge_frames_are_refused_before_allocating_under_an_address_space_limit():
    """100000² at spp 64 (9.6 TiB) and 8000² at spp 4 (6 GiB, within the machine's memory but
    not the 1 GiB left under ``ulimit -v``) are refused with an InputError naming the size and
    the memory, not Warp's "Failed to allocate" or a MemoryError; a small frame then renders."""
    root = Path(pw.__file__).resolve().parent.parent
    done = subprocess.run([sys.executable, "-c", HUGE_FRAMES], cwd=root, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
    refusals = [line for line in done.stdout.splitlines() if line.startswith("refused:")]
    assert len(refusals) == 2, done.stdout
    assert "100000x100000" in refusals[0] and "TiB of buffers" in refusals[0]
    assert "8000x8000" in refusals[1] and "GiB of buffers" in refusals[1] and "ulimit -v" in refusals[1]
    assert "rendered: " in done.stdout
