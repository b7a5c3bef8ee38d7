"""Primary visibility by rasterization (kernels/raster.py), on every core.

:func:`visibility_buffer` gives, per sample, the nearest triangle and its depth. Sample
positions are camera independent and kept process-wide. The rest is one launch of kernels/raster.py's
visibility_pipeline per thread, on pool threads side by side (Warp CPU launches run on one
thread and release the GIL; the caller waits, see pbrwarp/parallel.py), meeting at barriers that
spin in the kernel rather than return to Python: the buffer cleared and vertices projected (a
share each); triangles' screen rectangles, small triangles drawn into the buffer at once (atomic
minima, as two threads may write one sample) and larger ones binned into TILE_SIZE tiles, in
small batches of triangles, each launch taking those of its own part of the mesh first and then
what is left of the others'; the bins laid out and filled; then the tiles with something to
draw, in bands taken as the batches are, a tile drawn by one launch only. A sample keeps the
minimum of its entries whatever the order they come in, so the buffer does not depend on the
thread count. With a mesh's :func:`triangle_clusters`, clusters off screen, facing away (where
flagged) or hidden behind what the clusters facing the eye drew are skipped
(kernels/occlusion.py)."""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
import functools
import math
import threading
import time

import numpy as np
import warp as wp

from . import huge_pages
from .errors import InputError, InputTypeError
from .parallel import run_all, run_together, thread_count
from .scene_cache import PROCESS_WIDE
from pbrwarp.kernels import binning
from pbrwarp.kernels import occlusion as ok
from pbrwarp.kernels import raster as rk
from pbrwarp.kernels import sampling
from pbrwarp.kernels.camera import CameraData
from pbrwarp.kernels.loading import load_for_cpu
from pbrwarp.kernels.projection import Projection, projection_of
from pbrwarp.kernels.triangle_setup import MAX_IMAGE_SIZE, RasterMesh
from pbrwarp.kernels.visibility_buffer import VisibilityTarget
from pbrwarp.kernels.work_queue import RANGE_STRIDE

NO_TRIANGLE = 0xFFFFFFFFFFFFFFFF
TILE_SIZE = int(binning.TILE_SIZE)
# Fewest vertices worth a piece of projection: below this, sharing costs more than the work.
MIN_VERTEX_SHARE = 4096
# Batches of triangles per thread in each pass, the thread's own range of them taken first: a
# thread whose batches cost less (back faces culled, triangles off screen, clusters deferred)
# then takes the others' rather than waiting, and the last batch taken, which the other threads
# wait for at the pass's barrier, is short; at most MAX_BATCH triangles, at least a cluster.
# (Batches are not the binning's unit, which is the launch, so their number costs only an
# atomic take each; fewer, larger batches would leave the launches waiting at the pass's
# barrier for the last one.)
BATCHES_PER_THREAD = 64
MAX_BATCH = 2048
# Sample-position arrays kept for reuse, process-wide: they depend on the image size, spp and seed
# only, not on a scene.
CACHED_SAMPLE_LAYOUTS = 4
# Samples whose positions one job computes at most, so that an interrupt waits for little.
SAMPLES_PER_JOB = 1 << 18
# What an aborted call sets its work queues to: past any count of items (and far from overflow
# by the launches' takes after it).
_QUEUE_PAST_END = 1 << 30

class _Scratch(threading.local):
    """Per calling thread, the largest scratch array of each kind used so far, reused by later
    frames: the first touch of fresh memory page-faults, and page faults do not scale across
    threads (at large sizes they would take much of a frame and most of a second core's gain)."""

    def __init__(self):
        self.arrays = {}


_scratch = _Scratch()


def _scratch_array(arrays: dict, kind: str, shape, dtype) -> wp.array:
    """An array of ``shape`` (a length or a tuple; every extent at least 1) of ``dtype``, reused
    across calls: arrays is one thread's _scratch.arrays. The last view of each kind is kept too,
    since making one costs more than the small arrays' whole use."""
    shape = tuple(max(int(n), 1) for n in ((shape,) if isinstance(shape, (int, np.integer)) else shape))
    last = arrays.get((kind, "view"))
    if last is not None and last[0] == shape:
        view = last[1]
    else:
        size = math.prod(shape)
        base = arrays.get(kind)
        if base is None or len(base) < size:
            base = arrays[kind] = wp.empty(size, dtype=dtype, device="cpu")
        view = base[:size] if len(shape) == 1 else base[:size].reshape(shape)
        arrays[(kind, "view")] = (shape, view)
    return view


def _replay_launch(recorded: dict, key, kernel, inputs: list):
    """wp.launch(kernel, dim=1, inputs=inputs) on the CPU, replaying the launch recorded in
    ``recorded`` (one thread's _scratch.arrays) under ``key``, packed again but for the arrays
    that are the very objects it last had (an array's memory never moves) and the plain numbers
    equal to the last ones; a struct may have been changed in place, so structs are always
    packed (cheaply: an instance keeps its fields packed as they are set, see _kernel_struct).
    Packing every argument anew would cost a noticeable share of a small call. The record keeps
    its last inputs (the caller's mesh and buffer arrays among them) alive until the next call."""
    entry = recorded.get((key, "launch"))
    if entry is None:
        command = wp.launch(kernel, dim=1, device="cpu", inputs=inputs, record_cmd=True)
        recorded[(key, "launch")] = (command, list(inputs))
    else:
        command, last = entry
        for i, value in enumerate(inputs):
            previous = last[i]
            if isinstance(value, wp.array):
                unchanged = value is previous
            else:
                unchanged = type(value) in _PLAIN_NUMBERS and type(previous) is type(value) and value == previous
            if not unchanged:
                command.set_param_at_index(i, value)
                last[i] = value
    command.launch()


_PLAIN_NUMBERS = (int, float, bool)


def _kernel_struct(recorded: dict, kind, **fields):
    """The instance of Warp struct ``kind`` kept in ``recorded`` (one thread's _scratch.arrays),
    with ``fields`` set: only those that differ from its last ones (arrays: not the very object),
    as setting an array field builds its descriptor anew."""
    instance = recorded.get(kind)
    if instance is None:
        instance = recorded[kind] = kind()
    for name, value in fields.items():
        last = getattr(instance, name)
        if value is last or (not isinstance(value, wp.array) and type(value) is type(last) and value == last):
            continue
        setattr(instance, name, value)
    return instance


# Cost models for choosing between rasterizing and ray casting primary visibility, fitted on 2
# cores by bench/visibility.py (bench/results/visibility.md, least squares weighted by 1/time):
# raster seconds ~ RASTER_SECONDS_PER_TRIANGLE * triangles + RASTER_SECONDS_PER_SAMPLE * samples,
# ray cast seconds ~ RAYCAST_SECONDS_PER_SAMPLE_LOG2_TRIANGLE * samples * log2(triangles).
RASTER_SECONDS_PER_TRIANGLE = 10.5e-9
RASTER_SECONDS_PER_SAMPLE = 5.06e-9
RAYCAST_SECONDS_PER_SAMPLE_LOG2_TRIANGLE = 7.21e-9
# Calls the cost model puts under this (on every core) run their first launch on the calling
# thread: an interrupt then waits for that launch, at most a few times this long.
CALLER_LAUNCH_SECONDS = 0.03

KERNELS = (sampling.sample_positions, rk.visibility_pipeline, ok.cluster_bounds, projection_of)
CLUSTER_SIZE = int(ok.CLUSTER_SIZE)
# count_batch draws a cluster from one 64-bit mask of its triangles (kernels/binning.py triangles_to_count)
assert CLUSTER_SIZE <= 64, "a cluster's triangles must fit in one uint64 mask"


def _chunks(n: int, parts: int):
    """(index, first, count) of up to ``parts`` contiguous non-empty ranges covering [0, n)."""
    step = max(1, math.ceil(n / parts))
    return [(k, first, min(step, n - first)) for k, first in enumerate(range(0, n, step))]


_kernels_loaded = False


def _load_kernels():
    # compile or load every kernel once, before pool threads would each try at once (and only
    # once: even the check that they are loaded costs a call something with cold caches)
    global _kernels_loaded
    if not _kernels_loaded:
        for kernel in KERNELS:
            load_for_cpu(kernel)
        _kernels_loaded = True


@functools.cache
def _os_yield_address() -> int:
    """The address of the C library's sched_yield, which the raster's waiting launches call now
    and then (kernels/barriers.py all_arrived), or 0 where there is none (Windows)."""
    try:
        return ctypes.cast(ctypes.CDLL(None).sched_yield, ctypes.c_void_p).value or 0
    except (AttributeError, OSError, TypeError):
        return 0


@dataclass(frozen=True)
class Clusters:
    """Bounds of a mesh's clusters of CLUSTER_SIZE consecutive triangles, for occlusion culling
    (kernels/occlusion.py), from :func:`triangle_clusters`; valid for the very position and
    index arrays they were built from, while those are not changed."""

    positions: wp.array
    indices: wp.array
    lower: wp.array
    upper: wp.array
    axis: wp.array
    spread: wp.array

    def __len__(self):
        return len(self.lower)


def triangle_clusters(positions: wp.array, indices: wp.array) -> Clusters:
    """The clusters of a mesh for ``visibility_buffer(clusters=...)``: triangles [k CLUSTER_SIZE,
    (k + 1) CLUSTER_SIZE) form cluster k, so they cull well when neighbours are stored together
    (as upload stores them, pbrwarp/locality.py). Build them again after changing the arrays."""
    vertices, triangles = _check_geometry(positions, indices)
    if triangles:
        idx = indices.numpy()
        if idx.min() < 0 or idx.max() >= vertices:
            raise _index_out_of_range(idx, vertices)
    count = math.ceil(triangles / CLUSTER_SIZE)
    lower, upper, axis = (wp.empty(count, dtype=wp.vec3, device="cpu") for _ in range(3))
    spread = wp.empty(count, dtype=wp.float32, device="cpu")
    _load_kernels()
    if count:
        wp.launch(ok.cluster_bounds, dim=count, device="cpu",
                  inputs=[positions, indices, triangles, lower, upper, axis, spread])
    return Clusters(positions, indices, lower, upper, axis, spread)


_NO_CULLING = wp.empty(0, dtype=wp.uint8, device="cpu")
_NO_CLUSTERS = wp.empty(0, dtype=wp.vec3, device="cpu")
_NO_SPREADS = wp.empty(0, dtype=wp.float32, device="cpu")


def _cached_sample_positions(width, height, spp, grid_m, grid_n, seed, threads):
    def compute():
        out = wp.empty((height, width * spp), dtype=wp.vec2, device="cpu")

        def launch(job):
            _, first_row, rows = job
            wp.launch(sampling.sample_positions, dim=rows * width * spp, device="cpu",
                      inputs=[spp, grid_m, grid_n, seed, width, first_row, out])

        run_all(launch, _chunks(height, max(threads, math.ceil(height * width * spp / SAMPLES_PER_JOB))), threads)
        return out

    layout = (width, height, spp, grid_m, grid_n, seed)
    return PROCESS_WIDE.get(("sample positions", layout), None, compute, keep=CACHED_SAMPLE_LAYOUTS)


def sample_positions(width: int, height: int, spp: int = 1, grid_m: int = 1, grid_n: int = 1, seed: int = 0,
                     threads: int | None = None) -> wp.array:
    """Image positions (x, y) in pixels of every sample, shape (height, width * spp), sample s of
    pixel (px, py) at [py, px * spp + s]: the ray caster's (render_tile's) very positions,
    pixel centres for spp = 1, else multi_jittered_sample(s, grid_m, grid_n, seed + py * width + px).
    Cached: do not write to the returned array."""
    _check_sampling(width, height, spp, grid_m, grid_n, seed)
    _load_kernels()
    return _cached_sample_positions(width, height, spp, grid_m, grid_n, seed, thread_count(threads))


def projection(cam: CameraData, orthographic: bool = False) -> Projection:
    """World-to-screen mapping of ``cam`` in float64, the exact inverse of camera_ray_direction;
    or, ``orthographic``, the parallel projection along cam.forward whose view spans
    cam.right and cam.up (half-extents in world units) about cam.eye: kernels/projection.py
    camera_projection, the very one visibility_buffer's launches derive."""
    _load_kernels()
    out = wp.empty(1, dtype=Projection, device="cpu")
    usable = wp.empty(1, dtype=wp.int32, device="cpu")
    wp.launch(projection_of, dim=1, device="cpu", inputs=[cam, int(bool(orthographic)), out, usable])
    if not usable.numpy()[0]:
        raise _unusable_camera()
    return out.list()[0]


def _unusable_camera() -> InputError:
    return InputError("camera axes must be finite and linearly independent")


def _check_sampling(width, height, spp, grid_m, grid_n, seed):
    for name, value in (("width", width), ("height", height), ("spp", spp), ("grid_m", grid_m),
                        ("grid_n", grid_n), ("seed", seed)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise InputTypeError(f"{name} must be an integer, got {value!r}")
    if not (1 <= width <= MAX_IMAGE_SIZE and 1 <= height <= MAX_IMAGE_SIZE):
        raise InputError(f"image size must be 1..{MAX_IMAGE_SIZE} pixels a side, got {width}x{height}")
    if spp < 1 or grid_m < 1 or grid_n < 1 or grid_m * grid_n != spp:
        raise InputError(f"spp must be grid_m * grid_n >= 1, got spp={spp}, grid {grid_m}x{grid_n}")
    if not 0 <= seed < 2**31:
        raise InputError(f"seed must lie in [0, 2^31), got {seed}")


def _index_out_of_range(idx: np.ndarray, vertices: int) -> InputError:
    return InputError(f"triangle index out of range: indices span [{idx.min()}, {idx.max()}], {vertices} vertices")


def _check_geometry(positions, indices) -> tuple[int, int]:
    """(vertex count, triangle count). Index values are checked by visibility_pipeline, before
    any is used to read (one out of range would crash Warp)."""
    if not isinstance(positions, wp.array) or positions.dtype != wp.vec3 or positions.ndim != 1:
        raise InputTypeError("positions must be a 1-D wp.array of wp.vec3")
    if not isinstance(indices, wp.array) or indices.dtype != wp.int32 or indices.ndim != 1:
        raise InputTypeError("indices must be a 1-D wp.array of wp.int32")
    if positions.device.is_cuda or indices.device.is_cuda:
        raise InputError("positions and indices must live on the CPU")
    if len(indices) % 3:
        raise InputError(f"indices must hold 3 per triangle, got {len(indices)}")
    return len(positions), len(indices) // 3


@dataclass(frozen=True)
class _Layout:
    """What a visibility_buffer call of one shape (mesh and image sizes, spp, threads, clusters)
    works with: its batches and tiles, and its scratch arrays (views of _scratch_array's)."""

    tiles_x: int
    tiles: int
    batch_size: int
    batch_stride: int
    screen: wp.array
    depth_weights: wp.array
    binned_face: wp.array
    binned_rect: wp.array
    cursors: wp.array
    bin_start: wp.array
    bin_total: wp.array
    busy_tiles: wp.array
    batch_ranges: wp.array
    cluster_rect: wp.array
    cluster_nearest: wp.array
    # one block, zeroed before each call, holding binned_count, bad_indices, sync and tile_counts;
    # and NumPy views of it and of sync, the cheapest way from Python into them (Warp's array
    # methods cost more, above all with the caches cold after a large frame)
    zeroed: wp.array
    zeroed_view: np.ndarray
    sync_view: np.ndarray
    binned_count: wp.array
    bad_indices: wp.array
    sync: wp.array
    tile_counts: wp.array


def _call_layout(scratch: dict, vertices: int, triangles: int, width: int, height: int, spp: int, threads: int,
                 cluster_count: int) -> _Layout:
    """The _Layout of a call of this shape on the calling thread (``scratch`` its
    _scratch.arrays), the last one kept for the next call: building it takes a few dozen small
    Python steps, a noticeable share of a small call."""
    key = (vertices, triangles, width, height, spp, threads, cluster_count)
    last = scratch.get("layout")
    if last is not None and last[0] == key:
        return last[1]
    tiles_x = math.ceil(width / TILE_SIZE)
    tiles = tiles_x * math.ceil(height / TILE_SIZE)
    batch_size = min(MAX_BATCH, math.ceil(triangles / (threads * BATCHES_PER_THREAD)))
    batch_size = max(1, math.ceil(batch_size / CLUSTER_SIZE)) * CLUSTER_SIZE  # whole clusters
    batches = max(math.ceil(triangles / batch_size), 1)
    sync_slots = int(rk.SYNC_SLOTS)
    # per launch: its count of binned triangles, its flag for an index out of range, its row of
    # per-tile counts; then the shared slots
    zeroed = _scratch_array(scratch, "zeroed", 2 * threads + sync_slots + threads * tiles, wp.int32)
    counts_end = 2 * threads + sync_slots
    sync = zeroed[2 * threads:counts_end]
    layout = _Layout(
        tiles_x=tiles_x, tiles=tiles, batch_size=batch_size, batch_stride=math.ceil(batches / threads),
        screen=_scratch_array(scratch, "screen", vertices, wp.vec2i),
        depth_weights=_scratch_array(scratch, "depth_weights", vertices, wp.float64),
        # each launch's list of binned triangles has room for all of them
        binned_face=_scratch_array(scratch, "binned_face", threads * triangles, wp.int32),
        binned_rect=_scratch_array(scratch, "binned_rect", threads * triangles, wp.vec4i),
        cursors=_scratch_array(scratch, "cursors", (threads, tiles), wp.int32),
        bin_start=_scratch_array(scratch, "bin_start", tiles + 1, wp.int32),
        # written by the pipeline before it is read
        bin_total=_scratch_array(scratch, "bin_total", 1, wp.int64),
        busy_tiles=_scratch_array(scratch, "busy_tiles", tiles, wp.int32),
        batch_ranges=_scratch_array(scratch, "batch_ranges", 3 * threads * RANGE_STRIDE, wp.int64),
        cluster_rect=_scratch_array(scratch, "cluster_rect", cluster_count, wp.vec4i),
        cluster_nearest=_scratch_array(scratch, "cluster_nearest", cluster_count, wp.float64),
        zeroed=zeroed, zeroed_view=zeroed.numpy(), sync_view=sync.numpy(), binned_count=zeroed[:threads],
        bad_indices=zeroed[threads:2 * threads], sync=sync, tile_counts=zeroed[counts_end:].reshape((threads, tiles)))
    scratch["layout"] = (key, layout)
    return layout


def visibility_buffer(positions: wp.array, indices: wp.array, cam: CameraData, spp: int = 1, grid_m: int = 1,
                      grid_n: int = 1, seed: int = 0, threads: int | None = None,
                      out: wp.array | None = None, timings: dict | None = None,
                      cull_back_faces: wp.array | None = None, orthographic: bool = False,
                      clusters: Clusters | None = None, counts: dict | None = None) -> wp.array:
    """The nearest triangle of every camera sample: a (cam.height, cam.width * spp) uint64
    wp.array, sample s of pixel (px, py) at [py, px * spp + s] (see :func:`sample_positions`).

    Each entry is (float32 bits of depth) << 32 | triangle id, NO_TRIANGLE (all ones) where no
    triangle is hit; depth is camera-space z (the coefficient of cam.forward in point - eye),
    the lower id wins exact depth ties. Both facings are drawn, except triangles flagged (nonzero)
    in ``cull_back_faces`` (a uint8 wp.array, one entry per triangle), which are dropped where
    they face away from the eye; degenerate triangles cover nothing; triangles behind the camera
    are dropped and those crossing the camera plane or leaving the guard band are rasterized
    homogeneously (in float64, from their camera-space vertices; by casting each sample's ray when
    the eye lies in their plane). ``threads`` defaults to every core; the buffer does not depend on
    it. Its launches spin while they wait for each other, yielding their core every few tens of
    microseconds, so that more threads than cores cost little (a launch waiting for one that is
    not running gives up its core). ``out``, a buffer of that shape and dtype on the CPU, is
    filled and returned instead of a new one: reusing it saves the page faults of fresh memory,
    which do not scale across threads. ``timings``, if a dict,
    receives seconds per part: "samples" (positions, cached), "binning" (clearing, projection,
    small triangles drawn, the others binned and the bins laid out), "raster" (bins filled,
    tiles drawn); the launches then stop between the two, which costs a little.

    ``clusters`` (:func:`triangle_clusters` of these very arrays) turns on culling of clusters:
    those whose bounding box lies off screen are skipped; so are those facing away from the eye
    by more than 3° where every triangle is flagged in ``cull_back_faces``; the clusters facing
    the eye are drawn first, and then the others skipped where their box lies behind what the
    buffer holds at every sample it could cover (kernels/occlusion.py). The buffer is the same,
    bit for bit (for the clusters facing away: unless one of their triangles, under ~1/50 pixel
    across and within 3° of edge-on, has its winding flipped by the snapping of its vertices); a
    dense closed mesh seen from outside draws about half its triangles. Clusters facing away are
    tested in a second pass only where the mesh has at most 16 samples per triangle and at least
    one cluster in 8 faces away (estimated from a sample), as otherwise the pass costs more than
    it saves (kernels/raster.py occlusion_pass_pays). ``counts``, if a dict, then receives how
    many clusters there are ("clusters") and were "off_screen", "facing_away" (culled),
    "deferred" (to the second pass) and "occluded" (found hidden: with several threads this
    count varies from call to call, as a deferred cluster meets the buffer as it is when its
    turn comes, other deferred clusters drawn into it or not; the buffer does not vary).

    ``orthographic`` draws the parallel projection along cam.forward instead (see
    :func:`projection`), depth then the distance in front of the plane through cam.eye; only
    triangles wholly in front of that plane and within the guard band are drawn (shadow maps of
    directional lights place it behind the whole scene).
    """
    threads = thread_count(threads)
    if not isinstance(cam, CameraData.cls):
        raise InputTypeError(f"cam must be a CameraData, got {type(cam).__name__}")
    width, height = int(cam.width), int(cam.height)
    _check_sampling(width, height, spp, grid_m, grid_n, seed)
    vertices, triangles = _check_geometry(positions, indices)
    if threads * triangles >= 2**31:
        raise InputError(f"{triangles} triangles on {threads} threads: each thread's list of triangles to bin has "
                         "room for all of them, in int32 entries; use fewer threads")
    if out is not None and (not isinstance(out, wp.array) or out.dtype != wp.uint64 or out.device.is_cuda
                            or out.shape != (height, width * spp) or not out.is_contiguous):
        raise InputError(f"out must be a contiguous CPU wp.array of uint64 of shape {(height, width * spp)}")
    if cull_back_faces is None:
        cull_back_faces = _NO_CULLING
    elif (not isinstance(cull_back_faces, wp.array) or cull_back_faces.dtype != wp.uint8
          or cull_back_faces.shape != (triangles,) or cull_back_faces.device.is_cuda):
        raise InputError(f"cull_back_faces must be a CPU wp.array of uint8 with one entry per triangle ({triangles})")
    if clusters is not None and (not isinstance(clusters, Clusters) or clusters.positions is not positions
                                 or clusters.indices is not indices):
        raise InputError("clusters must be triangle_clusters(positions, indices) of these very arrays")
    _load_kernels()
    clock = time.perf_counter()
    samples = _cached_sample_positions(width, height, spp, grid_m, grid_n, seed, threads)
    t_samples = time.perf_counter()

    scratch = _scratch.arrays  # the calling thread's
    cluster_count = len(clusters) if clusters is not None else 0
    layout = _call_layout(scratch, vertices, triangles, width, height, spp, threads, cluster_count)
    layout.zeroed_view.fill(0)
    # as long as the longest bins so far (a second pass grows them when a frame needs more)
    bins = scratch.get("bins")
    if bins is None:
        bins = scratch["bins"] = wp.empty(max(triangles, layout.tiles), dtype=wp.int32, device="cpu")
    sync = layout.sync
    if cluster_count:
        cluster_arrays = [clusters.lower, clusters.upper, clusters.axis, clusters.spread]
    else:
        cluster_arrays = [_NO_CLUSTERS] * 3 + [_NO_SPREADS]
    if out is None:
        out = huge_pages.empty((height, width * spp), wp.uint64)

    released = scratch.get("released")
    if released is None:
        released = scratch["released"] = wp.zeros(1, dtype=wp.int64, device="cpu")
        scratch["released_view"] = released.numpy()
    released_view = scratch["released_view"]
    # the caller runs launch 0 itself where an interrupt may wait for it (parallel.run_together)
    short_call = (RASTER_SECONDS_PER_TRIANGLE * triangles + RASTER_SECONDS_PER_SAMPLE * width * height * spp
                  < CALLER_LAUNCH_SECONDS)

    def run(first_stage, stop_after_binning):
        def launch(k):
            _replay_launch(scratch, ("pipeline", k), rk.visibility_pipeline,
                           [k, first_stage, int(stop_after_binning), work, mesh, cam, int(bool(orthographic)),
                            target, binned, culling])
            if k == 0:
                # launch 0 returns once the others are done and wait to be released: release them
                # from here rather than after the caller has woken up to learn that it returned
                released_view[0] = epoch

        def abort():
            # a launch failed or the caller was interrupted: the others stop waiting at their next
            # barrier, and taking work at their next take (every queue past its end, every range
            # emptied; but ranges launch 0 sets out after this, from the barrier before: if every
            # launch reaches the next barrier before seeing the flag, they draw one stage more)
            layout.sync_view[int(rk.ABORTED)] = 1
            layout.sync_view[int(rk.QUEUE_START)] = layout.sync_view[int(rk.QUEUE_FILL)] = _QUEUE_PAST_END
            layout.batch_ranges.numpy().fill(0)
            released_view[0] = epoch

        epoch = scratch["epoch"] = scratch.get("epoch", 0) + 1
        # the kernel's structs, this thread's kept across calls, only their changed fields set
        work = _kernel_struct(scratch, rk.Launches, count=threads, sync=sync, batch_ranges=layout.batch_ranges,
                              released=released, epoch=epoch, os_yield=_os_yield_address(),
                              batch_size=layout.batch_size, batch_stride=layout.batch_stride,
                              min_vertex_share=MIN_VERTEX_SHARE)
        mesh = _kernel_struct(scratch, RasterMesh, positions=positions, indices=indices, vertex_count=vertices,
                              triangles=triangles, cull_back_faces=cull_back_faces, screen=layout.screen,
                              depth_weights=layout.depth_weights)
        target = _kernel_struct(scratch, VisibilityTarget, out=out, samples=samples, spp=spp)
        binned = _kernel_struct(scratch, binning.Bins, tiles_x=layout.tiles_x, binned_count=layout.binned_count,
                                binned_face=layout.binned_face, binned_rect=layout.binned_rect,
                                tile_counts=layout.tile_counts, bad_indices=layout.bad_indices, cursors=layout.cursors,
                                bin_start=layout.bin_start, bin_total=layout.bin_total, slots=bins,
                                busy_tiles=layout.busy_tiles)
        culling = _kernel_struct(scratch, rk.ClusterCulling, lower=cluster_arrays[0], upper=cluster_arrays[1],
                                 axis=cluster_arrays[2], spread=cluster_arrays[3], rect=layout.cluster_rect,
                                 nearest=layout.cluster_nearest)
        try:
            join = run_together(launch, threads, join=False, cancel=abort, caller_first=short_call)
        finally:
            released_view[0] = epoch  # the pool threads' launches return (kernels/barriers.py wait_for_release)
        if layout.sync_view[int(rk.ABORTED)] != 0:
            join()  # a pool thread's launch failed: its error, raised here
            raise RuntimeError("the raster's launches were aborted")

    split = timings is not None
    run(int(rk.START), split)
    outcome = int(layout.sync_view[int(rk.OUTCOME)])
    if outcome == int(rk.BAD_CAMERA):
        raise _unusable_camera()
    if outcome == int(rk.BAD_INDEX):
        raise _index_out_of_range(indices.numpy(), vertices)
    t_binned = time.perf_counter()
    if outcome == int(rk.BINS_TOO_SMALL):
        total = int(layout.bin_total.numpy()[0])
        if total >= 2**31:
            raise InputError(f"too many triangle-tile pairs ({total}) for int32 bins")
        bins = scratch["bins"] = wp.empty(total, dtype=wp.int32, device="cpu")
    if split or outcome == int(rk.BINS_TOO_SMALL):
        run(int(rk.FILL), False)
    if counts is not None:
        tally = layout.sync_view
        counts.update(clusters=cluster_count, off_screen=int(tally[int(rk.CLUSTERS_OFF_SCREEN)]),
                      deferred=int(tally[int(rk.CLUSTERS_DEFERRED)]), occluded=int(tally[int(rk.CLUSTERS_OCCLUDED)]),
                      facing_away=int(tally[int(rk.CLUSTERS_FACING_AWAY)]))
    if timings is not None:
        timings["samples"] = t_samples - clock
        timings["binning"] = t_binned - t_samples
        timings["raster"] = time.perf_counter() - t_binned
    return out


def decode(buffer) -> tuple[np.ndarray, np.ndarray]:
    """(triangle ids, depths) of a visibility buffer as NumPy arrays of its shape: ids int64 with
    -1 where nothing was hit, depths float32 with +inf there."""
    entries = buffer.numpy() if isinstance(buffer, wp.array) else np.asarray(buffer, dtype=np.uint64)
    miss = entries == np.uint64(NO_TRIANGLE)
    ids = np.where(miss, -1, (entries & np.uint64(0xFFFFFFFF)).astype(np.int64))
    depths = (entries >> np.uint64(32)).astype(np.uint32).view(np.float32).copy()
    depths[miss] = np.inf
    return ids, depths


_scratch_buffers = threading.local()


def reused_buffer(purpose: str, height: int, width: int) -> wp.array:
    """A (height, width) uint64 buffer kept per calling thread and ``purpose`` for ``out=``: fresh
    memory page-faults on first touch, which costs more than rasterizing into it. Its contents
    are overwritten by the next call with the same purpose on the same thread."""
    cache = _scratch_buffers.__dict__.setdefault("buffers", {})
    buffer = cache.get(purpose)
    if buffer is None or buffer.shape != (height, width):
        buffer = cache[purpose] = wp.empty((height, width), dtype=wp.uint64, device="cpu")
    return buffer
