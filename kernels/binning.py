"""Binning (sort-middle): each launch goes through its triangles' screen rectangles, draws the small
ones into the buffer at once and lists the others with the TILE_SIZE tiles they touch counted;
the bins are then laid out, each tile's owner by owner, and filled, and each tile is drawn from its
bin by the one launch that takes it."""

import warp as wp

from .camera import CameraData
from .coverage import pixel_centre_depth, rasterize_homogeneous, rasterize_triangle, trace_triangle
from .projection import HALF_PIXEL, SUBPIXEL_BITS, Projection, camera_coordinates, empty_rect
from .scene_data import triangle_corners
from .triangle_setup import (BEHIND_CAMERA, OUTSIDE_GUARD_BAND, RasterMesh, are_valid_indices, clipped_rect,
                             is_projected, projected_rect, rect_pixels, signed_area)
from .visibility_buffer import VisibilityTarget, keep_nearest, prefetch_row_span, visibility_entry

wp.set_module_options({"enable_backward": False})

# Screen tiles are TILE_SIZE x TILE_SIZE pixels; each is rasterized by one thread, alone.
TILE_SIZE = wp.constant(32)
# Triangles whose screen rectangle spans at most this many pixels are drawn as soon as they are
# projected, with atomic minima, instead of being binned into tiles and read again: for a
# triangle this small, binning and reading it back cost more than its few contended writes.
SMALL_TRIANGLE_PIXELS = wp.constant(64)


@wp.struct
class Bins:
    """The triangles each launch (its owner index) listed and the TILE_SIZE tiles' bins of them:
    per owner, its count of listed triangles (binned_count), their faces and screen rectangles at
    [owner triangles, + binned_count[owner]) of binned_face and binned_rect, its per-tile counts
    (row ``owner`` of tile_counts) and its flag for an index out of range (bad_indices); then, laid
    out by bin_offsets, where each tile's bin starts (bin_start, tiles + 1 entries), each owner's
    cursor in it (cursors), the length of all bins (bin_total[0]), the bins' entries (slots of the
    lists, in ``slots``) and the tiles with a nonempty bin (busy_tiles)."""

    tiles_x: int
    binned_count: wp.array(dtype=wp.int32)
    binned_face: wp.array(dtype=wp.int32)
    binned_rect: wp.array(dtype=wp.vec4i)
    tile_counts: wp.array2d(dtype=wp.int32)
    bad_indices: wp.array(dtype=wp.int32)
    cursors: wp.array2d(dtype=wp.int32)
    bin_start: wp.array(dtype=wp.int32)
    bin_total: wp.array(dtype=wp.int64)
    slots: wp.array(dtype=wp.int32)
    busy_tiles: wp.array(dtype=wp.int32)


_TRIANGLES_WITH_SAMPLES = """
    // For each triangle [first, end) (at most 64), whether count_triangle has anything to do:
    // clear only where its indices are valid, its vertices projected and its screen rectangle
    // (projected_rect) holds no sample. Branch-free over the triangles, so that the compiler
    // runs several at once in vector registers.
    const wp::int32* corner = (const wp::int32*)indices.data;
    const wp::int32* q = (const wp::int32*)screen.data;
    const wp::uint32 n = (wp::uint32)vertex_count;
    const wp::int64 half = HALF, one = 1;
    const int count = end - first;
    if (indices.strides[0] != sizeof(wp::int32) || screen.strides[0] != 2 * sizeof(wp::int32))
        return count >= 64 ? ~(wp::uint64)0 : (((wp::uint64)1 << count) - 1);  // strided: all of them
    wp::uint8 busy[64];
    for (int k = 0; k < count; ++k) {
        const size_t t = 3 * (size_t)(first + k);
        const wp::int32 i0 = corner[t], i1 = corner[t + 1], i2 = corner[t + 2];
        const bool valid = (wp::uint32)i0 < n && (wp::uint32)i1 < n && (wp::uint32)i2 < n;
        const wp::int32 j0 = valid ? i0 : 0, j1 = valid ? i1 : 0, j2 = valid ? i2 : 0;
        const wp::int32 x0 = q[2 * (size_t)j0], y0 = q[2 * (size_t)j0 + 1], x1 = q[2 * (size_t)j1];
        const wp::int32 y1 = q[2 * (size_t)j1 + 1], x2 = q[2 * (size_t)j2], y2 = q[2 * (size_t)j2 + 1];
        const bool projected = x0 > OUTSIDE && x1 > OUTSIDE && x2 > OUTSIDE;
        const wp::int64 lx = x0 < x1 ? (x0 < x2 ? x0 : x2) : (x1 < x2 ? x1 : x2);
        const wp::int64 hx = x0 > x1 ? (x0 > x2 ? x0 : x2) : (x1 > x2 ? x1 : x2);
        const wp::int64 ly = y0 < y1 ? (y0 < y2 ? y0 : y2) : (y1 < y2 ? y1 : y2);
        const wp::int64 hy = y0 > y1 ? (y0 > y2 ? y0 : y2) : (y1 > y2 ? y1 : y2);
        // sampled_pixel_range, then clamped_rect
        wp::int64 px0, px1, py0, py1;
        if (spp == 1) {
            px0 = -((half - lx) >> BITS); px1 = (hx - half) >> BITS;
            py0 = -((half - ly) >> BITS); py1 = (hy - half) >> BITS;
        } else {
            px0 = (lx - one) >> BITS; px1 = hx >> BITS;
            py0 = (ly - one) >> BITS; py1 = hy >> BITS;
        }
        px0 = px0 > 0 ? px0 : 0; py0 = py0 > 0 ? py0 : 0;
        px1 = px1 < width - 1 ? px1 : width - 1; py1 = py1 < height - 1 ? py1 : height - 1;
        const bool empty = px0 > px1 || py0 > py1;
        busy[k] = !(valid && projected && empty);
    }
    wp::uint64 mask = 0;
    for (int k = 0; k < count; ++k) mask |= (wp::uint64)busy[k] << k;
    return mask;
"""
for name, value in (("HALF", str(int(HALF_PIXEL))), ("BITS", str(int(SUBPIXEL_BITS))),
                    ("OUTSIDE", str(int(OUTSIDE_GUARD_BAND)))):
    _TRIANGLES_WITH_SAMPLES = _TRIANGLES_WITH_SAMPLES.replace(name, value)


@wp.func_native(_TRIANGLES_WITH_SAMPLES)
def triangles_to_count(indices: wp.array(dtype=wp.int32), screen: wp.array(dtype=wp.vec2i), vertex_count: int,
                       first: int, end: int, spp: int, width: int, height: int) -> wp.uint64:
    """Bit k set where count_triangle has anything to do for triangle first + k (end - first <=
    64, contiguous index and screen arrays): all but the triangles whose vertices are projected
    and whose screen rectangle holds no sample, most of a dense mesh's, found without a branch
    each."""
    ...


@wp.func_native("return __builtin_ctzll(mask);")
def lowest_set_bit(mask: wp.uint64) -> int:
    """The index of the lowest set bit of a nonzero mask."""
    ...


@wp.func
def count_triangle(mesh: RasterMesh, proj: Projection, target: VisibilityTarget, bins: Bins, face: int, owner: int):
    """Triangle ``face``, taken by launch ``owner``: dropped if it covers no sample or is culled;
    drawn now if small; else listed in the owner's part of ``bins`` and counted per tile it
    touches. An index out of range sets the owner's bad_indices flag (nothing is read through it)."""
    c = triangle_corners(mesh.indices, face)
    if not are_valid_indices(c, mesh.vertex_count):
        bins.bad_indices[owner] = 1
        return
    q0 = mesh.screen[c[0]]
    q1 = mesh.screen[c[1]]
    q2 = mesh.screen[c[2]]
    r = empty_rect()
    if is_projected(q0) and is_projected(q1) and is_projected(q2):
        # the rectangle first: most triangles of a dense mesh hold no sample and end here
        r = projected_rect(q0, q1, q2, target.spp, proj.width, proj.height)
        if r[0] > r[2]:
            return
        area = signed_area(q0, q1, q2)
        if area == wp.int64(0):
            return
        if mesh.cull_back_faces.shape[0] > 0:
            if mesh.cull_back_faces[face] != wp.uint8(0) and area * proj.back_facing_sign > wp.int64(0):
                return
        if rect_pixels(r) <= SMALL_TRIANGLE_PIXELS:
            # drawn now, with atomic minima, rather than binned and read again: most triangles of a
            # dense mesh are this small, and a third of them (a million-triangle model at 1024²)
            # span a single pixel
            if target.spp == 1 and rect_pixels(r) == 1:
                covered, depth = pixel_centre_depth(q0, q1, q2, mesh.depth_weights[c[0]], mesh.depth_weights[c[1]],
                                                    mesh.depth_weights[c[2]], r[0], r[1], proj.orthographic)
                if covered:
                    keep_nearest(target.out, r[1], r[0], visibility_entry(depth, face), True)
                return
            rasterize_triangle(face, q0, q1, q2, mesh.depth_weights[c[0]], mesh.depth_weights[c[1]],
                               mesh.depth_weights[c[2]], r, target.samples, target.spp, proj.orthographic, target.out,
                               True)
            return
    else:
        if proj.orthographic != 0:
            return
        if q0[0] == BEHIND_CAMERA and q1[0] == BEHIND_CAMERA and q2[0] == BEHIND_CAMERA:
            return
        r = clipped_rect(proj, mesh.positions[c[0]], mesh.positions[c[1]], mesh.positions[c[2]])
        if r[0] > r[2]:
            return
    # the owner is the launch drawing this triangle: its list and counts need no atomics
    slot = owner * mesh.triangles + bins.binned_count[owner]
    bins.binned_count[owner] = bins.binned_count[owner] + 1
    bins.binned_face[slot] = face
    bins.binned_rect[slot] = r
    for ty in range(r[1] / TILE_SIZE, r[3] / TILE_SIZE + 1):
        for tx in range(r[0] / TILE_SIZE, r[2] / TILE_SIZE + 1):
            tile = ty * bins.tiles_x + tx
            bins.tile_counts[owner, tile] = bins.tile_counts[owner, tile] + 1


@wp.func
def bin_offsets(bins: Bins) -> int:
    """Run by one thread: bins are contiguous per tile, each owner's part (the triangles a launch
    binned) after the previous owners'. bin_start[tile] is where a tile's bin starts,
    cursors[owner, tile] where an owner's part of it does, bin_total[0] the length of all bins
    (exact in int64; offsets are meaningful only if it is below 2^31). Returns how many tiles have
    a nonempty bin, listed at the start of busy_tiles in row-major order."""
    tiles = bins.tile_counts.shape[1]
    end = wp.int64(0)
    for tile in range(tiles):
        bins.bin_start[tile] = int(end)
        for owner in range(bins.tile_counts.shape[0]):
            bins.cursors[owner, tile] = int(end)
            end = end + wp.int64(bins.tile_counts[owner, tile])
    bins.bin_start[tiles] = int(end)
    bins.bin_total[0] = end
    busy = int(0)
    for tile in range(tiles):
        if bins.bin_start[tile + 1] > bins.bin_start[tile]:
            bins.busy_tiles[busy] = tile
            busy += 1
    return busy


@wp.func
def bin_triangle(bins: Bins, slot: int, owner: int):
    """The listed triangle ``slot`` (launch ``owner``'s) appended to the bin of every tile its
    rectangle touches, at the owner's cursor there."""
    r = bins.binned_rect[slot]
    for ty in range(r[1] / TILE_SIZE, r[3] / TILE_SIZE + 1):
        for tx in range(r[0] / TILE_SIZE, r[2] / TILE_SIZE + 1):
            tile = ty * bins.tiles_x + tx
            at = bins.cursors[owner, tile]
            bins.slots[at] = slot
            bins.cursors[owner, tile] = at + 1


@wp.func
def rasterize_tile(tile: int, mesh: RasterMesh, bins: Bins, target: VisibilityTarget, cam: CameraData,
                   proj: Projection):
    """Every triangle of a tile's bin drawn into it, by the one thread that owns it (no atomics)."""
    tile_x0 = (tile % bins.tiles_x) * TILE_SIZE
    tile_y0 = (tile / bins.tiles_x) * TILE_SIZE
    tile_x1 = wp.min(tile_x0 + TILE_SIZE, proj.width) - 1
    tile_y1 = wp.min(tile_y0 + TILE_SIZE, proj.height) - 1
    if bins.bin_start[tile + 1] > bins.bin_start[tile]:
        for row in range(tile_y0, tile_y1 + 1):
            prefetch_row_span(target.out, row, tile_x0 * target.spp, (tile_x1 - tile_x0 + 1) * target.spp)
    for k in range(bins.bin_start[tile], bins.bin_start[tile + 1]):
        slot = bins.slots[k]
        face = bins.binned_face[slot]
        r = bins.binned_rect[slot]
        rect = wp.vec4i(wp.max(r[0], tile_x0), wp.max(r[1], tile_y0), wp.min(r[2], tile_x1), wp.min(r[3], tile_y1))
        c = triangle_corners(mesh.indices, face)
        q0 = mesh.screen[c[0]]
        q1 = mesh.screen[c[1]]
        q2 = mesh.screen[c[2]]
        if is_projected(q0) and is_projected(q1) and is_projected(q2):
            rasterize_triangle(face, q0, q1, q2, mesh.depth_weights[c[0]], mesh.depth_weights[c[1]],
                               mesh.depth_weights[c[2]], rect, target.samples, target.spp, proj.orthographic,
                               target.out, False)
        else:
            p0 = mesh.positions[c[0]]
            p1 = mesh.positions[c[1]]
            p2 = mesh.positions[c[2]]
            if not rasterize_homogeneous(face, camera_coordinates(proj, p0), camera_coordinates(proj, p1),
                                         camera_coordinates(proj, p2), rect, target.samples, target.spp, proj,
                                         target.out):
                trace_triangle(face, p0, p1, p2, rect, target.samples, target.spp, cam, proj, target.out)
