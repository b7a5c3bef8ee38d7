"""Marks of entries and of whole triangles. A triangle's entry in a cell is clear where every
triangle the cell lists nearer to the light lies on or behind its plane (mark_clear_entries, run by
finish_cells once the cell's list is sorted); a triangle is clear of a light where each of its
shadow rays lands in cells where it is clear (pinhole views; mark_clear_triangles), the rays'
spread over the cells bounded by spread_cells."""

import warp as wp

from .light_buffer import CLEAR, DIRECTION_ROUNDING, ITEMS_PER_THREAD, NOT_CLEAR, ORIGIN_DEVIATION, LightBuffers
from .light_buffer_cells import CELL_MARGIN, cell_rect, point_triangle_distance, screen_bounds, sort_cell
from .light_buffer_planes import LightPlane, behind_plane, largest_coordinate, no_shadow_rays_leave, origin_magnitude
from .projection import camera_coordinates, empty_rect
from .robust import to_double
from .scene_data import triangle_corners
from .shadow_map import CUBE_FACES

wp.set_module_options({"enable_backward": False})

MAX_CLEAR_CHECKS = wp.constant(64)


@wp.func
def mark_clear_entries(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32),
                       planes: wp.array(dtype=LightPlane), e: int, cell_start: wp.array(dtype=wp.int32),
                       cell_faces: wp.array(dtype=wp.int32), cell_near: wp.array(dtype=float),
                       cell_clear: wp.array(dtype=wp.uint8)):
    """Per entry of (sorted) cell e: whether its triangle is clear there. A shadow ray leaves the
    triangle's plane towards the light and stays on the light's side of it (the light lies
    LIGHT_SIDE_MARGIN off it); it can meet only triangles listed in its cell that lie nearer to the
    light than its origin; if all of those lie on or behind the plane, it meets none."""
    begin = cell_start[e]
    end = cell_start[e + 1]
    for k in range(begin, end):
        cell_clear[k] = wp.uint8(0)
        face = cell_faces[k]
        plane = planes[face]
        if plane.light_side == wp.float64(0.0):
            continue
        p0 = to_double(positions[indices[3 * face]])
        clear = bool(True)
        checked = int(0)
        for j in range(begin, end):
            if cell_near[j] >= plane.far or not clear:
                break
            if j != k:
                checked += 1
                a = triangle_corners(indices, cell_faces[j])
                clear = checked <= MAX_CLEAR_CHECKS
                for corner in range(3):
                    if clear:
                        clear = behind_plane(plane.normal, plane.normal_sq, plane.light_side, p0,
                                             to_double(positions[a[corner]]))
        if clear:
            cell_clear[k] = wp.uint8(1)


@wp.kernel
def finish_cells(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32),
                 planes: wp.array(dtype=LightPlane), width: int, first_entry: int,
                 cell_start: wp.array(dtype=wp.int32), cell_faces: wp.array(dtype=wp.int32),
                 cell_near: wp.array(dtype=float), cell_clear: wp.array(dtype=wp.uint8)):
    """Each filled cell of one row of one view sorted, then its clear entries marked (a row per
    launch index: Warp copies a kernel's arguments for every index); ``planes``: its light's."""
    row = first_entry + wp.tid() * width
    if cell_start[row] == cell_start[row + width]:
        return  # an empty row
    for e in range(row, row + width):
        sort_cell(e, cell_start, cell_faces, cell_near)
        mark_clear_entries(positions, indices, planes, e, cell_start, cell_faces, cell_near, cell_clear)


# what spread_cells found of a triangle's shadow rays in a view
RAYS_ELSEWHERE = wp.constant(0)  # they pick another view (a cube face the triangle lies wholly outside of)
RAYS_IN_CELLS = wp.constant(1)  # they land in the cells of the rectangle returned
RAYS_UNKNOWN = wp.constant(2)  # they may leave the view or its same cells


@wp.func
def ray_stray(largest: wp.float64, travel: wp.float64, magnitude: wp.float64) -> wp.float64:
    """A bound on how far a shadow ray leaving a triangle (whose largest coordinate is ``largest``)
    lies from the exact segment from the triangle towards the light, within ``travel`` of its
    start: its origin's deviation and its float32 direction's rounding (``magnitude`` bounds the
    coordinates of the triangle and the light)."""
    return largest * ORIGIN_DEVIATION + wp.float64(2.0) * wp.float64(DIRECTION_ROUNDING) * (travel + magnitude)


@wp.func
def spread_cells(buffers: LightBuffers, view: int, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, origin_scale: wp.float64):
    """(RAYS_*, cell rectangle) for the shadow rays leaving the triangle that pick view ``view``. A
    ray leaves within ORIGIN_DEVIATION of the triangle and runs towards the light, missing it by
    its direction's rounding: seen from a point light it lies within an angle `spread` of the
    triangle, in a parallel view within `stray` (world units) of it, and the triangle's rectangle
    grown by that many cells must stay in the same cells, inside the view. ``origin_scale`` as
    for farness."""
    proj = buffers.views[view]
    c0 = camera_coordinates(proj, p0)
    c1 = camera_coordinates(proj, p1)
    c2 = camera_coordinates(proj, p2)
    zero = wp.float64(0.0)
    d0 = to_double(p0)
    d1 = to_double(p1)
    d2 = to_double(p2)
    largest = origin_magnitude(d0, d1, d2, origin_scale)
    magnitude = wp.max(largest, largest_coordinate(proj.eye))
    grow = zero
    if proj.orthographic != 0:
        if c0[2] <= zero or c1[2] <= zero or c2[2] <= zero:
            return RAYS_UNKNOWN, empty_rect()
        depth = wp.max(c0[2], wp.max(c1[2], c2[2]))
        stray = ray_stray(largest, depth, magnitude)
        # cells per world unit: the view's rows scale world units to half-extents
        row_x = wp.vec3d(proj.to_camera[0, 0], proj.to_camera[0, 1], proj.to_camera[0, 2])
        row_y = wp.vec3d(proj.to_camera[1, 0], proj.to_camera[1, 1], proj.to_camera[1, 2])
        grow = stray * wp.max(proj.half_width * wp.length(row_x), proj.half_height * wp.length(row_y))
    else:
        if c0[2] <= zero and c1[2] <= zero and c2[2] <= zero:
            return RAYS_ELSEWHERE, empty_rect()
        if c0[2] <= zero or c1[2] <= zero or c2[2] <= zero:
            return RAYS_UNKNOWN, empty_rect()
        near = point_triangle_distance(proj.eye, d0, d1, d2)
        # origins lie at least this far from the light
        nearest = near - largest * ORIGIN_DEVIATION
        if nearest <= zero:
            return RAYS_UNKNOWN, empty_rect()
        spread = ray_stray(largest, near, magnitude) / nearest
        grow = spread * buffers.view_cells_per_radian[view]
    b = screen_bounds(proj, c0, c1, c2)
    r = cell_rect(proj, b[0], b[1], b[2], b[3])
    x_min = b[0] - CELL_MARGIN - grow
    y_min = b[1] - CELL_MARGIN - grow
    x_max = b[2] + CELL_MARGIN + grow
    y_max = b[3] + CELL_MARGIN + grow
    if x_max < zero or y_max < zero or x_min >= wp.float64(proj.width) or y_min >= wp.float64(proj.height):
        if proj.orthographic != 0:
            return RAYS_UNKNOWN, empty_rect()
        return RAYS_ELSEWHERE, empty_rect()
    # else the spread rectangle lies inside the view, in the same cells
    if x_min < zero or y_min < zero or x_max >= wp.float64(proj.width) or y_max >= wp.float64(proj.height):
        return RAYS_UNKNOWN, empty_rect()
    if (int(wp.floor(x_min)) != r[0] or int(wp.floor(y_min)) != r[1] or int(wp.floor(x_max)) != r[2]
            or int(wp.floor(y_max)) != r[3]):
        return RAYS_UNKNOWN, empty_rect()
    return RAYS_IN_CELLS, r


@wp.func
def clear_in_cell(buffers: LightBuffers, e: int, face: int, reach: wp.float64) -> bool:
    """Whether triangle ``face``'s entry in cell e, looked for among the entries nearer than
    ``reach``, is marked clear there (cell_clear): no ray leaving it through the cell meets any."""
    for k in range(buffers.cell_start[e], buffers.cell_start[e + 1]):
        if wp.float64(buffers.cell_near[k]) > reach:
            return False
        if buffers.cell_faces[k] == face:
            return buffers.cell_clear[k] != wp.uint8(0)
    return False


@wp.func
def pinhole_triangle_is_clear(buffers: LightBuffers, view: int, cube: bool, face: int, p0: wp.vec3, p1: wp.vec3,
                              p2: wp.vec3) -> bool:
    """Whether every shadow ray leaving the triangle that picks pinhole view ``view`` lands in cells
    where it is clear (true for a cube face it lies wholly outside of: its rays pick another)."""
    where, r = spread_cells(buffers, view, p0, p1, p2, wp.float64(0.0))
    if where == RAYS_ELSEWHERE:
        return cube
    if where == RAYS_UNKNOWN:
        return False
    for y in range(r[1], r[3] + 1):
        for x in range(r[0], r[2] + 1):
            if not clear_in_cell(buffers, view * buffers.resolution * buffers.resolution + y * buffers.resolution + x,
                                 face, wp.float64(wp.inf)):
                return False
    return True


@wp.kernel
def mark_clear_triangles(buffers: LightBuffers, light: int, positions: wp.array(dtype=wp.vec3),
                         indices: wp.array(dtype=wp.int32), front_only: wp.array(dtype=wp.uint8), first: int,
                         end: int):
    """Per triangle of [first, end), whether every shadow ray leaving it towards ``light`` (pinhole
    views) is lit without a query: it is clear wherever its rays may land, in every view
    (buffers.triangle_clear: CLEAR, else NOT_CLEAR, unmarked where no_shadow_rays_leave)."""
    start = first + wp.tid() * ITEMS_PER_THREAD
    span = buffers.light_views[light]
    for face in range(start, wp.min(start + ITEMS_PER_THREAD, end)):
        c = triangle_corners(indices, face)
        clear = not no_shadow_rays_leave(front_only, face, buffers.views[span[0]], positions[c[0]], positions[c[1]],
                                         positions[c[2]])
        for v in range(span[0], span[0] + span[1]):
            if clear:
                clear = pinhole_triangle_is_clear(buffers, v, span[1] == CUBE_FACES, face, positions[c[0]],
                                                  positions[c[1]], positions[c[2]])
        buffers.triangle_clear[light * buffers.triangles + face] = wp.where(clear, CLEAR, NOT_CLEAR)
