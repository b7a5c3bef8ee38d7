"""Progressive rendering (render(time_budget=, target_error=), pw.Accumulator): passes add up to
one render, the variance estimate is unbiased against a pixel of known variance, budgets and
targets stop where documented, and the state survives threads."""

import math
import threading

import numpy as np
import pytest

import pbrwarp as pw
import pbrwarp.progressive as progressive
from pbrwarp.errors import InputError, InputTypeError
from pbrwarp.meshes import cornell_box

OPTIONS = dict(width=12, height=12, integrator="path", max_bounces=3, progress=False)


@pytest.fixture(scope="module")
def box():
    return cornell_box()


def half_emitter_scene():
    """An emissive half-plane x < 0 (radiance 1, black and non-reflecting) in front of the head-on
    camera of an image 9 pixels wide: the middle column's centres look at its edge, so half of
    each of its pixels sees radiance 1 and half the black background. One sample there is 1 with
    probability 1/2, else 0: variance 1/4."""
    scene = pw.Scene()
    positions = np.array([[-10.0, -10.0, 0.0], [0.0, -10.0, 0.0], [0.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])
    material = pw.Material(base_color=(0.0, 0.0, 0.0), metallic=0.0, specular=0.0, emissive=(1.0, 1.0, 1.0))
    scene.add_mesh(pw.Primitive(positions, np.array([[0, 1, 2], [0, 2, 3]]), material))
    camera = pw.Camera.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov_y=30.0)
    return scene, camera


def test_passes_add_up_to_one_render_of_all_their_samples(box):
    scene, camera = box
    one = pw.render(scene, camera, spp=8, seed=3, **OPTIONS)
    accumulator = pw.Accumulator(scene, camera, spp=3, seed=3, **OPTIONS)
    assert accumulator.spp == 0 and accumulator.frame is None
    accumulator.add()
    frame = accumulator.add(spp=5)  # passes of any size
    assert frame is accumulator.frame and accumulator.spp == frame.spp == one.spp == 8
    np.testing.assert_allclose(frame.rgb, one.rgb, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(frame.alpha, one.alpha, rtol=1e-6)
    np.testing.assert_allclose(frame.albedo, one.albedo, rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(frame.depth, one.depth)
    # normals: the passes' unit normals, hit-weighted, are one render's where a pixel sees one plane
    one_plane = np.max(np.abs(one.normal), axis=-1) > 1 - 1e-6  # the box's walls are axis-aligned
    assert one_plane.mean() > 0.3
    np.testing.assert_allclose(frame.normal[one_plane], one.normal[one_plane], atol=1e-5)
    assert frame.variance.shape == one.rgb.shape and np.all(np.isfinite(frame.variance))
    assert one.variance is None and one.relative_error() is None  # a plain render: no estimate


@pytest.mark.parametrize("pass_sizes", [(4,) * 6, (1, 2, 8, 3, 6, 4)], ids=["equal", "unequal"])
def test_the_variance_estimate_is_unbiased_on_a_pixel_of_known_variance(pass_sizes):
    """The middle column's per-sample variance is 1/4, so that of its mean over N samples is
    1/(4N). The estimates of many pixels and seeds average to it within four standard errors of
    their own spread, for equal and unequal passes; pixels the emitter covers or misses entirely
    have variance 0."""
    scene, camera = half_emitter_scene()
    passes = len(pass_sizes)
    samples = sum(pass_sizes)
    estimates, means = [], []
    for seed in range(12):
        accumulator = pw.Accumulator(scene, camera, width=9, height=64, spp=1, seed=seed, max_bounces=0,
                                     progress=False)
        for size in pass_sizes:
            frame = accumulator.add(spp=size)
        estimates.append(frame.variance[:, 4, 0].astype(np.float64))
        means.append(frame.rgb[:, 4, 0].astype(np.float64))
        np.testing.assert_allclose(frame.variance[:, [0, 1, 2, 3, 5, 6, 7, 8]], 0.0, atol=1e-12)
    estimates, means = np.concatenate(estimates), np.concatenate(means)
    expected = 0.25 / samples
    standard_error = estimates.std(ddof=1) / math.sqrt(estimates.size)
    assert abs(estimates.mean() - expected) < 4 * standard_error, (estimates.mean(), expected, standard_error)
    # the test tells a bias of 1/passes (dividing by passes, not passes - 1) from noise
    assert 4 * standard_error < expected / passes / 1.5
    # the means themselves scatter as the estimate says
    assert abs(means.var(ddof=1) / expected - 1.0) < 0.2


class FakeClock:
    """time.perf_counter for pbrwarp.progressive advancing a second per reading: every pass then
    seems to take about a second, whatever the machine's load."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        self.now += 1.0
        return self.now


def test_a_time_budget_adds_passes_while_the_next_fits(box, monkeypatch):
    """With passes of a second each (a fake clock read once before the first pass and once after
    each), a 5.5 s budget holds five: after the k-th, k seconds have passed and another would end
    at k + 1, so the sixth (ending at 6) does not fit."""
    scene, camera = box
    monkeypatch.setattr(progressive, "time", FakeClock())
    frame = pw.render(scene, camera, spp=2, time_budget=5.5, **OPTIONS)
    assert frame.spp == 5 * 2
    np.testing.assert_allclose(frame.rgb, pw.render(scene, camera, spp=10, **OPTIONS).rgb, rtol=1e-5, atol=1e-7)


def test_the_first_pass_always_completes(box):
    scene, camera = box
    frame = pw.render(scene, camera, spp=3, time_budget=1e-9, **OPTIONS)
    assert frame.spp == 3
    assert np.all(np.isinf(frame.variance)) and frame.relative_error() == math.inf  # unknown from one pass


def test_a_target_error_stops_at_the_first_pass_that_meets_it(box):
    scene, camera = box
    target = 0.2
    frame = pw.render(scene, camera, spp=2, target_error=target, seed=5, **OPTIONS)
    assert frame.relative_error() <= target
    accumulator = pw.Accumulator(scene, camera, spp=2, seed=5, **OPTIONS)
    errors = [accumulator.add().relative_error() for _ in range(frame.spp // 2)]
    assert errors[-1] == pytest.approx(frame.relative_error())
    assert all(error > target for error in errors[:-1])
    assert len(errors) >= 3  # the test stops on an estimate, not at the first finite one


def test_relative_error_is_the_documented_mean_over_covered_pixels():
    rgb = np.zeros((1, 3, 3), np.float32)
    rgb[0, 0] = 1.0
    rgb[0, 1] = 3.0
    variance = np.zeros_like(rgb)
    variance[0, 0] = 0.04
    variance[0, 1] = 0.09
    variance[0, 2] = 100.0  # not covered: left out
    frame = pw.Frame(rgb=rgb, depth=None, normal=None, alpha=np.array([[1.0, 0.5, 0.0]], np.float32),
                     variance=variance)
    eps = 0.01 * 2.0
    assert frame.relative_error() == pytest.approx((0.2 / (1.0 + eps) + 0.3 / (3.0 + eps)) / 2)


def test_one_accumulator_from_two_threads_holds_every_pass_once(box):
    scene, camera = box
    accumulator = pw.Accumulator(scene, camera, spp=1, seed=2, **OPTIONS)
    workers = [threading.Thread(target=lambda: [accumulator.add() for _ in range(3)]) for _ in range(2)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert accumulator.spp == 6
    np.testing.assert_allclose(accumulator.frame.rgb, pw.render(scene, camera, spp=6, seed=2, **OPTIONS).rgb,
                               rtol=1e-5, atol=1e-7)


def test_threads_do_not_change_the_accumulated_frame(box):
    scene, camera = box
    frames = []
    for threads in (1, 2):
        accumulator = pw.Accumulator(scene, camera, spp=2, threads=threads, **OPTIONS)
        accumulator.add()
        frames.append(accumulator.add())
    for name in ("rgb", "variance", "alpha", "albedo", "normal", "depth"):
        np.testing.assert_array_equal(getattr(frames[0], name), getattr(frames[1], name))


def test_bad_options_are_refused_with_advice(box):
    scene, camera = box
    with pytest.raises(InputError, match="integrator='path'"):
        pw.render(scene, camera, width=4, height=4, time_budget=1.0)
    with pytest.raises(InputError, match="integrator='path'"):
        pw.Accumulator(scene, camera, width=4, height=4, integrator="direct")
    with pytest.raises(InputError, match="integrator='path'"):
        pw.explain(scene, target_error=0.1)
    assert "path" in pw.explain(scene, target_error=0.1, integrator="path")
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(InputError, match="time_budget"):
            pw.render(scene, camera, time_budget=bad, **OPTIONS)
        with pytest.raises(InputError, match="target_error"):
            pw.render(scene, camera, target_error=bad, **OPTIONS)
    with pytest.raises(InputTypeError, match="time_budget"):
        pw.render(scene, camera, time_budget="1s", **OPTIONS)
    with pytest.raises(InputTypeError, match="time_budget"):
        pw.Accumulator(scene, camera, time_budget=1.0, **OPTIONS)
    accumulator = pw.Accumulator(scene, camera, first_sample=2**31 - 2, **OPTIONS)
    accumulator.add()
    with pytest.raises(InputError, match="2\\^31"):
        accumulator.add()
    with pytest.raises(InputError, match="spp"):
        accumulator.add(spp=0)


def test_frames_without_aovs_accumulate_too(box):
    scene, camera = box
    options = {**OPTIONS, "aovs": False}
    accumulator = pw.Accumulator(scene, camera, spp=2, **options)
    accumulator.add()
    frame = accumulator.add()
    assert frame.depth is None and frame.normal is None and frame.albedo is None
    np.testing.assert_allclose(frame.rgb, pw.render(scene, camera, spp=4, **options).rgb, rtol=1e-5, atol=1e-7)


def test_command_line_time_budget_and_target_error(tmp_path, monkeypatch, capsys):
    import trimesh

    from pbrwarp import cli

    mesh = tmp_path / "box.obj"
    trimesh.creation.box().export(mesh)
    out = tmp_path / "out.npy"
    asked = []
    add = progressive.Accumulation.add

    def recorded_add(self, **options):
        asked.append(options)
        return add(self, **options)

    monkeypatch.setattr(progressive.Accumulation, "add", recorded_add)
    base = ["render", str(mesh), "-o", str(out), "--size", "8x6", "--spp", "2", "--integrator", "path"]
    assert cli.main(base + ["--target-error", "0.5", "--time-budget", "30"]) == 0
    assert np.load(out).shape == (6, 8, 4)
    assert asked == [{"time_budget": 30.0, "target_error": 0.5}]
    for bad in (["--time-budget", "0"], ["--target-error", "nan"], ["--time-budget", "-1"]):
        assert cli.main(base + bad) == cli.EXIT_USAGE
        assert "expected a number above 0" in capsys.readouterr().err
    out.unlink()
    assert cli.main(base[:-2] + ["--time-budget", "1"]) == cli.EXIT_USAGE  # the direct integrator
    assert "integrator='path'" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("aovs", [True, False])
def test_the_memory_check_counts_the_sums_and_the_accumulated_frame(box, aovs, monkeypatch):
    """frame_bytes(progressive=True) adds exactly the arrays an Accumulation keeps per pixel (its
    float64 sums and the accumulated frame), and a progressive render is refused where only they
    would pass the memory limit."""
    from pbrwarp import validate

    scene, camera = box
    options = {**OPTIONS, "aovs": aovs}
    accumulator = pw.Accumulator(scene, camera, spp=1, **options)
    accumulator.add()
    frame = accumulator.add()
    sums = accumulator._sums
    kept = [sums.rgb, sums.rgb_squared, sums.alpha, sums.depth, sums.normal, sums.albedo, frame.rgb, frame.alpha,
            frame.variance, frame.depth, frame.normal, frame.albedo]
    width, height = OPTIONS["width"], OPTIONS["height"]
    extra = (validate.frame_bytes(width, height, 1, aovs, rasterized=False, progressive=True)
             - validate.frame_bytes(width, height, 1, aovs, rasterized=False))
    assert extra == sum(a.nbytes for a in kept if a is not None)
    plain = validate.frame_bytes(width, height, 1, aovs, rasterized=True)
    monkeypatch.setattr(validate, "memory_limit", lambda: (plain, "a test's limit"))
    assert pw.render(scene, camera, spp=1, **options).spp == 1
    with pytest.raises(InputError, match="a test's limit"):
        pw.render(scene, camera, spp=1, time_budget=1.0, **options)
    with pytest.raises(InputError, match="a test's limit"):
        pw.Accumulator(scene, camera, spp=1, **options)
    with pytest.raises(InputError, match="a test's limit"):
        pw.explain(scene, width=width, height=height, integrator="path", aovs=aovs, target_error=0.1)


def test_frame_and_spp_are_read_without_waiting_for_a_pass_under_way(box):
    """A display thread reads the frame of the passes done so far while add() renders the next."""
    scene, camera = box
    one_pass = pw.render(scene, camera, spp=1, **OPTIONS)
    started, release = threading.Event(), threading.Event()
    passes = []

    def run(spp, first_sample, progress):
        passes.append(first_sample)
        if len(passes) == 2:  # the second pass waits until the reader has looked
            started.set()
            assert release.wait(timeout=60)
        return one_pass

    accumulation = progressive.Accumulation(run, (OPTIONS["width"], OPTIONS["height"]), 1, 0, False)
    adder = threading.Thread(target=lambda: [accumulation.add(), accumulation.add()])
    adder.start()
    try:
        assert started.wait(timeout=60)
        assert accumulation.spp == 1 and accumulation.frame is not None  # the first pass, at once
    finally:
        release.set()
        adder.join(timeout=60)
    assert accumulation.spp == 2 and passes == [0, 1]
