"""A shadow ray's verdict from the light buffers: lit without a query where the point it leaves is
marked clear (ray_leaves_clear); else tested against the triangles the cells it crosses list nearer
to the light than its origin, with the ray caster's own ray-triangle test (light_buffer_occlusion),
or left to the BVH (UNDECIDED) where its cells cannot be named cheaply. Also the size of the
render kernel's shadow cache."""

import warp as wp

from .light_buffer import (CLEAR, DIRECTION_ROUNDING, INTERIOR_CLEAR, INTERIOR_SHRINKS, NOT_CLEAR, REGIONS_CLEAR,
                           LightBuffers)
from .light_buffer_cells import CELL_MARGIN, cell_rect
from .light_buffer_marks import clear_in_cell
from .light_buffer_regions import region_is_clear
from .projection import camera_coordinates, screen_point
from .ray_triangle import ray_triangle_intersection
from .robust import to_double
from .scene_data import triangle_corners
from .shadow_map import CUBE_FACES, cube_face

wp.set_module_options({"enable_backward": False})

# Verdicts of a light-buffer query.
LIT = wp.constant(0)
OCCLUDED = wp.constant(1)
UNDECIDED = wp.constant(2)
# A ray spanning more cells than this (its origin lies close to the light, or it runs nearly
# across the light's view) is left to the BVH.
MAX_QUERY_CELLS = wp.constant(4)
# The query's fast path takes a ray whose direction's rounding (slack times the distance) is at
# most this share of the light's clearance: up to t_end its points then stay at least
# CLEAR_RADIUS_SHARE of the clearance away from the light (1 - 6 FAST_PATH_SLACK_SHARE).
FAST_PATH_SLACK_SHARE = wp.constant(wp.float64(0.01))
CLEAR_RADIUS_SHARE = wp.constant(wp.float64(0.9))
# The shadow cache (Haines and Greenberg 1986): per light (the first SHADOW_CACHE_LIGHTS), the
# triangle that blocked the previous shadow ray of the row, tested before the light buffer is
# asked, since neighbouring pixels are mostly shadowed by the same triangle.
SHADOW_CACHE_LIGHTS = wp.constant(4)
ShadowCache = wp.types.vector(length=4, dtype=wp.int32)


@wp.func
def clear_mark(buffers: LightBuffers, light: int, face: int) -> wp.uint8:
    """buffers.triangle_clear's code for triangle ``face`` and ``light`` (NOT_CLEAR past the arrays)."""
    i = light * buffers.triangles + face
    if light >= buffers.light_views.shape[0] or i >= buffers.triangle_clear.shape[0]:
        return NOT_CLEAR
    return buffers.triangle_clear[i]


@wp.func
def triangle_is_clear(buffers: LightBuffers, light: int, face: int) -> bool:
    """Whether a shadow ray leaving triangle ``face`` towards ``light`` meets nothing, known
    without a query (mark_clear_triangles)."""
    return clear_mark(buffers, light, face) == CLEAR


@wp.func
def ray_leaves_clear(buffers: LightBuffers, light: int, face: int, b0: float, b1: float, b2: float) -> bool:
    """Whether the shadow ray towards ``light`` from the point of triangle ``face`` with
    barycentric coordinates (b0, b1, b2) meets nothing, known without a query: the whole triangle
    is clear, or its clear interior (mark_clear_interiors) or a clear region of it
    (mark_clear_regions) holds the point."""
    mark = clear_mark(buffers, light, face)
    if mark == CLEAR:
        return True
    if mark < INTERIOR_CLEAR:
        return False
    if mark >= REGIONS_CLEAR:
        return region_is_clear(buffers, light, mark, b0, b1, b2)
    least = INTERIOR_SHRINKS[int(mark - INTERIOR_CLEAR)] / 3.0
    return b0 >= least and b1 >= least and b2 >= least


@wp.func
def segment_meets_triangle(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), face: int,
                           origin: wp.vec3, direction: wp.vec3, max_t: float) -> bool:
    """Whether origin + t direction, 0 <= t < max_t, meets triangle ``face``, by the ray caster's
    own ray-triangle test."""
    c = triangle_corners(indices, face)
    hit, t, u, v = ray_triangle_intersection(origin, direction, positions[c[0]], positions[c[1]], positions[c[2]])
    return hit and t < max_t


# inlined: a call would copy the light buffers' struct (~0.6 KB) per cell tested
@wp.func(inline=True)
def cell_verdict(buffers: LightBuffers, e: int, reach: wp.float64, positions: wp.array(dtype=wp.vec3),
                 indices: wp.array(dtype=wp.int32), origin: wp.vec3, direction: wp.vec3, max_t: float,
                 origin_face: int, only_cell: bool):
    """(verdict, blocker) of the triangles cell e lists nearer than ``reach``: OCCLUDED by the
    first the ray meets, else LIT. ``only_cell``: the ray stays in this cell, so that it meets
    nothing if its origin's entry is clear here."""
    if only_cell:
        if clear_in_cell(buffers, e, origin_face, reach):
            return LIT, -1
    for k in range(buffers.cell_start[e], buffers.cell_start[e + 1]):
        if wp.float64(buffers.cell_near[k]) > reach:
            break
        face = buffers.cell_faces[k]
        if face != origin_face:
            if segment_meets_triangle(positions, indices, face, origin, direction, max_t):
                return OCCLUDED, face
    return LIT, -1


@wp.func
def light_buffer_occlusion(buffers: LightBuffers, light: int, light_position: wp.vec3,
                           positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), origin: wp.vec3,
                           direction: wp.vec3, max_t: float, origin_face: int):
    """(verdict, blocker): LIT, OCCLUDED or UNDECIDED (ask the BVH) for the shadow ray origin + t
    direction, 0 <= t < max_t, towards light ``light``: aimed at the light's position (point and
    spot lights) or along its reversed direction (directional lights); blocker is the triangle
    found in its way (OCCLUDED), else -1. The ray leaves triangle ``origin_face`` from an origin
    offset off its plane towards the light, so it cannot meet it (and is not tested against it)."""
    if light >= buffers.light_views.shape[0]:
        return UNDECIDED, -1  # buffers built for fewer lights (no_light_buffers): the BVH answers
    if triangle_is_clear(buffers, light, origin_face):
        return LIT, -1
    span = buffers.light_views[light]
    if span[1] == 0:
        return UNDECIDED, -1
    view = span[0]
    if span[1] == CUBE_FACES:
        view = span[0] + cube_face(origin - light_position)
    proj = buffers.views[view]
    co = camera_coordinates(proj, origin)
    cells = buffers.resolution * buffers.resolution
    # The ray is met only where it lies in front of a parallel view's plane (all triangles do), or
    # farther than the clearance from a point light; it misses the light by the float32 rounding
    # of its direction, at most `slack` times the distance travelled. Past t_end (taken in float64,
    # like both endpoints, which are then projected to the cells between them) it lies within the
    # clearance of the light, where no triangle is.
    reach = co[2]
    t_end = reach
    if proj.orthographic == 0:
        distance = wp.length(light_position - origin)
        magnitude = wp.max(wp.max(wp.abs(light_position[0]), wp.abs(light_position[1])),
                           wp.max(wp.abs(light_position[2]), wp.max(wp.abs(origin[0]), wp.max(wp.abs(origin[1]),
                                                                                             wp.abs(origin[2])))))
        slack = wp.float64(DIRECTION_ROUNDING * (1.0 + magnitude / distance))
        # an upper bound of the exact distance, and of every ray point's distance to the light
        reach = wp.float64(distance) * (wp.float64(1.0) + wp.float64(2.0) * slack)
        clearance = wp.float64(buffers.clearance[light])
        t_end = reach * (wp.float64(1.0) + slack) - clearance * (wp.float64(1.0) - slack)
        if t_end >= reach:
            return UNDECIDED, -1  # the rounding may carry the ray beyond the clearance
        # Fast path: a ray from the origin straight at the view's eye is, seen from the eye, a
        # single point, the origin's. The float32 ray strays from it by less than 2 slack reach
        # (its direction's rounding, and the float32 light position's off the eye, which slack's
        # magnitude term bounds), at least CLEAR_RADIUS_SHARE of the clearance away from the light
        # up to t_end: its projection stays within `drift` cells of the origin's, and if that lies
        # so far inside a cell, the whole ray stays in it.
        if co[2] > wp.float64(0.0) and slack * reach <= FAST_PATH_SLACK_SHARE * clearance:
            so = screen_point(proj, co)
            xo = so[0]
            yo = so[1]
            drift = (wp.float64(2.0) * slack * reach / (CLEAR_RADIUS_SHARE * clearance)
                     * buffers.view_cells_per_radian[view] + CELL_MARGIN)
            fx = wp.floor(xo)
            fy = wp.floor(yo)
            if (fx >= wp.float64(0.0) and fy >= wp.float64(0.0) and fx < wp.float64(proj.width)
                    and fy < wp.float64(proj.height) and xo - fx >= drift and fx + wp.float64(1.0) - xo >= drift
                    and yo - fy >= drift and fy + wp.float64(1.0) - yo >= drift):
                e = view * cells + int(fy) * buffers.resolution + int(fx)
                return cell_verdict(buffers, e, reach, positions, indices, origin, direction, max_t, origin_face,
                                    True)
    t_end = wp.clamp(t_end, wp.float64(0.0), wp.float64(max_t))
    end = to_double(origin) + to_double(direction) * t_end
    ce = proj.to_camera * (end - proj.eye)
    if proj.orthographic == 0 and (co[2] <= wp.float64(0.0) or ce[2] <= wp.float64(0.0)):
        return UNDECIDED, -1
    so = screen_point(proj, co)
    se = screen_point(proj, ce)
    xo = so[0]
    yo = so[1]
    xe = se[0]
    ye = se[1]
    r = cell_rect(proj, wp.min(xo, xe), wp.min(yo, ye), wp.max(xo, xe), wp.max(yo, ye))
    if r[0] > r[2]:
        return UNDECIDED, -1
    if wp.min(xo, xe) - CELL_MARGIN < wp.float64(0.0) or wp.min(yo, ye) - CELL_MARGIN < wp.float64(0.0):
        return UNDECIDED, -1  # partly outside the view
    if (wp.max(xo, xe) + CELL_MARGIN >= wp.float64(proj.width)
            or wp.max(yo, ye) + CELL_MARGIN >= wp.float64(proj.height)):
        return UNDECIDED, -1
    if (r[2] - r[0] + 1) * (r[3] - r[1] + 1) > MAX_QUERY_CELLS:
        return UNDECIDED, -1
    only_cell = r[0] == r[2] and r[1] == r[3]
    for y in range(r[1], r[3] + 1):
        for x in range(r[0], r[2] + 1):
            verdict, blocker = cell_verdict(buffers, view * cells + y * buffers.resolution + x, reach, positions,
                                            indices, origin, direction, max_t, origin_face, only_cell)
            if verdict == OCCLUDED:
                return verdict, blocker
    return LIT, -1
