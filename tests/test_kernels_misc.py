"""Sampling, texture filtering and tone mapping kernels against their definitions."""


import numpy as np
import pytest
import warp as wp

import pbrwarp as pw
from pbrwarp.kernels.sampling import multi_jittered_sample
from pbrwarp.kernels.textures import TEXELS_FLOAT, TEXELS_SRGB8, TEXELS_UNORM8, Texels, TextureData, sample_texture, texel_store
from pbrwarp.textures import UNORM8_DECODE
from pbrwarp.kernels.work_queue import add_atomically, take_next_from_ranges

import reference as ref


@wp.kernel(enable_backward=False)
def draw_samples(m: int, n: int, seed: int, out: wp.array(dtype=wp.vec2)):
    s = wp.tid()
    out[s] = multi_jittered_sample(s, m, n, seed)


@pytest.mark.parametrize("m,n", [(1, 1), (2, 2), (2, 3), (4, 4), (1, 7), (16, 16)])
@pytest.mark.parametrize("seed", [0, 17, 123456])
def test_multi_jittered_samples_are_stratified(m, n, seed):
    out = wp.zeros(m * n, dtype=wp.vec2)
    wp.launch(draw_samples, dim=m * n, inputs=[m, n, seed, out])
    xy = out.numpy().astype(np.float64)
    N = m * n
    assert np.all((xy >= 0) & (xy < 1))
    # one sample per cell of the m x n grid, and one per each of the N strips in x and in y
    cells = np.floor(xy[:, 0] * m).astype(int) + m * np.floor(xy[:, 1] * n).astype(int)
    assert sorted(cells) == list(range(N))
    assert sorted(np.floor(xy[:, 0] * N).astype(int)) == list(range(N))
    assert sorted(np.floor(xy[:, 1] * N).astype(int)) == list(range(N))


@wp.kernel(enable_backward=False)
def sample_at(tex: TextureData, texels: Texels, uv: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = sample_texture(tex, texels, uv[i])


def bilinear_reference(img, u, v, wrap):
    """Bilinear filtering with texel centres at half-integers; wrap: 0 repeat, 1 clamp, 2 mirror."""
    h, w = img.shape[:2]

    def index(i, size):
        if wrap == 1:
            return np.clip(i, 0, size - 1)
        if wrap == 2:
            k = np.mod(i, 2 * size)
            return np.where(k >= size, 2 * size - 1 - k, k)
        return np.mod(i, size)

    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    xa, xb = index(x0.astype(np.int64), w), index(x0.astype(np.int64) + 1, w)
    ya, yb = index(y0.astype(np.int64), h), index(y0.astype(np.int64) + 1, h)
    return ((img[ya, xa] * (1 - fx) + img[ya, xb] * fx) * (1 - fy) + (img[yb, xa] * (1 - fx) + img[yb, xb] * fx) * fy)


def texture_row(w, h, wrap, texel_format=TEXELS_FLOAT):
    row = TextureData()
    row.offset, row.width, row.height, row.wrap_s, row.wrap_t = 0, w, h, wrap, wrap
    row.texel_format = texel_format
    row.uv_row0, row.uv_row1 = wp.vec3(1, 0, 0), wp.vec3(0, 1, 0)
    return row


def srgb_eotf(c):
    """IEC 61966-2-1 in float64, written out here rather than taken from pbrwarp."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.mark.parametrize("texel_format", ["float", "unorm8", "srgb8"])
@pytest.mark.parametrize("wrap", [0, 1, 2])
@pytest.mark.parametrize("size", [(1, 1), (3, 5), (7, 4)])
def test_bilinear_sampling_and_wrap_modes(wrap, size, texel_format):
    """Bilinear filtering of linear values: 8-bit texels are decoded (value / 255, and sRGB's
    EOTF for the colour of sRGB ones) before the four are interpolated."""
    rng = np.random.default_rng(5)
    w, h = size
    uv = rng.uniform(-3, 4, (2000, 2))
    if texel_format == "float":
        img = rng.uniform(0, 1, (h, w, 4))
        texels, row = texel_store([img.reshape(-1, 4).astype(np.float32)]), texture_row(w, h, wrap)
    else:
        stored = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
        img = stored / 255.0
        if texel_format == "srgb8":
            img[..., :3] = srgb_eotf(img[..., :3])
        texels = texel_store(unorm8=[stored.reshape(-1, 4)], decode=UNORM8_DECODE)
        row = texture_row(w, h, wrap, TEXELS_SRGB8 if texel_format == "srgb8" else TEXELS_UNORM8)
    out = wp.zeros(len(uv), dtype=wp.vec4)
    wp.launch(sample_at, dim=len(uv), inputs=[row, texels, wp.array(uv.astype(np.float32), dtype=wp.vec2), out])
    want = bilinear_reference(img, uv[:, 0].astype(np.float32).astype(np.float64), uv[:, 1].astype(np.float32).astype(np.float64), wrap)
    np.testing.assert_allclose(out.numpy(), want, atol=2e-5)


@pytest.mark.parametrize("wrap", [0, 1, 2])
def test_huge_and_nan_uvs_stay_in_bounds_and_finite(wrap):
    img = np.random.default_rng(1).uniform(0, 1, (4, 4, 4))
    uv = np.array([[1e6, -1e6], [3e9, 1e12], [np.nan, 0.5], [np.inf, -np.inf], [0.5, np.nan]], np.float32)
    out = wp.zeros(len(uv), dtype=wp.vec4)
    wp.launch(sample_at, dim=len(uv), inputs=[texture_row(4, 4, wrap), texel_store([img.reshape(-1, 4).astype(np.float32)]),
                                              wp.array(uv, dtype=wp.vec2), out])
    got = out.numpy()
    assert np.all(np.isfinite(got))
    assert np.all((got >= img.min(axis=(0, 1)) - 1e-6) & (got <= img.max(axis=(0, 1)) + 1e-6))


def frame_of(rgb):
    rgb = np.asarray(rgb, np.float32).reshape(1, -1, 3)
    n = rgb.shape[1]
    return pw.Frame(rgb=rgb, depth=np.zeros((1, n), np.float32), normal=np.zeros((1, n, 3), np.float32),
                    alpha=np.ones((1, n), np.float32))


def test_tonemap_none_is_srgb_encoding():
    x = np.linspace(0, 1, 257)
    rgb = np.stack([x, x, x], -1)
    got = frame_of(rgb).to_srgb8(tonemap="none")[0, :, 0]
    want = np.floor(ref.srgb_encode(x) * 255 + 0.5)
    assert np.max(np.abs(got.astype(int) - want)) <= 1  # float32 vs float64 rounding at .5 boundaries


def test_exposure_is_in_stops():
    a = frame_of([[0.1, 0.1, 0.1]]).to_srgb8(exposure=1.0, tonemap="none")
    b = frame_of([[0.2, 0.2, 0.2]]).to_srgb8(exposure=0.0, tonemap="none")
    assert np.array_equal(a, b)


@pytest.mark.parametrize("tonemap", ["none", "reinhard", "aces"])
def test_tonemaps_map_inf_and_huge_to_white_and_nan_to_black(tonemap):
    rgb = [[np.inf, np.inf, np.inf], [1e30, 1e30, 1e30], [np.nan, np.nan, np.nan], [0, 0, 0], [-1, -1, -1]]
    out = frame_of(rgb).to_srgb8(tonemap=tonemap)[0]
    assert np.all(out[0] >= 254) and np.all(out[1] >= 254)
    assert np.all(out[2] == 0) and np.all(out[3] == 0) and np.all(out[4] == 0)


@pytest.mark.parametrize("tonemap", ["reinhard", "aces"])
def test_tonemaps_are_monotonic(tonemap):
    x = np.geomspace(1e-4, 1e4, 400)
    out = frame_of(np.stack([x, x, x], -1)).to_srgb8(tonemap=tonemap)[0, :, 0].astype(int)
    assert np.all(np.diff(out) >= 0)
    assert out[0] <= 2 and out[-1] >= 250


def test_reinhard_matches_definition():
    x = np.array([0.05, 0.5, 2.0, 10.0])
    out = frame_of(np.stack([x, x, x], -1)).to_srgb8(tonemap="reinhard")[0, :, 0].astype(int)
    want = np.floor(ref.srgb_encode(x / (1 + x)) * 255 + 0.5)
    assert np.max(np.abs(out - want)) <= 1


@wp.kernel(enable_backward=False)
def take_every_item(launch: int, launches: int, ranges: wp.array(dtype=wp.int64), taken_by: wp.array(dtype=wp.int32),
                    times_taken: wp.array(dtype=wp.int32)):
    item, owner = take_next_from_ranges(ranges, 0, launch, launches, launch)
    while item >= 0:
        add_atomically(times_taken, item, 1)
        taken_by[item] = launch
        item, owner = take_next_from_ranges(ranges, 0, launch, launches, owner)


@pytest.mark.parametrize("launches", [1, 2, 3, 5])
def test_ranges_hand_out_every_item_once_to_launches_running_at_once(launches):
    """kernels/work_queue.py take_next_from_ranges, as visibility_pipeline takes its batches and
    tiles: launches side by side on the thread pool, each taking its own range's items from the
    start and the others' from the end, take every item exactly once, however the ranges are
    sized (one empty here) and wherever the owner and the others meet."""
    from pbrwarp.kernels.work_queue import RANGE_STRIDE, reset_range
    from pbrwarp.parallel import run_together

    @wp.kernel(enable_backward=False)
    def set_ranges(ranges: wp.array(dtype=wp.int64), bounds: wp.array(dtype=wp.vec2i)):
        k = wp.tid()
        reset_range(ranges, k, bounds[k][0], bounds[k][1])

    rng = np.random.default_rng(launches)
    for _ in range(20):
        cuts = np.sort(rng.integers(0, 60000, launches - 1)) if launches > 1 else np.array([], dtype=int)
        edges = np.concatenate([[0], cuts, [60000]])
        if launches > 2:
            edges[2] = edges[1]  # an empty range
        bounds = wp.array(np.stack([edges[:-1], edges[1:]], axis=1).astype(np.int32), dtype=wp.vec2i)
        ranges = wp.empty(launches * RANGE_STRIDE, dtype=wp.int64)
        wp.launch(set_ranges, dim=launches, inputs=[ranges, bounds])
        taken_by = wp.full(60000, -1, dtype=wp.int32)
        times_taken = wp.zeros(60000, dtype=wp.int32)
        run_together(lambda k: wp.launch(take_every_item, dim=1, device="cpu",
                                         inputs=[k, launches, ranges, taken_by, times_taken]), launches)
        assert (times_taken.numpy() == 1).all()
        owners = taken_by.numpy()
        assert ((owners >= 0) & (owners < launches)).all()


@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
@pytest.mark.parametrize("caller_first", [False, True])
def test_run_together_runs_every_launch_at_once_and_where_asked(caller_first):
    """run_together: fn(0..n-1) all at once (each waits for all to have started), fn(0) on the
    calling thread exactly when caller_first, the others on pool threads; a failing launch
    cancels (releases) the others, those not yet taken by a pool thread are dropped, its error is
    raised once the rest are done, and the pool serves the next call as before."""
    import threading

    from pbrwarp.parallel import run_together

    started, where = threading.Barrier(3, timeout=10), {}

    def launch(k):
        where[k] = threading.get_ident()
        started.wait()

    run_together(launch, 3, caller_first=caller_first)
    assert sorted(where) == [0, 1, 2] and len(set(where.values())) == 3
    assert (where[0] == threading.get_ident()) == caller_first
    assert threading.get_ident() not in (where[1], where[2])

    release, finished = threading.Event(), []

    def failing(k):
        if k == 0:
            raise ValueError("launch 0 failed")
        release.wait(10)  # waits for the cancel, as raster launches wait at a barrier for the abort flag
        finished.append(k)

    for _ in range(20):
        release.clear()
        finished.clear()
        with pytest.raises(ValueError, match="launch 0 failed"):
            join = run_together(failing, 3, join=False, cancel=release.set, caller_first=caller_first)
            join()
        assert release.is_set() and set(finished) <= {1, 2}
    where.clear()
    started.reset()
    run_together(launch, 3, caller_first=caller_first)
    assert sorted(where) == [0, 1, 2]
