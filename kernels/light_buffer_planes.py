"""Where a triangle lies as a light sees it: the side of its plane the light is on (light_side), its
plane as the marks test other triangles against it (LightPlane, made once per triangle and light
by light_planes), how far from the light its shadow rays' origins may lie (farness), and the
triangles that need no marks (no_shadow_rays_leave) or no place in the lists
(never_first_blocker)."""

import warp as wp

from .light_buffer import ITEMS_PER_THREAD, NEAR_SHRINK, ORIGIN_DEVIATION
from .projection import Projection
from .robust import to_double
from .scene_data import triangle_corners

wp.set_module_options({"enable_backward": False})

# A triangle is marked clear in a cell only if the light lies at least this angle (radians) off its
# plane, far above the float32 rounding of a shadow ray's direction (~1e-7), and only after
# comparing it with at most MAX_CLEAR_CHECKS nearer triangles of the cell.
LIGHT_SIDE_MARGIN = wp.constant(wp.float64(1.0e-6))
# A vertex counts as behind a triangle's plane up to this fraction of its distance from the plane's
# origin vertex: the float64 rounding of the plane test (~1e-16) with room to spare, and far below
# a shadow ray origin's offset off its surface (~1e-7 of the coordinates).
PLANE_TOLERANCE = wp.constant(wp.float64(1.0e-12))


@wp.func
def towards_light(proj: Projection, p: wp.vec3d) -> wp.vec3d:
    """A vector from p towards the view's light: to its eye, or against a parallel view's z axis."""
    if proj.orthographic != 0:
        return -wp.vec3d(proj.to_camera[2, 0], proj.to_camera[2, 1], proj.to_camera[2, 2])
    return proj.eye - p


@wp.func
def largest_coordinate(p: wp.vec3d) -> wp.float64:
    return wp.max(wp.abs(p[0]), wp.max(wp.abs(p[1]), wp.abs(p[2])))


@wp.func
def origin_magnitude(p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d, origin_scale: wp.float64) -> wp.float64:
    """What the rounding of shadow ray origins spawned on the triangle scales with: its largest
    coordinate, or ``origin_scale``, that of the triangle it is a region of, if larger."""
    return wp.max(wp.max(largest_coordinate(p0), origin_scale), wp.max(largest_coordinate(p1), largest_coordinate(p2)))


@wp.func
def farness(proj: Projection, p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d, origin_scale: wp.float64) -> float:
    """An upper bound of the distance to the light (or of the depth in a parallel view) of every
    shadow ray origin spawned on the triangle, comparable with cell_near. ``origin_scale``: the
    largest coordinate of the triangle the origins' rounding comes from, if this one is a part
    of it (0 otherwise)."""
    deviation = ORIGIN_DEVIATION * origin_magnitude(p0, p1, p2, origin_scale)
    far = wp.float64(0.0)
    if proj.orthographic != 0:
        axis = wp.vec3d(proj.to_camera[2, 0], proj.to_camera[2, 1], proj.to_camera[2, 2])
        far = wp.max(wp.dot(axis, p0 - proj.eye), wp.max(wp.dot(axis, p1 - proj.eye), wp.dot(axis, p2 - proj.eye)))
        far = far + deviation * wp.length(axis)
    else:
        d0 = p0 - proj.eye
        d1 = p1 - proj.eye
        d2 = p2 - proj.eye
        far = wp.sqrt(wp.max(wp.dot(d0, d0), wp.max(wp.dot(d1, d1), wp.dot(d2, d2)))) + deviation
    return float(far + wp.abs(far) * wp.float64(NEAR_SHRINK))


@wp.func
def behind_plane(n: wp.vec3d, n_sq: wp.float64, light_side: wp.float64, origin: wp.vec3d, p: wp.vec3d) -> bool:
    """Whether p lies on the plane through origin with normal n (n_sq = |n|^2) or on its side away
    from the light."""
    offset = p - origin
    height = wp.dot(n, offset) * light_side
    if height <= wp.float64(0.0):
        return True
    return height * height <= PLANE_TOLERANCE * PLANE_TOLERANCE * n_sq * wp.dot(offset, offset)


@wp.struct
class LightPlane:
    """A triangle's plane as mark_clear_entries tests other triangles against it, for one light."""
    normal: wp.vec3d
    normal_sq: wp.float64
    # the sign of the light's side of the plane; 0 where the triangle is degenerate or the light
    # lies within LIGHT_SIDE_MARGIN of its plane (the triangle is then never clear)
    light_side: wp.float64
    # farness: no shadow ray origin on the triangle lies farther from the light
    far: float


@wp.func
def light_plane(proj: Projection, p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d) -> LightPlane:
    """Triangle (p0, p1, p2)'s LightPlane for the light of view ``proj`` (any of its views)."""
    plane = LightPlane()
    plane.normal = wp.cross(p1 - p0, p2 - p0)
    plane.normal_sq = wp.dot(plane.normal, plane.normal)
    plane.light_side = light_side(proj, p0, p1, p2, LIGHT_SIDE_MARGIN)
    plane.far = farness(proj, p0, p1, p2, wp.float64(0.0))
    return plane


@wp.func
def light_side(proj: Projection, p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d, margin: wp.float64) -> wp.float64:
    """The sign of the side of triangle p's plane that the light of view ``proj`` lies on, + in
    front (where its winding's normal points, surface_hit's front), or 0 where the light lies
    within ``margin`` (radians, about) of the plane."""
    n = wp.cross(p1 - p0, p2 - p0)
    towards = towards_light(proj, p0)
    side = wp.dot(n, towards)
    if side * side > margin * margin * wp.dot(n, n) * wp.dot(towards, towards):
        return wp.sign(side)
    return wp.float64(0.0)


@wp.func
def flag_set(flags: wp.array(dtype=wp.uint8), face: int) -> bool:
    """Whether per-triangle ``flags`` holds triangle ``face`` and it is set."""
    return face < flags.shape[0] and flags[face] != wp.uint8(0)


@wp.func
def no_shadow_rays_leave(front_only: wp.array(dtype=wp.uint8), face: int, proj: Projection, p0: wp.vec3,
                         p1: wp.vec3, p2: wp.vec3) -> bool:
    """Whether no shadow ray towards the light of view ``proj`` leaves triangle ``face``: it is
    shaded from its front only (front_only[face] set: pbrwarp.gpu_scene.back_faces_unseen) and the
    light lies behind its front. Marks are not worth making for it; a ray that rounding would
    still send from it is queried."""
    if not flag_set(front_only, face):
        return False
    return light_side(proj, to_double(p0), to_double(p1), to_double(p2), wp.float64(0.0)) < wp.float64(0.0)


@wp.func
def never_first_blocker(closed: wp.array(dtype=wp.uint8), face: int, proj: Projection, p0: wp.vec3, p1: wp.vec3,
                        p2: wp.vec3) -> bool:
    """Whether triangle ``face`` need not be listed: it belongs to an opaque closed mesh with the
    light outside (closed[face] set: light_buffers.closed_faces) and faces away from the light
    (by LIGHT_SIDE_MARGIN). A segment towards the light that crosses such a triangle enters the
    mesh there and must leave it, before the light, through a triangle facing the light, which is
    listed and blocks the segment as well."""
    if not flag_set(closed, face):
        return False
    return light_side(proj, to_double(p0), to_double(p1), to_double(p2), LIGHT_SIDE_MARGIN) < wp.float64(0.0)


@wp.kernel
def light_planes(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), proj: Projection,
                 first: int, last: int, front_only: wp.array(dtype=wp.uint8), planes: wp.array(dtype=LightPlane)):
    """The LightPlane of triangles first...last - 1 for the light of view ``proj``: computed once
    per triangle, where mark_clear_entries would redo it in every cell listing the triangle; light
    side 0 (never clear) where no shadow ray leaves the triangle (no_shadow_rays_leave)."""
    start = first + wp.tid() * ITEMS_PER_THREAD
    for face in range(start, wp.min(start + ITEMS_PER_THREAD, last)):
        c = triangle_corners(indices, face)
        plane = light_plane(proj, to_double(positions[c[0]]), to_double(positions[c[1]]),
                            to_double(positions[c[2]]))
        # no_shadow_rays_leave, from the plane's side (0 already where the light is that close)
        if plane.light_side < wp.float64(0.0) and flag_set(front_only, face):
            plane.light_side = wp.float64(0.0)
        planes[face] = plane


@wp.func
def behind_light_plane(plane: LightPlane, origin: wp.vec3d, q0: wp.vec3d, q1: wp.vec3d, q2: wp.vec3d) -> bool:
    """Whether triangle q lies on or behind the plane (through ``origin``), so that no shadow ray
    leaving the plane's triangle towards the light can meet it (never where the light lies too
    close to the plane: light_side 0)."""
    if plane.light_side == wp.float64(0.0):
        return False
    return (behind_plane(plane.normal, plane.normal_sq, plane.light_side, origin, q0)
            and behind_plane(plane.normal, plane.normal_sq, plane.light_side, origin, q1)
            and behind_plane(plane.normal, plane.normal_sq, plane.light_side, origin, q2))
