"""Marks of triangle interiors. Where neighbours rise in front of a triangle's plane (across the
concave creases of a noisy scanned surface), its interior, the triangle shrunk about its centroid,
is marked clear of a light where no listed triangle comes near the solid its shadow rays sweep
towards the light: a pyramid to a point or spot light, a prism towards a directional one
(interior_clear_level, mark_clear_interiors), as separating planes show (solid_separated)."""

import warp as wp

from .light_buffer import (INTERIOR_CLEAR, INTERIOR_LEVELS, INTERIOR_SHRINKS, ITEMS_PER_THREAD, NOT_CLEAR,
                           ORIGIN_DEVIATION, LightBuffers)
from .light_buffer_marks import RAYS_ELSEWHERE, RAYS_UNKNOWN, clear_in_cell, ray_stray, spread_cells
from .light_buffer_planes import (behind_light_plane, farness, largest_coordinate, light_plane, no_shadow_rays_leave,
                                  origin_magnitude, towards_light)
from .projection import Projection
from .robust import to_double
from .scene_data import triangle_corners
from .shadow_map import CUBE_FACES

wp.set_module_options({"enable_backward": False})

# Triangles last tested for a triangle's interior, skipped when its other cells list them again.
RECENT_CHECKS = 16
RecentChecks = wp.types.vector(length=RECENT_CHECKS, dtype=wp.int32)
# Most triangles a cell may list nearer to the light than a triangle before its interior is not
# tried (bounds the build's work on degenerate scenes).
MAX_INTERIOR_CHECKS = wp.constant(256)


@wp.struct
class SweptSolid:
    """The segments from a triangle (the base, corners s0 s1 s2) to a point (the apex: tops t0 =
    t1 = t2), or a prism (tops t_i = s_i + a common vector), by the outward unit normals of its
    faces: the base's and the side through each base edge (and its tops)."""
    s0: wp.vec3d
    s1: wp.vec3d
    s2: wp.vec3d
    t0: wp.vec3d
    t1: wp.vec3d
    t2: wp.vec3d
    base: wp.vec3d
    side01: wp.vec3d
    side12: wp.vec3d
    side20: wp.vec3d


@wp.func
def outward_unit(n: wp.vec3d, point: wp.vec3d, inside: wp.vec3d) -> wp.vec3d:
    """n normalized and turned away from ``inside`` (a point of the solid off the plane through
    ``point``), or zero where n is degenerate (such a face separates nothing)."""
    length = wp.length(n)
    if not length > wp.float64(0.0):
        return wp.vec3d(wp.float64(0.0))
    if wp.dot(n, inside - point) > wp.float64(0.0):
        return -n / length
    return n / length


@wp.func
def swept_solid(s0: wp.vec3d, s1: wp.vec3d, s2: wp.vec3d, t0: wp.vec3d, t1: wp.vec3d, t2: wp.vec3d) -> SweptSolid:
    out = SweptSolid()
    out.s0 = s0
    out.s1 = s1
    out.s2 = s2
    out.t0 = t0
    out.t1 = t1
    out.t2 = t2
    out.base = outward_unit(wp.cross(s1 - s0, s2 - s0), s0, t0)
    out.side01 = outward_unit(wp.cross(s1 - s0, t0 - s0), s0, s2)
    out.side12 = outward_unit(wp.cross(s2 - s1, t1 - s1), s1, s0)
    out.side20 = outward_unit(wp.cross(s0 - s2, t2 - s2), s2, s1)
    return out


@wp.func
def pyramid(apex: wp.vec3d, s0: wp.vec3d, s1: wp.vec3d, s2: wp.vec3d) -> SweptSolid:
    return swept_solid(s0, s1, s2, apex, apex, apex)


@wp.func
def beyond_plane(n: wp.vec3d, point: wp.vec3d, q0: wp.vec3d, q1: wp.vec3d, q2: wp.vec3d, margin: wp.float64) -> bool:
    """Whether triangle q lies farther than ``margin`` beyond the plane through ``point`` with unit
    normal n (never for n = 0)."""
    return wp.dot(n, q0 - point) > margin and wp.dot(n, q1 - point) > margin and wp.dot(n, q2 - point) > margin


@wp.func
def solid_separated(solid: SweptSolid, q0: wp.vec3d, q1: wp.vec3d, q2: wp.vec3d, margin: wp.float64) -> bool:
    """Whether triangle q lies farther than ``margin`` from the solid, shown by a separating plane:
    one of the solid's faces through its base, or q's own. Conservative: False where no such plane
    shows it."""
    # first the faces through the base's edges, beside which lie most triangles the solid's cells
    # list; then the whole solid on one side of q's plane (neighbours across a concave crease,
    # facing the light too); then the base
    if (beyond_plane(solid.side01, solid.s0, q0, q1, q2, margin)
            or beyond_plane(solid.side12, solid.s1, q0, q1, q2, margin)
            or beyond_plane(solid.side20, solid.s2, q0, q1, q2, margin)):
        return True
    n = wp.cross(q1 - q0, q2 - q0)
    bound_sq = margin * margin * wp.dot(n, n)
    if bound_sq > wp.float64(0.0):
        h0 = wp.dot(n, solid.s0 - q0)
        h1 = wp.dot(n, solid.s1 - q0)
        h2 = wp.dot(n, solid.s2 - q0)
        h3 = wp.dot(n, solid.t0 - q0)
        h4 = wp.dot(n, solid.t1 - q0)
        h5 = wp.dot(n, solid.t2 - q0)
        low = wp.min(wp.min(wp.min(h0, h1), wp.min(h2, h3)), wp.min(h4, h5))
        high = wp.max(wp.max(wp.max(h0, h1), wp.max(h2, h3)), wp.max(h4, h5))
        if (low > wp.float64(0.0) and low * low > bound_sq) or (high < wp.float64(0.0) and high * high > bound_sq):
            return True
    return beyond_plane(solid.base, solid.s0, q0, q1, q2, margin)


@wp.func
def shrunk_solid(proj: Projection, d0: wp.vec3d, d1: wp.vec3d, d2: wp.vec3d, level: int, far: float) -> SweptSolid:
    """What the shadow rays leaving the triangle shrunk by INTERIOR_SHRINKS[level] about its
    centroid sweep, exactly: the pyramid from it to a pinhole view's eye (the light), or in a
    parallel view the prism from it towards the light to the view's plane, behind every triangle
    (``far`` bounds the triangle's depth)."""
    centroid = (d0 + d1 + d2) / wp.float64(3.0)
    keep = wp.float64(1.0) - wp.float64(INTERIOR_SHRINKS[level])
    s0 = centroid + (d0 - centroid) * keep
    s1 = centroid + (d1 - centroid) * keep
    s2 = centroid + (d2 - centroid) * keep
    if proj.orthographic != 0:
        sweep = towards_light(proj, centroid) * wp.float64(far)
        return swept_solid(s0, s1, s2, s0 + sweep, s1 + sweep, s2 + sweep)
    return pyramid(proj.eye, s0, s1, s2)


# inlined: a call would copy the light buffers' struct (~0.6 KB) per triangle and view
@wp.func(inline=True)
def interior_clear_level(buffers: LightBuffers, view: int, cube: bool, face: int,
                         positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), p0: wp.vec3,
                         p1: wp.vec3, p2: wp.vec3, level: int, origin_scale: wp.float64) -> int:
    """The first of INTERIOR_SHRINKS from ``level`` on (INTERIOR_LEVELS for none) such that no
    shadow ray leaving the triangle shrunk by it about its centroid and picking view ``view`` can
    meet a triangle (``level`` itself for a cube face the triangle lies wholly outside of).

    Such a ray starts within ORIGIN_DEVIATION of the shrunk triangle and runs towards the light,
    straying from the exact segment to it (for a directional light, to the view's plane behind
    every triangle) by at most ray_stray: it lies within that of the solid the shrunk triangle
    sweeps towards the light (shrunk_solid). It can meet only triangles its cells list nearer to
    the light than the triangle's farness, and none of those comes within `margin` of that solid:
    twice ray_stray, and ORIGIN_DEVIATION of the coordinates' magnitude for the ray-triangle
    test's own rounding (about a float32 ulp); nor can they meet those on or behind the plane of
    triangle ``face``, which they leave towards the light (as mark_clear_entries argues).
    Unlike the triangle's own plane, in front of which its neighbours across a concave crease
    rise, the solid leaves them out where they face the light too or lean away from it. A
    smaller shrink's solid holds a larger one's, so a triangle clear of it is clear of every
    later one. The triangle may be a region of triangle ``face`` (``origin_scale`` as for
    farness)."""
    if level >= INTERIOR_LEVELS:
        return INTERIOR_LEVELS
    where, r = spread_cells(buffers, view, p0, p1, p2, origin_scale)
    if where == RAYS_ELSEWHERE:
        return wp.where(cube, level, INTERIOR_LEVELS)
    if where == RAYS_UNKNOWN:
        return INTERIOR_LEVELS
    proj = buffers.views[view]
    d0 = to_double(p0)
    d1 = to_double(p1)
    d2 = to_double(p2)
    corners = triangle_corners(indices, face)
    plane_origin = to_double(positions[corners[0]])
    plane = light_plane(proj, plane_origin, to_double(positions[corners[1]]), to_double(positions[corners[2]]))
    largest = origin_magnitude(d0, d1, d2, origin_scale)
    magnitude = wp.max(largest, largest_coordinate(proj.eye))
    far = farness(proj, d0, d1, d2, origin_scale)
    margin = wp.float64(2.0) * ray_stray(largest, wp.float64(far), magnitude) + magnitude * ORIGIN_DEVIATION
    solid = shrunk_solid(proj, d0, d1, d2, level, far)
    smallest = shrunk_solid(proj, d0, d1, d2, INTERIOR_LEVELS - 1, far)
    checked = int(0)
    recent = RecentChecks(-1)
    for y in range(r[1], r[3] + 1):
        for x in range(r[0], r[2] + 1):
            e = view * buffers.resolution * buffers.resolution + y * buffers.resolution + x
            if clear_in_cell(buffers, e, face, wp.float64(far)):
                continue  # nothing listed here can block a ray leaving the triangle
            for k in range(buffers.cell_start[e], buffers.cell_start[e + 1]):
                if buffers.cell_near[k] >= far:
                    break
                other = buffers.cell_faces[k]
                seen = other == face
                for j in range(RECENT_CHECKS):
                    seen = seen or recent[j] == other
                if not seen:
                    recent[checked % RECENT_CHECKS] = other
                    checked += 1
                    if checked > MAX_INTERIOR_CHECKS:
                        return INTERIOR_LEVELS
                    c = triangle_corners(indices, other)
                    q0 = to_double(positions[c[0]])
                    q1 = to_double(positions[c[1]])
                    q2 = to_double(positions[c[2]])
                    if not behind_light_plane(plane, plane_origin, q0, q1, q2) and not solid_separated(solid, q0, q1,
                                                                                                      q2, margin):
                        # a later shrink's smaller solid, if the smallest one is clear of q
                        if not solid_separated(smallest, q0, q1, q2, margin):
                            return INTERIOR_LEVELS
                        level += 1
                        solid = shrunk_solid(proj, d0, d1, d2, level, far)
                        while not solid_separated(solid, q0, q1, q2, margin):
                            level += 1
                            solid = shrunk_solid(proj, d0, d1, d2, level, far)
    return level


@wp.kernel
def mark_clear_interiors(buffers: LightBuffers, light: int, positions: wp.array(dtype=wp.vec3),
                         indices: wp.array(dtype=wp.int32), front_only: wp.array(dtype=wp.uint8), first: int,
                         end: int):
    """Per triangle of [first, end) not clear of ``light``: INTERIOR_CLEAR + k where
    no triangle can block a shadow ray leaving its interior shrunk by INTERIOR_SHRINKS[k], the
    first that works, in any view (buffers.triangle_clear); none where no_shadow_rays_leave."""
    start = first + wp.tid() * ITEMS_PER_THREAD
    span = buffers.light_views[light]
    for face in range(start, wp.min(start + ITEMS_PER_THREAD, end)):
        c = triangle_corners(indices, face)
        if buffers.triangle_clear[light * buffers.triangles + face] == NOT_CLEAR and not no_shadow_rays_leave(
                front_only, face, buffers.views[span[0]], positions[c[0]], positions[c[1]], positions[c[2]]):
            level = int(0)
            for v in range(span[0], span[0] + span[1]):
                level = interior_clear_level(buffers, v, span[1] == CUBE_FACES, face, positions, indices,
                                             positions[c[0]], positions[c[1]], positions[c[2]], level,
                                             wp.float64(0.0))
            if level < INTERIOR_LEVELS:
                buffers.triangle_clear[light * buffers.triangles + face] = INTERIOR_CLEAR + wp.uint8(level)
