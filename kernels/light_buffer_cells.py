"""The cells' lists of the light buffers: per view of a light, the triangles that may be seen
through each cell, nearest to the light first (count_cells, fill_cells, then sort_cell as
finish_cells runs it), but those of a closed mesh that face away from a light outside it
(never_first_blocker); and each light's clearance, within which no triangle lies
(nearest_surface_distance)."""

import warp as wp

from .light_buffer import ITEMS_PER_THREAD, NEAR_SHRINK
from .light_buffer_planes import never_first_blocker
from .projection import Projection, camera_coordinates, clamped_rect, empty_rect, screen_point
from .robust import RAY_FAR, to_double
from .scene_data import triangle_corners
from .triangle_setup import clipped_rect

wp.set_module_options({"enable_backward": False})

# Margin, in cells, of triangle rectangles and query rectangles: far above the rounding of the
# float64 projections (1e-12 cells), so that a ray and a triangle it meets always share a cell.
CELL_MARGIN = wp.constant(wp.float64(1.0e-3))


@wp.func
def point_segment_distance(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d) -> wp.float64:
    ab = b - a
    length_sq = wp.dot(ab, ab)
    s = wp.float64(0.0)
    if length_sq > wp.float64(0.0):
        s = wp.clamp(wp.dot(p - a, ab) / length_sq, wp.float64(0.0), wp.float64(1.0))
    return wp.length(p - (a + ab * s))


@wp.func
def point_triangle_distance(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> wp.float64:
    """Distance from p to triangle abc: to its plane where p's foot falls inside, else to the
    nearest edge (Ericson 2005, 5.1.5)."""
    n = wp.cross(b - a, c - a)
    n_sq = wp.dot(n, n)
    if n_sq > wp.float64(0.0):
        inside = (wp.dot(wp.cross(b - a, p - a), n) >= wp.float64(0.0)
                  and wp.dot(wp.cross(c - b, p - b), n) >= wp.float64(0.0)
                  and wp.dot(wp.cross(a - c, p - c), n) >= wp.float64(0.0))
        if inside:
            return wp.abs(wp.dot(p - a, n)) / wp.sqrt(n_sq)
    return wp.min(point_segment_distance(p, a, b),
                  wp.min(point_segment_distance(p, b, c), point_segment_distance(p, c, a)))


@wp.func
def screen_bounds(proj: Projection, c0: wp.vec3d, c1: wp.vec3d, c2: wp.vec3d) -> wp.vec4d:
    """(x_min, y_min, x_max, y_max), in cells, of a triangle wholly in front of the view, given
    its vertices' camera coordinates."""
    s0 = screen_point(proj, c0)
    s1 = screen_point(proj, c1)
    s2 = screen_point(proj, c2)
    return wp.vec4d(wp.min(s0[0], wp.min(s1[0], s2[0])), wp.min(s0[1], wp.min(s1[1], s2[1])),
                    wp.max(s0[0], wp.max(s1[0], s2[0])), wp.max(s0[1], wp.max(s1[1], s2[1])))


@wp.func
def cell_rect(proj: Projection, x_min: wp.float64, y_min: wp.float64, x_max: wp.float64, y_max: wp.float64) -> wp.vec4i:
    """Cells (inclusive, clamped to the view) of a rectangle in cell units, grown by CELL_MARGIN."""
    r = wp.float64(proj.width)
    low = wp.float64(-1.0)
    x0 = int(wp.floor(wp.clamp(x_min - CELL_MARGIN, low, r)))
    y0 = int(wp.floor(wp.clamp(y_min - CELL_MARGIN, low, r)))
    x1 = int(wp.floor(wp.clamp(x_max + CELL_MARGIN, low, r)))
    y1 = int(wp.floor(wp.clamp(y_max + CELL_MARGIN, low, r)))
    return clamped_rect(x0, y0, x1, y1, proj.width, proj.height)


@wp.func
def triangle_cells(proj: Projection, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> wp.vec4i:
    """Cells the part of a triangle in front of the view may be seen through, conservatively."""
    c0 = camera_coordinates(proj, p0)
    c1 = camera_coordinates(proj, p1)
    c2 = camera_coordinates(proj, p2)
    zero = wp.float64(0.0)
    if c0[2] <= zero and c1[2] <= zero and c2[2] <= zero:
        return empty_rect()
    if proj.orthographic == 0 and (c0[2] <= zero or c1[2] <= zero or c2[2] <= zero):
        return clipped_rect(proj, p0, p1, p2)
    b = screen_bounds(proj, c0, c1, c2)
    return cell_rect(proj, b[0], b[1], b[2], b[3])


@wp.func
def triangle_nearness(proj: Projection, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> float:
    """A lower bound of the distance from a pinhole view's eye (the light) to the triangle, or of
    its depth in a parallel view."""
    if proj.orthographic != 0:
        z = wp.min(camera_coordinates(proj, p0)[2], wp.min(camera_coordinates(proj, p1)[2],
                                                           camera_coordinates(proj, p2)[2]))
        return float(z - wp.abs(z) * wp.float64(NEAR_SHRINK))
    d = point_triangle_distance(proj.eye, to_double(p0), to_double(p1), to_double(p2))
    return float(d * (wp.float64(1.0) - wp.float64(NEAR_SHRINK)))


@wp.func
def listed_cells(closed: wp.array(dtype=wp.uint8), face: int, proj: Projection, p0: wp.vec3, p1: wp.vec3,
                 p2: wp.vec3) -> wp.vec4i:
    """The cells of one view whose lists hold triangle ``face``: triangle_cells, none where
    never_first_blocker."""
    if never_first_blocker(closed, face, proj, p0, p1, p2):
        return empty_rect()
    return triangle_cells(proj, p0, p1, p2)


@wp.kernel
def count_cells(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), proj: Projection,
                first_entry: int, triangles: int, closed: wp.array(dtype=wp.uint8), counts: wp.array(dtype=wp.int32)):
    """Per cell of one view (entries first_entry...), how many triangles it lists (all but those
    never_first_blocker); one launch per view, whose cells no other launch touches."""
    start = wp.tid() * ITEMS_PER_THREAD
    for face in range(start, wp.min(start + ITEMS_PER_THREAD, triangles)):
        c = triangle_corners(indices, face)
        r = listed_cells(closed, face, proj, positions[c[0]], positions[c[1]], positions[c[2]])
        for y in range(r[1], r[3] + 1):
            for x in range(r[0], r[2] + 1):
                e = first_entry + y * proj.width + x
                counts[e] = counts[e] + 1


@wp.kernel
def fill_cells(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), proj: Projection,
               first_entry: int, triangles: int, closed: wp.array(dtype=wp.uint8),
               cursors: wp.array(dtype=wp.int32), cell_faces: wp.array(dtype=wp.int32),
               cell_near: wp.array(dtype=float)):
    """Each triangle appended to the lists of the cells of one view it may be seen through (but
    those never_first_blocker)."""
    start = wp.tid() * ITEMS_PER_THREAD
    for face in range(start, wp.min(start + ITEMS_PER_THREAD, triangles)):
        c = triangle_corners(indices, face)
        p0 = positions[c[0]]
        p1 = positions[c[1]]
        p2 = positions[c[2]]
        r = listed_cells(closed, face, proj, p0, p1, p2)
        if r[0] <= r[2]:
            near = triangle_nearness(proj, p0, p1, p2)
            for y in range(r[1], r[3] + 1):
                for x in range(r[0], r[2] + 1):
                    e = first_entry + y * proj.width + x
                    slot = cursors[e]
                    cell_faces[slot] = face
                    cell_near[slot] = near
                    cursors[e] = slot + 1


@wp.func
def sort_cell(e: int, cell_start: wp.array(dtype=wp.int32), cell_faces: wp.array(dtype=wp.int32),
              cell_near: wp.array(dtype=float)):
    """Cell e's list in ascending nearness: Shell sort with gaps shrinking by 2.25 (Ciura 2001's
    ratio), in place, fast on the usual short lists and not quadratic on long ones."""
    begin = cell_start[e]
    n = cell_start[e + 1] - begin
    gap = n
    while gap > 1:
        gap = wp.max(1, int(float(gap) / 2.25))
        for i in range(begin + gap, begin + n):
            near = cell_near[i]
            face = cell_faces[i]
            j = i
            while j - gap >= begin and cell_near[j - gap] > near:
                cell_near[j] = cell_near[j - gap]
                cell_faces[j] = cell_faces[j - gap]
                j -= gap
            cell_near[j] = near
            cell_faces[j] = face


@wp.kernel
def nearest_surface_distance(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    """Distance from each point to the nearest triangle of ``mesh`` (RAY_FAR for an empty one)."""
    i = wp.tid()
    out[i] = RAY_FAR
    q = wp.mesh_query_point_no_sign(mesh, points[i], RAY_FAR)
    if q.result:
        out[i] = wp.length(wp.mesh_eval_position(mesh, q.face, q.u, q.v) - points[i])
