"""Light buffers (Haines and Greenberg 1986, "The Light Buffer: A Shadow-Testing Accelerator"): per
light, a grid over the directions it shines in, each cell listing the triangles seen through it,
nearest to the light first. A shadow ray runs from its origin towards the light, so seen from the
light it stays in the cell of its origin: it is tested against that cell's triangles nearer to the
light than its origin only, with the ray caster's own ray-triangle test, and gets the verdict a
BVH any-hit query would give at a fraction of the cost.

Most shadow rays need not even that: where every triangle a cell lists nearer than a triangle T
lies on or behind T's plane (seen from the light), no ray leaving T's lit side through that cell
can meet one, so T's entry there is marked clear; a triangle clear in every cell its rays can
land in (pinhole views) is marked clear of the light, and its rays are lit without a query. On a
convex surface that is every triangle facing the light. On a noisy scanned one, neighbours across
concave creases rise in front of each other's planes; there a triangle's interior (the triangle
shrunk about its centroid) is marked clear where no listed triangle comes near the solid its rays
sweep towards the light (a pyramid to a point or spot light, a prism towards a directional one),
and rays leaving that interior are lit without a query too. A large triangle that something
shadows in part (a floor under a mesh) is cut into regions, squares of its barycentric plane
a few cells across, each marked clear as an interior would be, so that the rays from its lit
part need no query either.

Views are the shadow maps' (kernels/shadow_map.py): a cube of six for point lights and wide spot
lights, one pinhole view for narrow spots, a parallel view behind the scene for directional lights,
in the rasterizer's Projection (cells are its pixels). A ray from a point or spot light whose
origin lies farther inside its cell than the ray can stray (its rounding, in cells) is known to
stay in that cell from its origin's projection alone. A ray whose cells cannot be named cheaply
(it leaves its cube face or its view, or spans more than MAX_QUERY_CELLS cells) is left to the BVH.
"""

import warp as wp

from .projection import Projection, camera_coordinates, clamped_rect, empty_rect, screen_point
from .ray_triangle import ray_triangle_intersection
from .robust import RAY_FAR, to_double
from .scene_data import triangle_corners
from .shadow_map import CUBE_FACES, cube_face
from .triangle_setup import clipped_rect

wp.set_module_options({"enable_backward": False})

# Triangles per Warp thread in the per-triangle launches: a CPU launch calls the kernel once per
# thread and copies its arguments each time, which cost more than one triangle's work.
ITEMS_PER_THREAD = wp.constant(64)

# Verdicts of a light-buffer query.
LIT = wp.constant(0)
OCCLUDED = wp.constant(1)
UNDECIDED = wp.constant(2)
# Margin, in cells, of triangle rectangles and query rectangles: far above the rounding of the
# float64 projections (1e-12 cells), so that a ray and a triangle it meets always share a cell.
CELL_MARGIN = wp.constant(wp.float64(1.0e-3))
# Bound on the angle between a shadow ray's float32 direction and the exact one towards the light,
# relative to (1 + the coordinates' magnitude over the distance): the difference of light and
# origin rounds to half an ulp of the larger per component, the normalization to a few ulps.
DIRECTION_ROUNDING = wp.constant(1.0e-6)
# A ray spanning more cells than this (its origin lies close to the light, or it runs nearly
# across the light's view) is left to the BVH.
MAX_QUERY_CELLS = wp.constant(4)
# The query's fast path takes a ray whose direction's rounding (slack times the distance) is at
# most this share of the light's clearance: up to t_end its points then stay at least
# CLEAR_RADIUS_SHARE of the clearance away from the light (1 - 6 FAST_PATH_SLACK_SHARE).
FAST_PATH_SLACK_SHARE = wp.constant(wp.float64(0.01))
CLEAR_RADIUS_SHARE = wp.constant(wp.float64(0.9))
# Nearness values are lowered by this fraction so that rounding never makes a triangle seem
# farther from the light than a point on it.
NEAR_SHRINK = wp.constant(1.0e-6)
# A triangle is marked clear in a cell only if the light lies at least this angle (radians) off its
# plane, far above the float32 rounding of a shadow ray's direction (~1e-7), and only after
# comparing it with at most MAX_CLEAR_CHECKS nearer triangles of the cell.
LIGHT_SIDE_MARGIN = wp.constant(wp.float64(1.0e-6))
MAX_CLEAR_CHECKS = wp.constant(64)
# A vertex counts as behind a triangle's plane up to this fraction of its distance from the plane's
# origin vertex: the float64 rounding of the plane test (~1e-16) with room to spare, and far below
# a shadow ray origin's offset off its surface (~1e-7 of the coordinates).
PLANE_TOLERANCE = wp.constant(wp.float64(1.0e-12))
# Bound, relative to a triangle's largest coordinate, on how far a shadow ray's origin may lie from
# it: the hit point's rounding and the origin's offset (kernels/robust.py), each at most
# sqrt(3) gamma(7) 3 ~ 2.2e-6 of it.
ORIGIN_DEVIATION = wp.constant(wp.float64(1.0e-5))
# The shadow cache (Haines and Greenberg 1986): per light (the first SHADOW_CACHE_LIGHTS), the
# triangle that blocked the previous shadow ray of the row, tested before the light buffer is
# asked, since neighbouring pixels are mostly shadowed by the same triangle.
SHADOW_CACHE_LIGHTS = wp.constant(4)
# triangle_clear codes: no mark, every ray of the triangle clear, (INTERIOR_CLEAR + k) the rays
# leaving its part shrunk about its centroid by INTERIOR_SHRINKS[k] clear (interior_clear_level),
# or (REGIONS_CLEAR + t) the rays leaving some of its regions clear, as the light's t-th entry of
# region_grids says (mark_clear_regions).
NOT_CLEAR = wp.constant(wp.uint8(0))
CLEAR = wp.constant(wp.uint8(1))
INTERIOR_CLEAR = wp.constant(wp.uint8(2))
# Shrinks tried in turn, the smallest first: a ray whose hit point's barycentric coordinates are
# all at least s / 3 leaves the triangle shrunk by s (it keeps 1 - s of each corner's distance to
# the centroid). The first, 0, is the whole triangle, which the solids can show clear where the
# cells' plane tests (mark_clear_triangles) could not.
INTERIOR_LEVELS = 7
InteriorShrinks = wp.types.vector(length=INTERIOR_LEVELS, dtype=wp.float32)
INTERIOR_SHRINKS = wp.constant(InteriorShrinks(0.0, 0.02, 0.05, 0.1, 0.2, 0.35, 0.6))
REGIONS_CLEAR = wp.constant(wp.uint8(int(INTERIOR_CLEAR) + INTERIOR_LEVELS))
# Large triangles (a floor) are shadowed in parts: their regions are marked one by one. A region
# is a square of the barycentric plane, (b0, b1) in [i, i + 1) x [j, j + 1) over the grid size n,
# so that a hit point finds its region from its barycentrics alone; at most MAX_REGION_TRIANGLES
# triangles per light have regions (the codes left in a uint8).
MAX_REGION_TRIANGLES = wp.constant(255 - int(REGIONS_CLEAR))
# A hit point's float32 barycentrics are within this of the exact ones (a few ulps of 1): the
# regions are grown by three times it (b0 = 1 - b1 - b2 adds two), and a point whose barycentrics
# lie farther than it outside the triangle (an edge sample's extrapolated ones) is not looked up.
REGION_SLACK = wp.constant(1.0e-5)
# Triangles last tested for a triangle's interior, skipped when its other cells list them again.
RECENT_CHECKS = 16
RecentChecks = wp.types.vector(length=RECENT_CHECKS, dtype=wp.int32)
# Most triangles a cell may list nearer to the light than a triangle before its interior is not
# tried (bounds the build's work on degenerate scenes).
MAX_INTERIOR_CHECKS = wp.constant(256)
ShadowCache = wp.types.vector(length=4, dtype=wp.int32)


@wp.struct
class LightBuffers:
    views: wp.array(dtype=Projection)
    # per pinhole view: a bound on the cells a direction crosses per radian it turns, anywhere in
    # the view (cells_per_radian)
    view_cells_per_radian: wp.array(dtype=wp.float64)
    # per light: (first view, number of views), (0, 0) for a light whose rays go to the BVH
    light_views: wp.array(dtype=wp.vec2i)
    # per light: no triangle lies nearer than this to it (point and spot lights)
    clearance: wp.array(dtype=float)
    # cell c of view v is entry v * resolution^2 + c; its triangles are cell_faces[cell_start[e]:
    # cell_start[e + 1]], ascending in cell_near (a lower bound of their distance to the light, or
    # of their depth in a parallel view)
    cell_start: wp.array(dtype=wp.int32)
    cell_faces: wp.array(dtype=wp.int32)
    cell_near: wp.array(dtype=float)
    # 1 where the entry's triangle is clear in its cell: no triangle listed there can block a shadow
    # ray leaving it towards the light (every one that may lie nearer is behind its plane)
    cell_clear: wp.array(dtype=wp.uint8)
    # per light and triangle (light * triangles + face): CLEAR where every shadow ray leaving the
    # triangle lands in cells where it is clear (pinhole views only), INTERIOR_CLEAR + k where
    # every ray leaving its interior (shrunk by INTERIOR_SHRINKS[k]) meets nothing, so that those
    # need no query, REGIONS_CLEAR + t where its regions are marked (region_grids' t-th entry of
    # the light), else NOT_CLEAR
    triangle_clear: wp.array(dtype=wp.uint8)
    # per light and region triangle (light * MAX_REGION_TRIANGLES + t): (grid size n, first entry of
    # region_clear); region (i, j) is entry first + i n + j, 1 where every ray leaving it is clear
    region_grids: wp.array(dtype=wp.vec2i)
    region_clear: wp.array(dtype=wp.uint8)
    triangles: int
    resolution: int


# ---------------------------------------------------------------------- building
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


@wp.func
def region_corner(p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d, b0: wp.float64, b1: wp.float64) -> wp.vec3:
    """The point with barycentric coordinates (b0, b1, 1 - b0 - b1), in float32."""
    return wp.vec3(p2 + (p0 - p2) * b0 + (p1 - p2) * b1)


# inlined: a call would copy the light buffers' struct (~0.6 KB) per region part
@wp.func(inline=True)
def region_part_is_clear(buffers: LightBuffers, light: int, face: int, positions: wp.array(dtype=wp.vec3),
                         indices: wp.array(dtype=wp.int32), c0: wp.vec3, c1: wp.vec3, c2: wp.vec3,
                         origin_scale: wp.float64) -> bool:
    """Whether every shadow ray towards ``light`` leaving triangle c (a part of triangle ``face``)
    meets nothing, in every view of the light: its first interior level, the whole of it."""
    span = buffers.light_views[light]
    for v in range(span[0], span[0] + span[1]):
        if interior_clear_level(buffers, v, span[1] == CUBE_FACES, face, positions, indices, c0, c1, c2, 0,
                                origin_scale) != 0:
            return False
    return True


@wp.kernel
def mark_clear_regions(buffers: LightBuffers, light: int, positions: wp.array(dtype=wp.vec3),
                       indices: wp.array(dtype=wp.int32), face: int, grid: wp.vec2i, first: int, end: int):
    """Per region r = i n + j in [first, end) of triangle ``face``'s grid (size n = grid[0], flags
    from grid[1] on): 1 in region_clear where every shadow ray towards ``light`` leaving the region
    meets nothing. The region, grown by three REGION_SLACKs, is a parallelogram: two triangles,
    each shown clear as an interior would be (the float32 rounding of their corners is far within
    the origins' deviation, taken from the whole triangle's coordinates)."""
    c = triangle_corners(indices, face)
    p0 = to_double(positions[c[0]])
    p1 = to_double(positions[c[1]])
    p2 = to_double(positions[c[2]])
    scale = origin_magnitude(p0, p1, p2, wp.float64(0.0))
    n = grid[0]
    grow = wp.float64(3.0 * REGION_SLACK)
    start = first + wp.tid() * ITEMS_PER_THREAD
    for r in range(start, wp.min(start + ITEMS_PER_THREAD, end)):
        i = r // n
        j = r % n
        clear = wp.uint8(0)
        if i + j < n:
            a0 = wp.float64(i) / wp.float64(n) - grow
            a1 = wp.float64(i + 1) / wp.float64(n) + grow
            e0 = wp.float64(j) / wp.float64(n) - grow
            e1 = wp.float64(j + 1) / wp.float64(n) + grow
            q00 = region_corner(p0, p1, p2, a0, e0)
            q10 = region_corner(p0, p1, p2, a1, e0)
            q11 = region_corner(p0, p1, p2, a1, e1)
            q01 = region_corner(p0, p1, p2, a0, e1)
            if (region_part_is_clear(buffers, light, face, positions, indices, q00, q10, q11, scale)
                    and region_part_is_clear(buffers, light, face, positions, indices, q00, q11, q01, scale)):
                clear = wp.uint8(1)
        buffers.region_clear[grid[1] + r] = clear


@wp.func
def region_is_clear(buffers: LightBuffers, light: int, mark: wp.uint8, b0: float, b1: float, b2: float) -> bool:
    """Whether the region of the point with barycentric coordinates (b0, b1, b2) of a triangle with
    region mark ``mark`` is marked clear (mark_clear_regions)."""
    if b0 < -REGION_SLACK or b1 < -REGION_SLACK or b2 < -REGION_SLACK:
        return False
    grid = buffers.region_grids[light * MAX_REGION_TRIANGLES + int(mark - REGIONS_CLEAR)]
    n = grid[0]
    i = wp.clamp(int(b0 * float(n)), 0, n - 1)
    # where b0 + b1 rounds above 1, the region below it (grown by the slack) holds the point
    j = wp.clamp(int(b1 * float(n)), 0, n - 1 - i)
    return buffers.region_clear[grid[1] + i * n + j] != wp.uint8(0)


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


@wp.kernel
def nearest_surface_distance(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    """Distance from each point to the nearest triangle of ``mesh`` (RAY_FAR for an empty one)."""
    i = wp.tid()
    out[i] = RAY_FAR
    q = wp.mesh_query_point_no_sign(mesh, points[i], RAY_FAR)
    if q.result:
        out[i] = wp.length(wp.mesh_eval_position(mesh, q.face, q.u, q.v) - points[i])


# ---------------------------------------------------------------------- shadow rays
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
