"""Triangle setup for the rasterizer: the mesh's vertices projected and snapped to fixed point
(1/4096 pixel) within a guard band, and the screen rectangle a triangle may cover, from its snapped
vertices or, for a triangle reaching behind the camera, from the part of it in front
(clipped_rect, which the light buffers use too)."""

import warp as wp

from .projection import (SUBPIXEL_SCALE, Projection, camera_coordinates, clamped_rect, empty_rect, pixels_around,
                         sampled_pixel_range, screen_point)

wp.set_module_options({"enable_backward": False})

# Largest |screen coordinate| in pixels a projected vertex may have. Snapped coordinates (to
# 1/4096 pixel, kernels/projection.py SUBPIXEL_BITS) are then below 2^29 and samples (images up
# to MAX_IMAGE_SIZE) below 2^28, so an edge function A X + B Y + C stays below 2^61 and is
# computed exactly.
GUARD_BAND = wp.constant(wp.float64(131072.0))
# Snapped coordinates within the guard band plus 2^30 are positive, and below 2^31 (see
# project_vertices).
SNAP_SHIFT = wp.constant(wp.int64(1073741824))
SNAP_OFFSET = wp.constant(wp.float64(1073741824.5))
MAX_IMAGE_SIZE = 65536

# The x of a vertex's screen position when it is not projected: snapped coordinates lie within
# +-2^29, so int32 holds them and these codes below them.
BEHIND_CAMERA = wp.constant(-2147483648)
OUTSIDE_GUARD_BAND = wp.constant(-2147483647)
# Relative size below which a direction component may have the wrong sign after rounding.
DIRECTION_TOLERANCE = wp.constant(wp.float64(1.0e-12))


@wp.struct
class RasterMesh:
    """A mesh as the rasterizer draws it: vertex positions and a flat index array (vertex_count and
    triangles their counts), per triangle a flag (nonzero) to drop it where it faces away from the
    eye (cull_back_faces; empty: none dropped), and per vertex what project_vertices makes of it
    for this call: its snapped screen position or code (screen) and its depth weight."""

    positions: wp.array(dtype=wp.vec3)
    indices: wp.array(dtype=wp.int32)
    vertex_count: int
    triangles: int
    cull_back_faces: wp.array(dtype=wp.uint8)
    screen: wp.array(dtype=wp.vec2i)
    depth_weights: wp.array(dtype=wp.float64)


# ---------------------------------------------------------------------- vertices
_PROJECT_VERTICES = """
#pragma clang fp contract(off)
    // Camera coordinates as camera_coordinates computes them, pixel coordinates as screen_point
    // does (no fused multiply-adds, the same order of operations), every vertex handled alike
    // and without branches, so that the compiler runs several at once in vector registers.
    const double m00 = to_camera.data[0][0], m01 = to_camera.data[0][1], m02 = to_camera.data[0][2];
    const double m10 = to_camera.data[1][0], m11 = to_camera.data[1][1], m12 = to_camera.data[1][2];
    const double m20 = to_camera.data[2][0], m21 = to_camera.data[2][1], m22 = to_camera.data[2][2];
    const double ex = eye[0], ey = eye[1], ez = eye[2];
    const bool parallel = orthographic != 0;
    const double guard = GUARD, scale = SCALE, offset = OFFSET;
    const wp::int32 shift = SHIFT;
    wp::int32* out = (wp::int32*)screen.data;
    double* weights = (double*)depth_weights.data;
    auto project = [&](const float* p, int i) {
        const double dx = (double)p[0] - ex, dy = (double)p[1] - ey, dz = (double)p[2] - ez;
        const double a = m00 * dx + m01 * dy + m02 * dz;
        const double b = m10 * dx + m11 * dy + m12 * dz;
        const double z = m20 * dx + m21 * dy + m22 * dz;
        const double inverse_z = 1.0 / z;
        const double x = parallel ? (a + 1.0) * half_width : (a * inverse_z + 1.0) * half_width;
        const double y = parallel ? (1.0 - b) * half_height : (1.0 - b * inverse_z) * half_height;
        const bool inside = x <= guard && x >= -guard && y <= guard && y >= -guard;
        // clamped first (NaN to -guard), so that the conversion is defined for every vertex
        const double xc = x >= -guard ? (x <= guard ? x : guard) : -guard;
        const double yc = y >= -guard ? (y <= guard ? y : guard) : -guard;
        const wp::int32 sx = (wp::int32)(xc * scale + offset) - shift;
        const wp::int32 sy = (wp::int32)(yc * scale + offset) - shift;
        const bool behind = z <= 0.0;
        out[2 * (size_t)i] = behind ? BEHIND : (inside ? sx : OUTSIDE);
        out[2 * (size_t)i + 1] = behind || !inside ? 0 : sy;
        weights[i] = parallel ? z : inverse_z;
    };
    const char* base = (const char*)positions.data;
    const size_t stride = positions.strides[0];
    if (stride == 3 * sizeof(float) && screen.strides[0] == 2 * sizeof(wp::int32) &&
        depth_weights.strides[0] == sizeof(double)) {
        for (int i = first; i < end; ++i) project((const float*)base + 3 * (size_t)i, i);
    } else {
        for (int i = first; i < end; ++i) project((const float*)(base + (size_t)i * stride), i);
    }
"""
for name, value in (("GUARD", repr(float(GUARD_BAND))), ("SCALE", repr(float(SUBPIXEL_SCALE))),
                    ("OFFSET", repr(float(SNAP_OFFSET))), ("SHIFT", str(int(SNAP_SHIFT))),
                    ("BEHIND", f"({int(BEHIND_CAMERA) + 1} - 1)"), ("OUTSIDE", str(int(OUTSIDE_GUARD_BAND)))):
    _PROJECT_VERTICES = _PROJECT_VERTICES.replace(name, value)


@wp.func_native(_PROJECT_VERTICES)
def project_vertices(positions: wp.array(dtype=wp.vec3), to_camera: wp.mat33d, eye: wp.vec3d, half_width: wp.float64,
                     half_height: wp.float64, orthographic: int, first: int, end: int,
                     screen: wp.array(dtype=wp.vec2i), depth_weights: wp.array(dtype=wp.float64)):
    """Vertices [first, end) projected (Projection's fields given apart): screen[i] their pixel
    coordinates in fixed point, rounded to nearest (shifted positive so that truncation rounds
    down), or (BEHIND_CAMERA, 0) for camera z <= 0, or (OUTSIDE_GUARD_BAND, 0) beyond the guard
    band; depth_weights[i] what is interpolated linearly in screen space, 1/z in perspective,
    z itself in parallel projection (see rasterize_triangle), meaningful where projected. In C++,
    a branch-free loop over the vertices, so that the compiler can vectorize it."""
    ...


@wp.func
def is_projected(q: wp.vec2i) -> bool:
    return q[0] > OUTSIDE_GUARD_BAND


# ---------------------------------------------------------------------- triangles
@wp.func
def are_valid_indices(c: wp.vec3i, vertex_count: int) -> bool:
    """Whether 0 <= c[i] < vertex_count for each corner: one unsigned comparison each."""
    n = wp.uint32(vertex_count)
    return wp.uint32(c[0]) < n and wp.uint32(c[1]) < n and wp.uint32(c[2]) < n


@wp.func
def signed_area(q0: wp.vec2i, q1: wp.vec2i, q2: wp.vec2i) -> wp.int64:
    """Twice the signed area of a projected triangle, exact."""
    return ((wp.int64(q1[0]) - wp.int64(q0[0])) * (wp.int64(q2[1]) - wp.int64(q0[1]))
            - (wp.int64(q1[1]) - wp.int64(q0[1])) * (wp.int64(q2[0]) - wp.int64(q0[0])))


@wp.func
def rect_pixels(r: wp.vec4i) -> int:
    return (r[2] - r[0] + 1) * (r[3] - r[1] + 1)


# ---------------------------------------------------------------------- screen rectangles
@wp.func
def projected_rect(q0: wp.vec2i, q1: wp.vec2i, q2: wp.vec2i, spp: int, width: int, height: int) -> wp.vec4i:
    """Pixels with samples a projected triangle may cover."""
    xs = sampled_pixel_range(wp.int64(wp.min(q0[0], wp.min(q1[0], q2[0]))),
                             wp.int64(wp.max(q0[0], wp.max(q1[0], q2[0]))), spp)
    ys = sampled_pixel_range(wp.int64(wp.min(q0[1], wp.min(q1[1], q2[1]))),
                             wp.int64(wp.max(q0[1], wp.max(q1[1], q2[1]))), spp)
    return clamped_rect(xs[0], ys[0], xs[1], ys[1], width, height)


@wp.func
def include_point(bounds: wp.vec4d, x: wp.float64, y: wp.float64) -> wp.vec4d:
    """bounds = (min x, min y, max x, max y) grown to hold (x, y)."""
    return wp.vec4d(wp.min(bounds[0], x), wp.min(bounds[1], y), wp.max(bounds[2], x), wp.max(bounds[3], y))


@wp.func
def include_direction(bounds: wp.vec4d, a: wp.float64, b: wp.float64, tolerance: wp.float64) -> wp.vec4d:
    """bounds grown by the projection of points approaching the camera plane z = 0 in camera
    direction (a, b): they run off to infinity along it (screen y grows as b falls)."""
    far = wp.float64(wp.inf)
    r = bounds
    if a > -tolerance:
        r[2] = far
    if a < tolerance:
        r[0] = -far
    if b > -tolerance:
        r[1] = -far
    if b < tolerance:
        r[3] = far
    return r


@wp.func
def include_clipped_edge(bounds: wp.vec4d, front: wp.vec3d, back: wp.vec3d) -> wp.vec4d:
    """bounds grown by edge (front, back), front.z > 0 >= back.z, where it reaches z = 0."""
    s = front[2] / (front[2] - back[2])
    a = front[0] + s * (back[0] - front[0])
    b = front[1] + s * (back[1] - front[1])
    scale = wp.max(wp.abs(front[0]), wp.max(wp.abs(front[1]), wp.abs(front[2])))
    scale = wp.max(scale, wp.max(wp.abs(back[0]), wp.max(wp.abs(back[1]), wp.abs(back[2]))))
    return include_direction(bounds, a, b, DIRECTION_TOLERANCE * scale)


@wp.func
def include_vertex_and_edge(bounds: wp.vec4d, proj: Projection, c: wp.vec3d, next_c: wp.vec3d) -> wp.vec4d:
    r = bounds
    zero = wp.float64(0.0)
    if c[2] > zero:
        xy = screen_point(proj, c)
        r = include_point(r, xy[0], xy[1])
        if next_c[2] <= zero:
            r = include_clipped_edge(r, c, next_c)
    elif next_c[2] > zero:
        r = include_clipped_edge(r, next_c, c)
    return r


@wp.func
def clipped_rect(proj: Projection, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> wp.vec4i:
    """Pixels the part in front of the camera (z > 0) of a triangle may cover, conservatively.

    That part projects to a convex region: the hull of its vertices' projections and, where it
    reaches the camera plane, of the directions it runs off to infinity in.
    """
    c0 = camera_coordinates(proj, p0)
    c1 = camera_coordinates(proj, p1)
    c2 = camera_coordinates(proj, p2)
    far = wp.float64(wp.inf)
    bounds = wp.vec4d(far, far, -far, -far)
    bounds = include_vertex_and_edge(bounds, proj, c0, c1)
    bounds = include_vertex_and_edge(bounds, proj, c1, c2)
    bounds = include_vertex_and_edge(bounds, proj, c2, c0)
    if not (bounds[0] <= bounds[2]):
        return empty_rect()
    return pixels_around(proj, bounds)
