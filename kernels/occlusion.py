"""Culling of clusters of triangles for the rasterizer (kernels/raster.py).

A cluster is CLUSTER_SIZE consecutive triangles: neighbours on the surface, as upload stores
triangles along a Morton curve (pbrwarp/locality.py). Its bounding box and normal cone, computed
once per mesh (cluster_bounds), bound where its triangles project, how near they come and which
way they face. The rasterizer drops clusters off screen (outside_view, cluster_view) and, where
every triangle is flagged for back-face culling, those facing away (faces_away); it draws the
clusters facing the eye (faces_eye) first, then skips every other cluster whose box lies behind
what the buffer holds at every sample its triangles could cover (is_occluded: the z-buffer test
of a bounding box of Greene, Kass and Miller 1993, at the finest level of their hierarchy, read
from the buffer itself). Off-screen and occlusion tests are conservative: a cluster is skipped
only where none of its triangles could change the visibility buffer, which is then the one drawn
without culling, bit for bit. The facing-away test leaves a margin (BACK_FACE_MARGIN) for the
snapping of vertices, which decides each triangle's facing in the rasterizer.
"""

import warp as wp

from .projection import Projection, camera_coordinates, empty_rect, sampled_pixels_within, screen_point
from .robust import to_double

wp.set_module_options({"enable_backward": False})

# Triangles per cluster: a few pixels across on a dense mesh at 1024², where culling pays; smaller
# clusters fit the surface more tightly and so cull more, while their tests cost little. At
# most 64: the rasterizer draws a cluster from one 64-bit mask of its triangles.
CLUSTER_SIZE = wp.constant(64)
# Samples a cluster's rectangle may hold and still be tested: larger clusters, whose triangles are
# large too, are drawn (testing them would cost more than it could save).
MAX_TESTED_SAMPLES = wp.constant(4096)
# Bound on the float64 rounding of a camera-space depth relative to the magnitudes it is computed
# from, with room to spare (a few units of 1.1e-16 per operation).
DEPTH_ROUNDING = wp.constant(wp.float64(1.0e-12))
# Relative margin between a cluster's nearest depth and what it must lie behind: the rasterizer's
# interpolated depth (float64, then rounded to float32, 6e-8) may fall that far below its
# triangle's nearest vertex.
DEPTH_MARGIN = wp.constant(wp.float64(1.0e-6))
# Angle (radians) by which every triangle of a cluster must face away from the eye for the cluster
# to be culled as a whole: a triangle that close to edge-on keeps its winding after its vertices
# are snapped (kernels/triangle_setup.py) unless it is under ~1/50 pixel across.
BACK_FACE_MARGIN = wp.constant(wp.float64(0.05))
# Fates of clusters in the rasterizer's ClusterCulling.nearest, besides the nearest depth (> 0) of
# one deferred to the occlusion test: drawn in the first pass, or skipped (off screen, facing away,
# occluded).
NOT_DEFERRED = wp.constant(wp.float64(-1.0))
SKIPPED = wp.constant(wp.float64(-2.0))


@wp.func
def triangle_normal(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> wp.vec3d:
    """(p1 - p0) x (p2 - p0) in float64: twice the area, along the counter-clockwise normal."""
    q0 = to_double(p0)
    return wp.cross(to_double(p1) - q0, to_double(p2) - q0)


@wp.func
def box_centre(lo: wp.vec3, hi: wp.vec3) -> wp.vec3d:
    return (to_double(lo) + to_double(hi)) * wp.float64(0.5)


@wp.kernel
def cluster_bounds(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), triangles: int,
                   lower: wp.array(dtype=wp.vec3), upper: wp.array(dtype=wp.vec3), axis: wp.array(dtype=wp.vec3),
                   spread: wp.array(dtype=float)):
    """Per cluster, the box of its vertices (exact: float32 minima and maxima) and the cone of
    its triangles' normals (counter-clockwise winding): its axis, the direction of their
    area-weighted sum, and the cosine of the largest angle between the axis and a normal (-1 if
    the normals do not fit in a cone narrower than a half-space). Degenerate triangles, which
    cover nothing, are left out of the cone. Indices must have been checked to lie in range."""
    cluster = wp.tid()
    first = cluster * CLUSTER_SIZE
    end = wp.min(first + CLUSTER_SIZE, triangles)
    lo = wp.vec3(wp.inf, wp.inf, wp.inf)
    hi = wp.vec3(-wp.inf, -wp.inf, -wp.inf)
    normal_sum = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
    for face in range(first, end):
        p0 = positions[indices[3 * face]]
        p1 = positions[indices[3 * face + 1]]
        p2 = positions[indices[3 * face + 2]]
        lo = wp.min(lo, wp.min(p0, wp.min(p1, p2)))
        hi = wp.max(hi, wp.max(p0, wp.max(p1, p2)))
        normal_sum = normal_sum + triangle_normal(p0, p1, p2)
    length = wp.length(normal_sum)
    cone_cos = wp.float64(-1.0)
    direction = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
    if length > wp.float64(0.0):
        direction = normal_sum / length
        cone_cos = wp.float64(1.0)
        for face in range(first, end):
            n = triangle_normal(positions[indices[3 * face]], positions[indices[3 * face + 1]],
                                positions[indices[3 * face + 2]])
            n_length = wp.length(n)
            if n_length > wp.float64(0.0):
                cone_cos = wp.min(cone_cos, wp.dot(n, direction) / n_length)
    lower[cluster] = lo
    upper[cluster] = hi
    axis[cluster] = wp.vec3(float(direction[0]), float(direction[1]), float(direction[2]))
    spread[cluster] = float(cone_cos)


@wp.func
def view_direction(proj: Projection, lo: wp.vec3, hi: wp.vec3) -> wp.vec3d:
    """The direction the camera looks at a cluster along: from the eye to its box's centre, or
    the projection's direction (along which camera a and b stay put, z grows) in parallel."""
    if proj.orthographic != 0:
        m = proj.to_camera
        d = wp.cross(wp.vec3d(m[0, 0], m[0, 1], m[0, 2]), wp.vec3d(m[1, 0], m[1, 1], m[1, 2]))
        if wp.dot(d, wp.vec3d(m[2, 0], m[2, 1], m[2, 2])) < wp.float64(0.0):
            d = -d
        return d
    return box_centre(lo, hi) - proj.eye


@wp.func
def faces_eye(proj: Projection, lo: wp.vec3, hi: wp.vec3, axis: wp.vec3) -> bool:
    """Whether a cluster mostly faces the eye (its normals' axis points back along the view
    direction): the clusters drawn before the occlusion test, a guess that decides how much is
    culled, never what is drawn."""
    return wp.dot(to_double(axis), view_direction(proj, lo, hi)) < wp.float64(0.0)


@wp.func
def faces_away(proj: Projection, lo: wp.vec3, hi: wp.vec3, axis: wp.vec3, spread: float) -> bool:
    """Whether every triangle of a cluster faces away from the eye by more than BACK_FACE_MARGIN
    (the normal cone test of Shirman and Abi-Ezzi 1993): the angle between the cone's axis and
    the direction to any point of the box, within view_angle + asin(radius / distance) for its
    bounding sphere, plus the cone's half-angle and the margin stays below a right angle.
    In cosines and sines, so without inverse trigonometric functions."""
    if spread <= 0.0:
        return False
    v = view_direction(proj, lo, hi)
    distance = wp.length(v)
    sin_sphere = wp.float64(0.0)
    if proj.orthographic == 0:
        half_diagonal = (to_double(hi) - to_double(lo)) * wp.float64(0.5)
        if not (wp.length(half_diagonal) < distance):
            return False
        sin_sphere = wp.length(half_diagonal) / distance
    cos_sphere = wp.sqrt(wp.float64(1.0) - sin_sphere * sin_sphere)
    cos_cone = wp.float64(spread)
    sin_cone = wp.sqrt(wp.max(wp.float64(1.0) - cos_cone * cos_cone, wp.float64(0.0)))
    # the angle cone + sphere + margin, sum of angles below a right angle each
    sin_sum = sin_cone * cos_sphere + cos_cone * sin_sphere
    cos_sum = cos_cone * cos_sphere - sin_cone * sin_sphere
    sin_total = sin_sum * wp.cos(BACK_FACE_MARGIN) + cos_sum * wp.sin(BACK_FACE_MARGIN)
    cos_total = cos_sum * wp.cos(BACK_FACE_MARGIN) - sin_sum * wp.sin(BACK_FACE_MARGIN)
    a = to_double(axis)
    # cos(view angle) > cos(right angle - total) = sin(total), the total below a right angle
    return cos_total > wp.float64(0.0) and wp.dot(a, v) > sin_total * wp.length(a) * distance


@wp.func
def all_flagged(flags: wp.array(dtype=wp.uint8), first: int, end: int) -> bool:
    """Whether flags[first:end] are all nonzero (False for an empty flag array)."""
    if flags.shape[0] == 0:
        return False
    for i in range(first, end):
        if flags[i] == wp.uint8(0):
            return False
    return True


@wp.func
def outside_view(proj: Projection, lo: wp.vec3, hi: wp.vec3) -> bool:
    """Whether a cluster's box lies wholly outside the view (beside it or behind the camera
    plane), cheaply: from the box of its camera-space
    image (centre and half-extents), tested against the planes of the view's sides, which pass a
    pixel beyond the image's edges (the rasterizer's sampled_pixel_range) plus the rounding."""
    m = proj.to_camera
    centre = box_centre(lo, hi)
    half = (to_double(hi) - to_double(lo)) * wp.float64(0.5)
    c = m * (centre - proj.eye)
    # the extents of the image of the box, grown by the rounding of its corners' coordinates
    magnitude = wp.vec3d(wp.abs(centre[0]) + half[0] + wp.abs(proj.eye[0]), wp.abs(centre[1]) + half[1]
                         + wp.abs(proj.eye[1]), wp.abs(centre[2]) + half[2] + wp.abs(proj.eye[2]))
    e = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
    for i in range(3):
        row = wp.vec3d(wp.abs(m[i, 0]), wp.abs(m[i, 1]), wp.abs(m[i, 2]))
        e[i] = wp.dot(row, half) + DEPTH_ROUNDING * wp.dot(row, magnitude)
    # |a| <= sx z (or sx in parallel), sx = 1 + 2 pixels / half the image
    sx = wp.float64(1.0) + wp.float64(2.0) / proj.half_width
    sy = wp.float64(1.0) + wp.float64(2.0) / proj.half_height
    if proj.orthographic != 0:
        return (c[2] + e[2] <= wp.float64(0.0) or c[0] - e[0] > sx or c[0] + e[0] < -sx or c[1] - e[1] > sy
                or c[1] + e[1] < -sy)
    # a > sx z everywhere in the box if its least a - sx z is positive, and so on
    return (c[2] + e[2] <= wp.float64(0.0) or c[0] - sx * c[2] - (e[0] + sx * e[2]) > wp.float64(0.0)
            or c[0] + sx * c[2] + (e[0] + sx * e[2]) < wp.float64(0.0)
            or c[1] - sy * c[2] - (e[1] + sy * e[2]) > wp.float64(0.0)
            or c[1] + sy * c[2] + (e[1] + sy * e[2]) < wp.float64(0.0))


@wp.func
def cluster_view(proj: Projection, lo: wp.vec3, hi: wp.vec3, spp: int):
    """(rect, nearest) of a cluster's box: the pixels whose samples its triangles may cover
    (empty if none: off screen or wholly behind the camera plane) and a lower bound on the
    depth the rasterizer gives them (0 where the box reaches the camera plane: not testable).
    The corners' camera coordinates are the lowest corner's plus the edges' (one matrix product
    for three edges rather than one per corner); DEPTH_ROUNDING covers the difference."""
    m = proj.to_camera
    base = camera_coordinates(proj, lo)
    ex = wp.vec3d(m[0, 0], m[1, 0], m[2, 0]) * (wp.float64(hi[0]) - wp.float64(lo[0]))
    ey = wp.vec3d(m[0, 1], m[1, 1], m[2, 1]) * (wp.float64(hi[1]) - wp.float64(lo[1]))
    ez = wp.vec3d(m[0, 2], m[1, 2], m[2, 2]) * (wp.float64(hi[2]) - wp.float64(lo[2]))
    nearest = wp.float64(wp.inf)
    farthest = wp.float64(-wp.inf)
    x0 = wp.float64(wp.inf)
    y0 = wp.float64(wp.inf)
    x1 = wp.float64(-wp.inf)
    y1 = wp.float64(-wp.inf)
    for k in range(8):
        c = base
        if (k & 1) != 0:
            c = c + ex
        if (k & 2) != 0:
            c = c + ey
        if (k & 4) != 0:
            c = c + ez
        nearest = wp.min(nearest, c[2])
        farthest = wp.max(farthest, c[2])
        if c[2] > wp.float64(0.0) or proj.orthographic != 0:
            xy = screen_point(proj, c)
            x0 = wp.min(x0, xy[0])
            y0 = wp.min(y0, xy[1])
            x1 = wp.max(x1, xy[0])
            y1 = wp.max(y1, xy[1])
    # how far rounding may have moved the corners' depths
    extent = wp.vec3d(wp.max(wp.abs(wp.float64(lo[0])), wp.abs(wp.float64(hi[0]))) + wp.abs(proj.eye[0]),
                      wp.max(wp.abs(wp.float64(lo[1])), wp.abs(wp.float64(hi[1]))) + wp.abs(proj.eye[1]),
                      wp.max(wp.abs(wp.float64(lo[2])), wp.abs(wp.float64(hi[2]))) + wp.abs(proj.eye[2]))
    rounding = DEPTH_ROUNDING * (wp.abs(m[2, 0]) * extent[0] + wp.abs(m[2, 1]) * extent[1]
                                 + wp.abs(m[2, 2]) * extent[2])
    if farthest < -rounding:
        return empty_rect(), wp.float64(0.0)
    nearest = nearest * (wp.float64(1.0) - DEPTH_MARGIN) - rounding
    if nearest <= wp.float64(0.0):
        # the box reaches the camera plane, where its projection is unbounded
        return wp.vec4i(0, 0, proj.width - 1, proj.height - 1), wp.float64(0.0)
    r = sampled_pixels_within(proj, wp.vec4d(x0, y0, x1, y1), spp)
    if r[0] > r[2]:
        return r, wp.float64(0.0)
    return r, nearest


@wp.func_native("""
    // signed comparisons (AVX2 has none of unsigned 64-bit integers) of entries and bound with
    // their top bit flipped, OR-ed without a branch, so that a row runs in vector registers
    const wp::int64 flipped = (wp::int64)(bound ^ 0x8000000000000000ull);
    for (int row = rect[1]; row <= rect[3]; ++row) {
        const wp::uint64* entry = (const wp::uint64*)((const char*)out.data + (size_t)row * out.strides[0]);
        wp::int64 reached = 0;
        for (int i = rect[0] * spp; i < (rect[2] + 1) * spp; ++i)
            reached |= (wp::int64)(entry[i] ^ 0x8000000000000000ull) >= flipped;
        if (reached) return false;
    }
    return true;
    """)
def is_occluded(out: wp.array2d(dtype=wp.uint64), rect: wp.vec4i, spp: int, bound: wp.uint64) -> bool:
    """Whether every entry of ``out`` over the samples of rect (cluster_view's, nonempty) lies
    below ``bound``, the least entry a deferred cluster's triangles could write there, so that
    none of them can win a sample, not even a tie. Row by row, each without a branch. Other
    launches may be drawing meanwhile: they only lower entries."""
    ...
