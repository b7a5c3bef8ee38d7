"""Primary visibility by rasterization: per sample, the nearest triangle and its depth, in the
visibility buffer (kernels/visibility_buffer.py), drawn by visibility_pipeline.

visibility_pipeline runs the stages, launched once per thread, the launches meeting at barriers
(kernels/barriers.py): the buffer cleared and vertices projected (kernels/triangle_setup.py); then
per triangle its screen rectangle, small triangles drawn at once with atomic minima and larger
ones binned into tiles; then the binned ones drawn, tile by tile (kernels/binning.py; the
coverage of one triangle: kernels/coverage.py). Each launch takes the triangles of its own range
of the mesh and the tiles of its own band of the image first, then what is left of the others'
(kernels/work_queue.py). Given a mesh's clusters (kernels/occlusion.py), it skips those off
screen or (where flagged) facing away and, where enough face away, draws in two passes: the
clusters facing the eye first, then those facing away that the first pass does not hide. A
parallel projection (Projection.orthographic) serves directional lights' shadow maps.
"""

import warp as wp

from .barriers import SPINS_BEFORE_YIELD, all_arrived, all_done, wait_for_release
from .binning import Bins, bin_offsets, bin_triangle, count_triangle, lowest_set_bit, rasterize_tile, triangles_to_count
from .camera import CameraData
from .occlusion import (CLUSTER_SIZE, MAX_TESTED_SAMPLES, NOT_DEFERRED, SKIPPED, all_flagged, cluster_view, faces_away,
                        faces_eye, is_occluded, outside_view)
from .projection import Projection, camera_projection, has_usable_axes
from .triangle_setup import RasterMesh, project_vertices, rect_pixels
from .visibility_buffer import VisibilityTarget, clear_row_span, visibility_entry
from .work_queue import add_atomically, reset_range, take_next_from_ranges, take_next_item_from

wp.set_module_options({"enable_backward": False})

# Slots of the int32 ``sync`` array shared by a call's launches: the work queue of filling; one
# arrival counter per barrier; the abort flag (set from Python when a launch fails to
# start, lest the others wait for it forever); the outcome of binning.
QUEUE_FILL = wp.constant(0)
BARRIER_PROJECTED = wp.constant(1)
BARRIER_COUNTED = wp.constant(2)
BARRIER_OFFSETS = wp.constant(3)
BARRIER_FILLED = wp.constant(4)
ABORTED = wp.constant(5)
OUTCOME = wp.constant(6)
# with occlusion culling: one more barrier, and how many clusters were off screen, deferred,
# then found occluded, and culled as facing away
BARRIER_DRAWN_FIRST = wp.constant(7)
CLUSTERS_OFF_SCREEN = wp.constant(8)
CLUSTERS_DEFERRED = wp.constant(9)
CLUSTERS_OCCLUDED = wp.constant(10)
CLUSTERS_FACING_AWAY = wp.constant(11)
# whether this call draws in two passes (occlusion_pass_pays, decided by launch 0)
OCCLUSION_PASS = wp.constant(12)
# the queue of the first stage's pieces (rows to clear, vertices to project)
QUEUE_START = wp.constant(13)
# the launches done, which launch 0 waits for before it returns
FINISHED = wp.constant(14)
# the launches stopping after binning, which launch 0 waits for likewise
STOPPED_AFTER_BINNING = wp.constant(15)
SYNC_SLOTS = 16
# Pieces of the first stage per launch.
START_PIECES_PER_LAUNCH = wp.constant(8)
# Outcomes of binning: drawn (or drawing), an index out of range (nothing read through it), or
# more triangle-tile pairs than the bins hold (in ``bin_total``; grow them and resume at FILL).
BINNED = wp.constant(0)
BAD_INDEX = wp.constant(1)
BINS_TOO_SMALL = wp.constant(2)
# The camera's axes are not finite or not independent (nothing drawn).
BAD_CAMERA = wp.constant(3)
# Stages a launch may start at.
START = wp.constant(0)
FILL = wp.constant(1)
# What a pass over the batches draws: every triangle (no clusters); the clusters not culled, in one
# pass; or in two, first the clusters that cannot be tested or face the eye (the others
# deferred), then the deferred ones not occluded.
DRAW_ALL = wp.constant(0)
DRAW_CULLED = wp.constant(1)
DRAW_FIRST = wp.constant(2)
DRAW_UNOCCLUDED = wp.constant(3)
# Two passes where the mesh has at most this many samples per triangle and at least one cluster in
# FACING_SHARE faces away. With more samples per triangle, the triangles facing the eye are too
# large to be drawn in the first pass (they are binned, drawn last) and the tests read more
# samples for each triangle they may cull; with fewer clusters facing away, the pass's barrier
# costs more than the tests save. bench/visibility.py times the rasterizer with clusters culled
# as pw.render culls them.
SAMPLES_PER_TRIANGLE = wp.constant(16)
FACING_SHARE = wp.constant(8)
# Clusters sampled to estimate how many face away from the eye (occlusion_pass_pays).
FACING_SAMPLE = wp.constant(256)


@wp.struct
class Launches:
    """How a call's launches share the work: their count, the int32 ``sync`` slots (SYNC_SLOTS), the
    work ranges (kernels/work_queue.py; per pass one per launch, then the tiles'), the release
    word of the pool threads' launches and this call's epoch (wait_for_release), the address of
    sched_yield (all_done's ``os_yield``), and the size of the work items."""

    count: int
    sync: wp.array(dtype=wp.int32)
    batch_ranges: wp.array(dtype=wp.int64)
    released: wp.array(dtype=wp.int64)
    epoch: wp.int64
    os_yield: wp.uint64
    # triangles per batch, and batches in each launch's own range
    batch_size: int
    batch_stride: int
    # fewest vertices in a piece of projection
    min_vertex_share: int


@wp.struct
class ClusterCulling:
    """A mesh's clusters of CLUSTER_SIZE consecutive triangles (none: no culling): their bounds and
    facing (occlusion.cluster_bounds), and per cluster deferred to the second pass its screen
    rectangle and nearest depth (or its fate: NOT_DEFERRED, SKIPPED)."""

    lower: wp.array(dtype=wp.vec3)
    upper: wp.array(dtype=wp.vec3)
    axis: wp.array(dtype=wp.vec3)
    spread: wp.array(dtype=float)
    rect: wp.array(dtype=wp.vec4i)
    nearest: wp.array(dtype=wp.float64)


@wp.func
def share(n: int, parts: int, minimum: int) -> int:
    """The size of each of ``parts`` contiguous shares of n items, at least ``minimum``."""
    return wp.max(minimum, (n + parts - 1) / parts)


@wp.func
def occlusion_pass_pays(proj: Projection, clusters: ClusterCulling, triangles: int, samples_count: wp.int64) -> bool:
    """Whether drawing in two passes, the clusters facing away tested for occlusion, may pay:
    whether the triangles are small for the samples and enough clusters face away (as faces_eye
    tells them apart, estimated from FACING_SAMPLE clusters evenly spread); see
    SAMPLES_PER_TRIANGLE. Not for a height field seen from above, nor a mesh of few triangles
    for the samples."""
    if wp.int64(triangles) * wp.int64(SAMPLES_PER_TRIANGLE) < samples_count:
        return False
    count = clusters.lower.shape[0]
    sampled = int(0)
    away = int(0)
    for cluster in range(0, count, wp.max(1, count / FACING_SAMPLE)):
        sampled += 1
        if not faces_eye(proj, clusters.lower[cluster], clusters.upper[cluster], clusters.axis[cluster]):
            away += 1
    return away * FACING_SHARE >= sampled


@wp.func
def count_batch(draw: int, batch: int, owner: int, batch_size: int, mesh: RasterMesh, proj: Projection,
                target: VisibilityTarget, bins: Bins, clusters: ClusterCulling) -> wp.vec4i:
    """count_triangle for the triangles of ``batch`` that pass ``draw`` (DRAW_ALL, ...), cluster
    by cluster, the binned ones listed as launch ``owner``'s; DRAW_FIRST records the deferred
    clusters' rectangles and nearest depths. Returns how many clusters were off screen, deferred,
    occluded and culled as facing away."""
    end = wp.min((batch + 1) * batch_size, mesh.triangles)
    first_cluster = batch * batch_size / CLUSTER_SIZE
    end_cluster = (end + CLUSTER_SIZE - 1) / CLUSTER_SIZE
    off_screen = int(0)
    facing_away = int(0)
    deferred = int(0)
    occluded = int(0)
    # the clusters' fates first, in a loop of their own, which keeps the drawing loop below as
    # lean as without clusters (tests inlined into it slow the drawing of every triangle)
    if draw == DRAW_CULLED or draw == DRAW_FIRST:
        for cluster in range(first_cluster, end_cluster):
            fate = NOT_DEFERRED
            lo = clusters.lower[cluster]
            hi = clusters.upper[cluster]
            # cheap tests first: most clusters are drawn or dropped on them
            if outside_view(proj, lo, hi):
                off_screen += 1
                fate = SKIPPED
            elif not faces_eye(proj, lo, hi, clusters.axis[cluster]):
                # (nested: Warp evaluates both sides of ``and``)
                if mesh.cull_back_faces.shape[0] > 0:
                    if faces_away(proj, lo, hi, clusters.axis[cluster], clusters.spread[cluster]):
                        if all_flagged(mesh.cull_back_faces, cluster * CLUSTER_SIZE,
                                            wp.min((cluster + 1) * CLUSTER_SIZE, end)):
                            facing_away += 1
                            fate = SKIPPED
                if fate == NOT_DEFERRED and draw == DRAW_FIRST:
                    rect, nearest = cluster_view(proj, lo, hi, target.spp)
                    if rect[0] > rect[2]:
                        off_screen += 1
                        fate = SKIPPED
                    elif nearest > wp.float64(0.0) and rect_pixels(rect) * target.spp <= MAX_TESTED_SAMPLES:
                        clusters.rect[cluster] = rect
                        fate = nearest
                        deferred += 1
            clusters.nearest[cluster] = fate
    if draw == DRAW_UNOCCLUDED:
        for cluster in range(first_cluster, end_cluster):
            if clusters.nearest[cluster] > wp.float64(0.0):
                # entries order by depth first and positive float32 depths by their bits: one
                # below this bound has a depth under the float32 nearest rounds to, so at most
                # the float32 below it, which lies below nearest
                bound = visibility_entry(float(clusters.nearest[cluster]), 0)
                if is_occluded(target.out, clusters.rect[cluster], target.spp, bound):
                    clusters.nearest[cluster] = SKIPPED
                    occluded += 1
    for cluster in range(first_cluster, end_cluster):
        drawn = True
        if draw == DRAW_CULLED or draw == DRAW_FIRST:
            drawn = clusters.nearest[cluster] == NOT_DEFERRED
        elif draw != DRAW_ALL:
            drawn = clusters.nearest[cluster] > wp.float64(0.0)
        if drawn:
            base = cluster * CLUSTER_SIZE
            busy = triangles_to_count(mesh.indices, mesh.screen, mesh.vertex_count, base,
                                      wp.min(base + CLUSTER_SIZE, end), target.spp, proj.width, proj.height)
            while busy != wp.uint64(0):
                face = base + lowest_set_bit(busy)
                busy = busy & (busy - wp.uint64(1))
                count_triangle(mesh, proj, target, bins, face, owner)
    return wp.vec4i(off_screen, deferred, occluded, facing_away)


@wp.kernel
def visibility_pipeline(launch: int, first_stage: int, stop_after_binning: int, work: Launches, mesh: RasterMesh,
                        cam: CameraData, orthographic: int, target: VisibilityTarget, bins: Bins,
                        clusters: ClusterCulling):
    """The whole visibility buffer (target.out): launched with one index on each of work.count
    threads (``launch`` = 0, 1, ...) side by side, which meet at spinning barriers (all_arrived)
    between stages.

    From START: the buffer's rows cleared and the vertices projected, in pieces taken from a queue
    (launch 0 first decides on the occlusion pass and sets out the batch ranges), until all are done
    (all_done); then batches of work.batch_size triangles: launch k owns the range of
    work.batch_stride batches from k batch_stride (in work.batch_ranges: a set of ranges per pass,
    one for the tiles) and takes them in order, then takes what is left of the others' ranges from
    their ends
    (take_next_from_ranges), so that each draws a region of the mesh of its own, on screen mostly
    apart from the others', and finds the buffer's lines there in its own core's cache (with one
    queue shared by all, each launch would draw all over the mesh and the image):
    small triangles drawn into the buffer at once (atomically, as another launch may draw the same
    sample), the others that may cover a sample listed by the launch that drew them (their owner)
    with their screen rectangles at bins.binned_face and bins.binned_rect [owner triangles, +
    binned_count[owner]) and counted per tile they touch in row ``owner`` of bins.tile_counts (no
    atomics), or the owner's bins.bad_indices set for a triangle with an index out of range (it
    is not read). Batches are small (a few clusters) so that launches finish a pass together; the
    binning, owned per launch rather than per batch, does not grow with their number. With
    ``clusters`` (nonempty) the batches are drawn cluster by cluster (count_batch), but for the
    clusters off screen or facing away from the eye where every triangle is flagged for culling; where occlusion_pass_pays (launch 0 decides it, in work.sync), in two passes:
    first those facing the eye or not testable, the others deferred (their rectangle and nearest
    depth kept in clusters.rect and clusters.nearest); then, once every launch has drawn its
    first-pass batches, the deferred clusters that what the buffer holds by then does not hide
    (is_occluded), their batches taken from the second pass's ranges. Launch 0 then lays out the
    bins (bin_offsets) and records the OUTCOME in work.sync; all stop unless it is BINNED (or if
    stop_after_binning, to time the parts apart). From FILL: each listed triangle's slot appended
    to the bin of every tile its rectangle touches, owner by owner from another queue; then the
    tiles with a nonempty bin (bins.busy_tiles, in row-major order), a band of them per launch
    taken as the batches are, each drawn by the launch that took it alone (rasterize_tile). Every queue
    and range hands out work to whichever launch asks first, so one with cheaper work (culled
    back faces, triangles off screen) takes more. The projection is cam's (camera_projection,
    parallel if ``orthographic``); a camera without usable axes draws nothing, its OUTCOME
    BAD_CAMERA. Launch 0 returns only once every launch is done (the FINISHED count), so that the
    buffer is complete when it has, the others once work.released[0] has reached work.epoch too
    (wait_for_release); a call that stops after binning, only once every launch has left the
    barrier before it (the STOPPED_AFTER_BINNING count), as the caller may zero work.sync for its
    next call at once: a launch still waiting there would never see its count reached. work.sync
    must be zeroed before a call (and its FILL barrier, queues and outcome before resuming
    there); work.os_yield is all_arrived's.
    """
    # each launch derives the same projection (computing it costs less than packing it in Python)
    proj = camera_projection(cam, orthographic)
    if not has_usable_axes(cam):
        if launch == 0:
            work.sync[OUTCOME] = BAD_CAMERA
        return
    launches = work.count
    sync = work.sync
    if first_stage == START:
        samples_count = wp.int64(target.out.shape[0]) * wp.int64(target.out.shape[1])
        done = int(0)
        if launch == 0:
            # one unit of the stage's work, done before launch 0 takes any other
            if clusters.lower.shape[0] > 0:
                if occlusion_pass_pays(proj, clusters, mesh.triangles, samples_count):
                    sync[OCCLUSION_PASS] = 1
            batches = (mesh.triangles + work.batch_size - 1) / work.batch_size
            for k in range(2 * launches):  # each pass's batch ranges, one per launch
                range_owner = k % launches
                reset_range(work.batch_ranges, k, range_owner * work.batch_stride,
                            wp.min((range_owner + 1) * work.batch_stride, batches))
            done = 1
        # the buffer's rows cleared and the vertices projected in pieces taken from a queue: a
        # launch that starts late (a pool thread's wake-up) finds its share done by the others
        pieces = launches * START_PIECES_PER_LAUNCH
        rows = share(proj.height, pieces, 1)
        row_pieces = (proj.height + rows - 1) / rows
        vertices = share(mesh.vertex_count, pieces, work.min_vertex_share)
        vertex_pieces = (mesh.vertex_count + vertices - 1) / vertices
        piece = take_next_item_from(sync, QUEUE_START)
        while piece < row_pieces + vertex_pieces:
            if piece < row_pieces:
                for row in range(piece * rows, wp.min((piece + 1) * rows, proj.height)):
                    clear_row_span(target.out, row, 0, target.out.shape[1])
            else:
                first = (piece - row_pieces) * vertices
                project_vertices(mesh.positions, proj.to_camera, proj.eye, proj.half_width, proj.half_height,
                                 proj.orthographic, first, wp.min(first + vertices, mesh.vertex_count), mesh.screen,
                                 mesh.depth_weights)
            done += 1
            piece = take_next_item_from(sync, QUEUE_START)
        # small triangles are drawn into the cleared buffer from projected vertices
        if not all_done(sync, BARRIER_PROJECTED, done, row_pieces + vertex_pieces + 1, ABORTED, SPINS_BEFORE_YIELD,
                        work.os_yield):
            return
        passes = int(1)
        draw = DRAW_ALL
        if clusters.lower.shape[0] > 0:
            draw = DRAW_CULLED
            if sync[OCCLUSION_PASS] != 0:
                passes = 2
                draw = DRAW_FIRST
        tally = wp.vec4i(0)
        for k in range(passes):
            if k == 1:
                # the clusters facing away are tested against what those facing the eye drew
                if not all_arrived(sync, BARRIER_DRAWN_FIRST, launches, ABORTED, SPINS_BEFORE_YIELD, work.os_yield):
                    return
                draw = DRAW_UNOCCLUDED
            # this launch's own range first, from its start; then the others', from their ends
            # (the owner has a name of its own here and below: reusing `owner`, a for-loop variable
            # elsewhere in this kernel, made these while loops spin forever on warp 1.19; cf.
            # NVIDIA/warp#1534, a for-loop variable's name reused in a while loop)
            batch, batch_owner = take_next_from_ranges(work.batch_ranges, k * launches, launch, launches, launch)
            while batch >= 0:
                tally = tally + count_batch(draw, batch, launch, work.batch_size, mesh, proj, target, bins, clusters)
                batch, batch_owner = take_next_from_ranges(work.batch_ranges, k * launches, launch, launches,
                                                           batch_owner)
        if draw != DRAW_ALL:
            add_atomically(sync, CLUSTERS_OFF_SCREEN, tally[0])
            add_atomically(sync, CLUSTERS_DEFERRED, tally[1])
            add_atomically(sync, CLUSTERS_OCCLUDED, tally[2])
            add_atomically(sync, CLUSTERS_FACING_AWAY, tally[3])
        if not all_arrived(sync, BARRIER_COUNTED, launches, ABORTED, SPINS_BEFORE_YIELD, work.os_yield):
            return
        if launch == 0:
            outcome = BINNED
            for owner in range(bins.bad_indices.shape[0]):
                if bins.bad_indices[owner] != 0:
                    outcome = BAD_INDEX
            if outcome == BINNED:
                busy = bin_offsets(bins)
                share = (busy + launches - 1) / launches
                for band in range(launches):  # the tiles' ranges, a band of the image each
                    reset_range(work.batch_ranges, 2 * launches + band, wp.min(band * share, busy),
                                wp.min((band + 1) * share, busy))
                if bins.bin_total[0] > wp.int64(bins.slots.shape[0]):
                    outcome = BINS_TOO_SMALL
            sync[OUTCOME] = outcome
        if not all_arrived(sync, BARRIER_OFFSETS, launches, ABORTED, SPINS_BEFORE_YIELD, work.os_yield):
            return
        if sync[OUTCOME] != BINNED or stop_after_binning != 0:
            all_done(sync, STOPPED_AFTER_BINNING, 1, wp.where(launch == 0, launches, 0), ABORTED, SPINS_BEFORE_YIELD,
                     work.os_yield)
            return
    owner = take_next_item_from(sync, QUEUE_FILL)
    while owner < bins.binned_count.shape[0]:
        first = owner * mesh.triangles
        for slot in range(first, first + bins.binned_count[owner]):
            bin_triangle(bins, slot, owner)
        owner = take_next_item_from(sync, QUEUE_FILL)
    if not all_arrived(sync, BARRIER_FILLED, launches, ABORTED, SPINS_BEFORE_YIELD, work.os_yield):
        return
    # only tiles with something to draw are handed out: taking one from a queue shared by the
    # launches fetches its counter from another core's cache, which costs more than an empty
    # tile, and dense meshes bin almost nothing; each launch draws its own band of them first,
    # then takes the others' from their ends, far from where their owners draw
    listed, tile_owner = take_next_from_ranges(work.batch_ranges, 2 * launches, launch, launches, launch)
    while listed >= 0:
        rasterize_tile(bins.busy_tiles[listed], mesh, bins, target, cam, proj)
        listed, tile_owner = take_next_from_ranges(work.batch_ranges, 2 * launches, launch, launches, tile_owner)
    # launch 0 returns once every launch is done drawing, so that the caller need not wait for the
    # pool threads' return to Python and their wake-up of it (a GIL hand-over each); the
    # launches that stop earlier all stop at the same stage, having drawn all they draw
    all_done(sync, FINISHED, 1, wp.where(launch == 0, launches, 0), ABORTED, SPINS_BEFORE_YIELD, work.os_yield)
    if launch != 0:
        wait_for_release(work.released, work.epoch, sync, ABORTED, SPINS_BEFORE_YIELD, work.os_yield)
