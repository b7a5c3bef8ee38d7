"""Primary visibility by rasterization: per sample, the nearest triangle and its depth.

The visibility buffer holds one uint64 per sample, (float32 bits of depth) << 32 | triangle id,
so that an unsigned minimum keeps the nearest triangle (the lower id on an exact depth tie) and
NO_TRIANGLE (all ones) means nothing was hit. Depth is camera-space z, the coefficient of
``cam.forward`` in (point - eye): monotone along every camera ray, which is all a per-sample
comparison needs.

Coverage is decided in exact int64 arithmetic on vertices and samples snapped to 1/4096 pixel, with
a tie-breaking rule on edges, so a sample on an edge shared by two triangles is covered exactly
once. Triangles that reach behind the camera or outside the guard band are not projected: they
are rasterized homogeneously in float64 over a conservative screen rectangle
(rasterize_homogeneous).
``ray_triangle_intersection`` is the ray-triangle test Warp's ``mesh_query_ray`` runs, step for
step, which a shading kernel calls to recompute the hit of the triangle this buffer names.
A parallel projection (Projection.orthographic) serves directional lights' shadow maps.

visibility_pipeline runs the stages, launched once per thread, the launches meeting at barriers:
the buffer cleared and vertices projected; then per triangle its screen rectangle, small
triangles drawn at once with atomic minima and larger ones binned into tiles; then the binned
ones drawn, tile by tile. Each launch takes the triangles of its own range of the mesh and the
tiles of its own band of the image first, then what is left of the others'. Given a mesh's clusters
(kernels/occlusion.py), it skips those off screen or (where flagged) facing away and, where
enough face away, draws in two passes: the clusters facing the eye first, then those facing
away that the first pass does not hide.
"""

import warp as wp

from .camera import CameraData, camera_ray_direction
from .projection import (
    HALF_PIXEL,
    PIXEL,
    SUBPIXEL_BITS,
    SUBPIXEL_SCALE,
    Projection,
    camera_coordinates,
    camera_projection,
    clamped_rect,
    empty_rect,
    has_usable_axes,
    pixels_around,
    sampled_pixel_range,
    screen_point,
)
from .robust import to_double
from .sampling import multi_jittered_sample
from .occlusion import (
    CLUSTER_SIZE,
    MAX_TESTED_SAMPLES,
    NOT_DEFERRED,
    SKIPPED,
    all_flagged,
    cluster_view,
    faces_away,
    faces_eye,
    is_occluded,
    outside_view,
)
from .work_queue import add_atomically, reset_range, take_next_from_ranges, take_next_item_from

wp.set_module_options({"enable_backward": False})

NO_TRIANGLE = wp.constant(wp.uint64(0xFFFFFFFFFFFFFFFF))
TRIANGLE_MASK = wp.constant(wp.uint64(0xFFFFFFFF))
DEPTH_SHIFT = wp.constant(wp.uint64(32))

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
# Screen tiles are TILE_SIZE x TILE_SIZE pixels; each is rasterized by one thread, alone.
TILE_SIZE = wp.constant(32)
# Triangles whose screen rectangle spans at most this many pixels are drawn as soon as they are
# projected, with atomic minima, instead of being binned into tiles and read again (64 rather
# than 16: one thread's CPU time rasterizing bench/frames.py's scenes fell 10-15% in paired
# development runs, the 512² meshes' did not change).
SMALL_TRIANGLE_PIXELS = wp.constant(64)
# Bound, relative to the magnitude of its terms and per step, on how far an edge function stepped
# along a row in float64 strays from its direct evaluation (a few units of rounding, 1.1e-16, per
# addition), with room to spare.
STEPPED_EDGE_ROUNDING = wp.constant(wp.float64(1.0e-15))
# Rows at least this wide solve for their covered run of pixels before stepping along it: the
# solve (three int64 divisions) pays off only where it skips many uncovered pixels, and in
# development trials rows of 8 made dense meshes' small triangles slower.
SPAN_MIN_WIDTH = wp.constant(16)

# The x of a vertex's screen position when it is not projected: snapped coordinates lie within
# +-2^29, so int32 holds them and these codes below them.
BEHIND_CAMERA = wp.constant(-2147483648)
OUTSIDE_GUARD_BAND = wp.constant(-2147483647)
# Relative size of c0 . (c1 x c2), for camera-space triangle vertices, below which the eye counts as
# lying in the triangle's plane: far above the float64 rounding of camera coordinates (1e-16).
EYE_IN_PLANE_TOLERANCE = wp.constant(wp.float64(1.0e-9))
# Relative size below which a direction component may have the wrong sign after rounding.
DIRECTION_TOLERANCE = wp.constant(wp.float64(1.0e-12))


@wp.func_native("return fmaf(a, b, c);")
def fused_multiply_add(a: float, b: float, c: float) -> float: ...


@wp.func_native("memset((wp::uint64*)((char*)out.data + (size_t)row * out.strides[0]) + first, 0xFF, "
                "sizeof(wp::uint64) * (size_t)count);")
def clear_row_span(out: wp.array2d(dtype=wp.uint64), row: int, first: int, count: int):
    """out[row, first:first + count] = NO_TRIANGLE (all bits set) with one memset, which the
    compiler vectorizes where it does not an element-by-element loop; rows must be contiguous."""
    ...


@wp.func_native("""
    const char* base = (const char*)out.data + (size_t)row * out.strides[0] + sizeof(wp::uint64) * (size_t)first;
    for (int offset = 0; offset < (int)(sizeof(wp::uint64) * count); offset += 64) __builtin_prefetch(base + offset, 1, 3);
    """)
def prefetch_row_span(out: wp.array2d(dtype=wp.uint64), row: int, first: int, count: int):
    """Asks for the cache lines of out[row, first:first + count], to be written soon: a tile's
    rows lie a whole image row apart, where the hardware prefetchers do not follow."""
    ...


@wp.func_native("wp::uint32 bits; memcpy(&bits, &x, sizeof(bits)); return bits;")
def float_bits(x: float) -> wp.uint32: ...


@wp.func
def visibility_entry(depth: float, triangle: int) -> wp.uint64:
    """The buffer entry of a hit; smaller entries are nearer (depth >= 0)."""
    return (wp.uint64(float_bits(depth)) << DEPTH_SHIFT) | wp.uint64(triangle)


@wp.func
def visible_triangle(entry: wp.uint64) -> int:
    """The triangle id of a buffer entry, -1 for NO_TRIANGLE."""
    if entry == NO_TRIANGLE:
        return -1
    return int(entry & TRIANGLE_MASK)


@wp.func
def difference_of_products(a: float, b: float, c: float, d: float) -> float:
    """a b - c d with the rounding of c d compensated (Kahan), as Warp's diff_product."""
    cd = c * d
    return fused_multiply_add(a, b, -cd) + fused_multiply_add(-c, d, cd)


@wp.func
def longest_axis(v: wp.vec3) -> int:
    """Index of the largest |component|, the first on ties (Warp's max_dim)."""
    axis = int(0)
    largest = wp.abs(v[0])
    if wp.abs(v[1]) > largest:
        axis = 1
        largest = wp.abs(v[1])
    if wp.abs(v[2]) > largest:
        axis = 2
    return axis


@wp.func
def triangle_corners(indices: wp.array(dtype=wp.int32), face: int) -> wp.vec3i:
    """The vertex indices of triangle ``face`` in a flat index array."""
    return wp.vec3i(indices[3 * face], indices[3 * face + 1], indices[3 * face + 2])


@wp.func
def ray_triangle_intersection(origin: wp.vec3, direction: wp.vec3, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3):
    """Watertight ray-triangle test (Woop, Benthin and Wald 2013), step for step Warp's
    intersect_ray_tri_woop (warp/native/intersect.h), which ``wp.mesh_query_ray`` runs.

    Returns (hit, t, u, v): the point origin + t direction = p0 u + p1 v + p2 (1 - u - v), Warp's
    barycentric convention. hit is False when the ray misses or t < 0; t, u, v are then those of
    the ray's intersection with the triangle's plane (extrapolated barycentrics), or all 0 when the
    ray is parallel to the plane.
    """
    kz = longest_axis(direction)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    # keep the winding of the sheared triangle
    if direction[kz] < 0.0:
        swap = kx
        kx = ky
        ky = swap
    shear_x = direction[kx] / direction[kz]
    shear_y = direction[ky] / direction[kz]
    shear_z = 1.0 / direction[kz]
    a = p0 - origin
    b = p1 - origin
    c = p2 - origin
    ax = a[kx] - shear_x * a[kz]
    ay = a[ky] - shear_y * a[kz]
    bx = b[kx] - shear_x * b[kz]
    by = b[ky] - shear_y * b[kz]
    cx = c[kx] - shear_x * c[kz]
    cy = c[ky] - shear_y * c[kz]
    eu = difference_of_products(cx, by, cy, bx)
    ev = difference_of_products(ax, cy, ay, cx)
    ew = difference_of_products(bx, ay, by, ax)
    # an edge through the ray: decide its sign in double precision, so neighbours agree
    if eu == 0.0 or ev == 0.0 or ew == 0.0:
        eu = float(wp.float64(cx) * wp.float64(by) - wp.float64(cy) * wp.float64(bx))
        ev = float(wp.float64(ax) * wp.float64(cy) - wp.float64(ay) * wp.float64(cx))
        ew = float(wp.float64(bx) * wp.float64(ay) - wp.float64(by) * wp.float64(ax))
    inside = not ((eu < 0.0 or ev < 0.0 or ew < 0.0) and (eu > 0.0 or ev > 0.0 or ew > 0.0))
    det = eu + ev + ew
    if det == 0.0:
        return False, 0.0, 0.0, 0.0
    scaled_t = eu * (shear_z * a[kz]) + ev * (shear_z * b[kz]) + ew * (shear_z * c[kz])
    behind = (det > 0.0 and scaled_t < 0.0) or (det < 0.0 and scaled_t > 0.0)
    inv_det = 1.0 / det
    return inside and not behind, scaled_t * inv_det, eu * inv_det, ev * inv_det


# ---------------------------------------------------------------------- sample positions
@wp.kernel
def sample_positions(spp: int, grid_m: int, grid_n: int, seed: int, width: int, first_row: int,
                     out: wp.array2d(dtype=wp.vec2)):
    """Image position (pixels, (0, 0) the top-left corner) of every sample of rows first_row...,
    computed exactly as the ray caster's render_tile computes its rays' (x, y)."""
    i = wp.tid()
    s = i % spp
    px = (i / spp) % width
    py = first_row + i / (spp * width)
    offset = wp.vec2(0.5, 0.5)
    if spp > 1:
        offset = multi_jittered_sample(s, grid_m, grid_n, seed + py * width + px)
    out[py, px * spp + s] = wp.vec2(float(px) + offset[0], float(py) + offset[1])


@wp.func
def snap(x: float) -> wp.int64:
    """A sample coordinate (>= 0) in fixed point."""
    return wp.int64(wp.float64(x) * SUBPIXEL_SCALE + wp.float64(0.5))


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
    z itself in parallel projection (see rasterize_triangle), meaningful where projected. In C++
    so that the compiler vectorizes it: development, the 1M-vertex terrain, 9.2 -> 4.1 ms on one
    thread, the same results bit for bit."""
    ...


@wp.func
def is_projected(q: wp.vec2i) -> bool:
    return q[0] > OUTSIDE_GUARD_BAND


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


# ---------------------------------------------------------------------- rasterization
@wp.func
def owns_boundary(a: wp.int64, b: wp.int64) -> bool:
    """Whether samples exactly on the edge with function a x + b y + c belong to its triangle.
    Equivalent to testing the sample moved by (eps, eps^2): the reversed edge (-a, -b), the same
    edge seen from the neighbouring triangle, gets the opposite answer, and at a shared vertex
    exactly one triangle of a fan wins."""
    return a > wp.int64(0) or (a == wp.int64(0) and b > wp.int64(0))


@wp.func_native("""
    wp::uint64* slot = (wp::uint64*)((char*)out.data + (size_t)row * out.strides[0]) + col;
    if (!shared) { if (entry < *slot) *slot = entry; return; }
    wp::uint64 current = __atomic_load_n(slot, __ATOMIC_RELAXED);
    while (entry < current &&
           !__atomic_compare_exchange_n(slot, &current, entry, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {}
    """)
def keep_nearest(out: wp.array2d(dtype=wp.uint64), row: int, col: int, entry: wp.uint64, shared: bool):
    """out[row, col] = min(out[row, col], entry); atomically if ``shared`` (the sample may be
    written by another thread at the same time), else plainly (its tile is this thread's)."""
    ...


@wp.func
def inside_edge(e: wp.int64, a: wp.int64, b: wp.int64) -> bool:
    """Whether a sample with value e of the edge function a x + b y + c (its triangle oriented
    counter-clockwise) is inside that edge, by rasterize_triangle's rule: e > 0, or e == 0 on an
    edge that owns its boundary."""
    return e > wp.int64(0) or (e == wp.int64(0) and owns_boundary(a, b))


@wp.func
def pixel_centre_depth(q0: wp.vec2i, q1: wp.vec2i, q2: wp.vec2i, w0: wp.float64, w1: wp.float64, w2: wp.float64,
                       px: int, py: int, orthographic: int):
    """(covered, depth) of the centre of pixel (px, py) by a projected triangle, coverage exactly
    as rasterize_triangle decides it with spp = 1 (the same int64 edge functions, evaluated with
    the sample moved to the origin) and depth interpolated as it does; for triangles whose
    rectangle is that one pixel, without rasterize_triangle's setup for a whole rectangle."""
    sx = wp.int64(px) * PIXEL + HALF_PIXEL
    sy = wp.int64(py) * PIXEL + HALF_PIXEL
    x0 = wp.int64(q0[0]) - sx
    y0 = wp.int64(q0[1]) - sy
    x1 = wp.int64(q1[0]) - sx
    y1 = wp.int64(q1[1]) - sy
    x2 = wp.int64(q2[0]) - sx
    y2 = wp.int64(q2[1]) - sy
    area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    if area == wp.int64(0):
        return False, 0.0
    flip = wp.int64(1)
    if area < wp.int64(0):
        flip = wp.int64(-1)
    # edge i runs between the other two vertices, its function evaluated at the sample (the origin)
    e0 = (x1 * y2 - x2 * y1) * flip
    e1 = (x2 * y0 - x0 * y2) * flip
    e2 = (x0 * y1 - x1 * y0) * flip
    if not (inside_edge(e0, (y1 - y2) * flip, (x2 - x1) * flip) and inside_edge(e1, (y2 - y0) * flip, (x0 - x2) * flip)
            and inside_edge(e2, (y0 - y1) * flip, (x1 - x0) * flip)):
        return False, 0.0
    weights = w0 * wp.float64(e0) + w1 * wp.float64(e1) + w2 * wp.float64(e2)
    return True, interpolated_depth(weights, wp.float64(area * flip), orthographic)


@wp.func
def floor_division(n: wp.int64, d: wp.int64) -> wp.int64:
    """floor(n / d) for d > 0 (Warp's integer division truncates towards zero)."""
    q = n / d
    if q * d > n:
        q = q - wp.int64(1)
    return q


@wp.func
def covered_steps(e: wp.int64, step: wp.int64, span: wp.vec2i) -> wp.vec2i:
    """The steps k of ``span`` (first, last; empty when first > last) where the edge function
    e + k step is >= 0: k >= -e / step rounded up for a rising edge, k <= e / -step rounded down
    for a falling one."""
    first = wp.int64(span[0])
    last = wp.int64(span[1])
    if step > wp.int64(0):
        first = wp.max(first, -floor_division(e, step))
    elif step < wp.int64(0):
        last = wp.min(last, floor_division(e, -step))
    elif e < wp.int64(0):
        last = first - wp.int64(1)
    first = wp.min(first, last + wp.int64(1))
    return wp.vec2i(int(first), int(last))


@wp.func
def interpolated_depth(weights: wp.float64, double_area: wp.float64, orthographic: int) -> float:
    if orthographic != 0:
        return float(weights / double_area)
    return float(double_area / weights)


@wp.func
def rasterize_triangle(face: int, q0: wp.vec2i, q1: wp.vec2i, q2: wp.vec2i, w0: wp.float64, w1: wp.float64,
                       w2: wp.float64, rect: wp.vec4i,
                       samples: wp.array2d(dtype=wp.vec2), spp: int, orthographic: int,
                       out: wp.array2d(dtype=wp.uint64),
                       shared: bool):
    """Edge-function coverage of the samples of ``rect`` by a projected triangle, exact in int64;
    depth from the vertices' depth weights w (project_vertices) interpolated linearly in screen
    space: 1/z, perspective-correct, or z in parallel projection. ``shared``: other threads may
    write the same samples (see keep_nearest)."""
    x0 = wp.int64(q0[0])
    y0 = wp.int64(q0[1])
    x1 = wp.int64(q1[0])
    y1 = wp.int64(q1[1])
    x2 = wp.int64(q2[0])
    y2 = wp.int64(q2[1])
    # edge i runs between the other two vertices; e_i(x, y) = a_i x + b_i y + c_i
    a0 = y1 - y2
    b0 = x2 - x1
    c0 = x1 * y2 - x2 * y1
    a1 = y2 - y0
    b1 = x0 - x2
    c1 = x2 * y0 - x0 * y2
    a2 = y0 - y1
    b2 = x1 - x0
    c2 = x0 * y1 - x1 * y0
    area = a0 * x0 + b0 * y0 + c0
    if area == wp.int64(0):
        return
    # either winding: flip clockwise triangles so inside is e_i > 0 (both facings are drawn)
    if area < wp.int64(0):
        a0 = -a0
        b0 = -b0
        c0 = -c0
        a1 = -a1
        b1 = -b1
        c1 = -c1
        a2 = -a2
        b2 = -b2
        c2 = -c2
        area = -area
    # e_i + bias_i >= 0 <=> e_i > 0, or e_i == 0 on an owned edge
    bias0 = wp.int64(0)
    bias1 = wp.int64(0)
    bias2 = wp.int64(0)
    if not owns_boundary(a0, b0):
        bias0 = wp.int64(-1)
    if not owns_boundary(a1, b1):
        bias1 = wp.int64(-1)
    if not owns_boundary(a2, b2):
        bias2 = wp.int64(-1)
    c0 = c0 + bias0
    c1 = c1 + bias1
    c2 = c2 + bias2
    # sum_i e_i w_i / area, the biases taken back out, is 1/z (perspective) or z (parallel): z is
    # one division per covered sample, none for a triangle that covers none
    double_area = wp.float64(area)
    w_bias = -(wp.float64(bias0) * w0 + wp.float64(bias1) * w1 + wp.float64(bias2) * w2)
    if spp == 1:
        # pixel centres: step the edge functions along the row instead of loading samples
        step0 = a0 * PIXEL
        step1 = a1 * PIXEL
        step2 = a2 * PIXEL
        width = rect[2] - rect[0] + 1
        for py in range(rect[1], rect[3] + 1):
            sx = wp.int64(rect[0]) * PIXEL + HALF_PIXEL
            sy = wp.int64(py) * PIXEL + HALF_PIXEL
            e0 = a0 * sx + b0 * sy + c0
            e1 = a1 * sx + b1 * sy + c1
            e2 = a2 * sx + b2 * sy + c2
            first = int(0)
            last = width - 1
            if width >= SPAN_MIN_WIDTH:
                # wide rows: the covered run of pixels solved from the edge functions, so that a
                # large triangle's uncovered pixels cost nothing
                span = covered_steps(e0, step0, covered_steps(e1, step1, covered_steps(e2, step2,
                                                                                       wp.vec2i(first, last))))
                first = span[0]
                last = span[1]
                e0 = e0 + step0 * wp.int64(first)
                e1 = e1 + step1 * wp.int64(first)
                e2 = e2 + step2 * wp.int64(first)
            for px in range(rect[0] + first, rect[0] + last + 1):
                if (e0 | e1 | e2) >= wp.int64(0):
                    weights = w_bias + w0 * wp.float64(e0) + w1 * wp.float64(e1) + w2 * wp.float64(e2)
                    keep_nearest(out, py, px, visibility_entry(interpolated_depth(weights, double_area, orthographic),
                                                               face), shared)
                e0 = e0 + step0
                e1 = e1 + step1
                e2 = e2 + step2
        return
    for py in range(rect[1], rect[3] + 1):
        for col in range(rect[0] * spp, (rect[2] + 1) * spp):
            p = samples[py, col]
            sx = snap(p[0])
            sy = snap(p[1])
            e0 = a0 * sx + b0 * sy + c0
            e1 = a1 * sx + b1 * sy + c1
            e2 = a2 * sx + b2 * sy + c2
            if (e0 | e1 | e2) >= wp.int64(0):
                weights = w_bias + w0 * wp.float64(e0) + w1 * wp.float64(e1) + w2 * wp.float64(e2)
                depth = interpolated_depth(weights, double_area, orthographic)
                keep_nearest(out, py, col, visibility_entry(depth, face), shared)


@wp.func
def trace_triangle(face: int, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, rect: wp.vec4i,
                   samples: wp.array2d(dtype=wp.vec2), spp: int, cam: CameraData, proj: Projection,
                   out: wp.array2d(dtype=wp.uint64)):
    """Coverage of the samples of ``rect`` by casting each sample's camera ray at the triangle, for
    one whose plane holds the eye: rays from an eye inside it hit at t = 0, as the ray caster's do;
    depth is the hit's camera-space z."""
    depth_row = wp.vec3d(proj.to_camera[2, 0], proj.to_camera[2, 1], proj.to_camera[2, 2])
    for py in range(rect[1], rect[3] + 1):
        for col in range(rect[0] * spp, (rect[2] + 1) * spp):
            p = samples[py, col]
            d = camera_ray_direction(cam, p[0], p[1])
            hit, t, u, v = ray_triangle_intersection(cam.eye, d, p0, p1, p2)
            if hit:
                z = wp.float64(t) * wp.dot(depth_row, to_double(d))
                keep_nearest(out, py, col, visibility_entry(float(z), face), False)


@wp.func
def owns_boundary_float(a: wp.float64, b: wp.float64) -> bool:
    """owns_boundary for an edge function with float64 coefficients."""
    return a > wp.float64(0.0) or (a == wp.float64(0.0) and b > wp.float64(0.0))


@wp.func
def homogeneous_edge(n: wp.vec3d, proj: Projection) -> wp.vec3d:
    """(A, B, C) of the edge function A x + B y + C in pixels of the plane through the eye with
    normal n (camera coordinates): n . (a/z, b/z, 1) with a/z = x / half_width - 1, b/z = 1 - y / half_height."""
    return wp.vec3d(n[0] / proj.half_width, -n[1] / proj.half_height, n[2] - n[0] + n[1])


@wp.func
def homogeneous_coverage(e0: wp.vec3d, e1: wp.vec3d, e2: wp.vec3d, own0: bool, own1: bool, own2: bool,
                         x: wp.float64, y: wp.float64):
    """(covered, sum of the edge functions) of the sample (x, y), the edge functions evaluated
    directly: a sample exactly on an edge is covered if its triangle owns the edge."""
    f0 = e0[0] * x + e0[1] * y + e0[2]
    f1 = e1[0] * x + e1[1] * y + e1[2]
    f2 = e2[0] * x + e2[1] * y + e2[2]
    zero = wp.float64(0.0)
    covered = ((f0 > zero or (f0 == zero and own0)) and (f1 > zero or (f1 == zero and own1))
               and (f2 > zero or (f2 == zero and own2)))
    return covered, f0 + f1 + f2


@wp.func
def rasterize_homogeneous(face: int, c0: wp.vec3d, c1: wp.vec3d, c2: wp.vec3d, rect: wp.vec4i,
                          samples: wp.array2d(dtype=wp.vec2), spp: int, proj: Projection,
                          out: wp.array2d(dtype=wp.uint64)) -> bool:
    """Coverage of the samples of ``rect`` by a triangle that cannot be projected (it reaches
    behind the camera or beyond the guard band), from its camera-space vertices, without clipping
    (homogeneous rasterization, Olano and Greer 1997): a sample's ray (a/z, b/z, 1) crosses the
    triangle where it lies on the inner side of the three planes through the eye and an edge,
    n_i = c_j x c_k, and then at depth z = det / sum_i n_i . ray, det = c0 . (c1 x c2), the
    plane's distance term. Each edge function is evaluated directly in float64, so a neighbour
    sharing the edge, whose normal is exactly the negation, takes the opposite decision and the
    ownership rule settles samples exactly on it. Returns False, drawing nothing, for a triangle
    whose plane holds the eye (see trace_triangle)."""
    n0 = wp.cross(c1, c2)
    n1 = wp.cross(c2, c0)
    n2 = wp.cross(c0, c1)
    det = wp.dot(c0, n0)
    # the eye in the triangle's plane, to within the rounding of the camera coordinates
    if wp.abs(det) <= EYE_IN_PLANE_TOLERANCE * wp.length(c0) * wp.length(c1) * wp.length(c2):
        return False
    if det < wp.float64(0.0):
        n0 = -n0
        n1 = -n1
        n2 = -n2
        det = -det
    e0 = homogeneous_edge(n0, proj)
    e1 = homogeneous_edge(n1, proj)
    e2 = homogeneous_edge(n2, proj)
    own0 = owns_boundary_float(e0[0], e0[1])
    own1 = owns_boundary_float(e1[0], e1[1])
    own2 = owns_boundary_float(e2[0], e2[1])
    if spp == 1:
        # Pixel centres: each edge function is stepped along the row (g), whose rounding stays
        # within `slop` of the direct evaluation's: a sample farther than that inside every edge
        # is covered (its depth from g, as exact as the direct evaluation's up to that rounding),
        # one farther outside one is not, and only samples that close to an edge are decided by
        # the direct evaluation, which neighbours sharing the edge agree on.
        width = wp.float64(rect[2] - rect[0] + 1)
        x_far = wp.max(wp.abs(wp.float64(rect[0])), wp.abs(wp.float64(rect[2]) + wp.float64(1.0)))
        y_far = wp.max(wp.abs(wp.float64(rect[1])), wp.abs(wp.float64(rect[3]) + wp.float64(1.0)))
        slop = (STEPPED_EDGE_ROUNDING * (width + wp.float64(8.0))
                * wp.vec3d(wp.abs(e0[0]) * x_far + wp.abs(e0[1]) * y_far + wp.abs(e0[2]),
                           wp.abs(e1[0]) * x_far + wp.abs(e1[1]) * y_far + wp.abs(e1[2]),
                           wp.abs(e2[0]) * x_far + wp.abs(e2[1]) * y_far + wp.abs(e2[2])))
        for py in range(rect[1], rect[3] + 1):
            y = wp.float64(py) + wp.float64(0.5)
            x = wp.float64(rect[0]) + wp.float64(0.5)
            g0 = e0[0] * x + e0[1] * y + e0[2]
            g1 = e1[0] * x + e1[1] * y + e1[2]
            g2 = e2[0] * x + e2[1] * y + e2[2]
            for px in range(rect[0], rect[2] + 1):
                if g0 > slop[0] and g1 > slop[1] and g2 > slop[2]:
                    keep_nearest(out, py, px, visibility_entry(float(det / (g0 + g1 + g2)), face), False)
                elif g0 >= -slop[0] and g1 >= -slop[1] and g2 >= -slop[2]:
                    covered, weights = homogeneous_coverage(e0, e1, e2, own0, own1, own2,
                                                            wp.float64(px) + wp.float64(0.5), y)
                    if covered:
                        keep_nearest(out, py, px, visibility_entry(float(det / weights), face), False)
                g0 = g0 + e0[0]
                g1 = g1 + e1[0]
                g2 = g2 + e2[0]
        return True
    for py in range(rect[1], rect[3] + 1):
        for col in range(rect[0] * spp, (rect[2] + 1) * spp):
            p = samples[py, col]
            covered, weights = homogeneous_coverage(e0, e1, e2, own0, own1, own2, wp.float64(p[0]), wp.float64(p[1]))
            if covered:
                keep_nearest(out, py, col, visibility_entry(float(det / weights), face), False)
    return True


# ---------------------------------------------------------------------- binning
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
def count_triangle(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), vertex_count: int,
                   screen: wp.array(dtype=wp.vec2i), depth_weights: wp.array(dtype=wp.float64), proj: Projection,
                   samples: wp.array2d(dtype=wp.vec2), spp: int, face: int, owner: int, tiles_x: int,
                   cull_back_faces: wp.array(dtype=wp.uint8), first: int, binned_count: wp.array(dtype=wp.int32),
                   binned_face: wp.array(dtype=wp.int32), binned_rect: wp.array(dtype=wp.vec4i),
                   tile_counts: wp.array2d(dtype=wp.int32), bad_indices: wp.array(dtype=wp.int32),
                   out: wp.array2d(dtype=wp.uint64)):
    c = triangle_corners(indices, face)
    if not are_valid_indices(c, vertex_count):
        bad_indices[owner] = 1
        return
    q0 = screen[c[0]]
    q1 = screen[c[1]]
    q2 = screen[c[2]]
    r = empty_rect()
    if is_projected(q0) and is_projected(q1) and is_projected(q2):
        # the rectangle first: most triangles of a dense mesh hold no sample and end here
        r = projected_rect(q0, q1, q2, spp, proj.width, proj.height)
        if r[0] > r[2]:
            return
        area = signed_area(q0, q1, q2)
        if area == wp.int64(0):
            return
        if cull_back_faces.shape[0] > 0:
            if cull_back_faces[face] != wp.uint8(0) and area * proj.back_facing_sign > wp.int64(0):
                return
        if rect_pixels(r) <= SMALL_TRIANGLE_PIXELS:
            # drawn now, with atomic minima, rather than binned and read again: most triangles of a
            # dense mesh are this small, and a third of them (a million-triangle model at 1024²)
            # span a single pixel
            if spp == 1 and rect_pixels(r) == 1:
                covered, depth = pixel_centre_depth(q0, q1, q2, depth_weights[c[0]], depth_weights[c[1]],
                                                    depth_weights[c[2]], r[0], r[1], proj.orthographic)
                if covered:
                    keep_nearest(out, r[1], r[0], visibility_entry(depth, face), True)
                return
            rasterize_triangle(face, q0, q1, q2, depth_weights[c[0]], depth_weights[c[1]], depth_weights[c[2]], r,
                               samples, spp, proj.orthographic, out, True)
            return
    else:
        if proj.orthographic != 0:
            return
        if q0[0] == BEHIND_CAMERA and q1[0] == BEHIND_CAMERA and q2[0] == BEHIND_CAMERA:
            return
        r = clipped_rect(proj, positions[c[0]], positions[c[1]], positions[c[2]])
        if r[0] > r[2]:
            return
    # the owner is the launch drawing this triangle: its list and counts need no atomics
    slot = first + binned_count[owner]
    binned_count[owner] = binned_count[owner] + 1
    binned_face[slot] = face
    binned_rect[slot] = r
    for ty in range(r[1] / TILE_SIZE, r[3] / TILE_SIZE + 1):
        for tx in range(r[0] / TILE_SIZE, r[2] / TILE_SIZE + 1):
            tile = ty * tiles_x + tx
            tile_counts[owner, tile] = tile_counts[owner, tile] + 1


@wp.func
def bin_offsets(tile_counts: wp.array2d(dtype=wp.int32), cursors: wp.array2d(dtype=wp.int32),
                bin_start: wp.array(dtype=wp.int32), total: wp.array(dtype=wp.int64),
                busy_tiles: wp.array(dtype=wp.int32)) -> int:
    """Run by one thread: bins are contiguous per tile, each owner's part (the triangles a launch
    binned) after the previous owners'. bin_start[tile] is where a tile's bin starts,
    cursors[owner, tile] where an owner's part of it does, total[0] the length of all bins (exact
    in int64; offsets are meaningful only if it is below 2^31). Returns how many tiles have a
    nonempty bin, listed at the start of busy_tiles in row-major order."""
    tiles = tile_counts.shape[1]
    end = wp.int64(0)
    for tile in range(tiles):
        bin_start[tile] = int(end)
        for owner in range(tile_counts.shape[0]):
            cursors[owner, tile] = int(end)
            end = end + wp.int64(tile_counts[owner, tile])
    bin_start[tiles] = int(end)
    total[0] = end
    busy = int(0)
    for tile in range(tiles):
        if bin_start[tile + 1] > bin_start[tile]:
            busy_tiles[busy] = tile
            busy += 1
    return busy


@wp.func
def bin_triangle(binned_rect: wp.array(dtype=wp.vec4i), slot: int, owner: int, tiles_x: int,
                 cursors: wp.array2d(dtype=wp.int32), bins: wp.array(dtype=wp.int32)):
    r = binned_rect[slot]
    for ty in range(r[1] / TILE_SIZE, r[3] / TILE_SIZE + 1):
        for tx in range(r[0] / TILE_SIZE, r[2] / TILE_SIZE + 1):
            tile = ty * tiles_x + tx
            at = cursors[owner, tile]
            bins[at] = slot
            cursors[owner, tile] = at + 1


@wp.func
def rasterize_tile(tile: int, positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32),
                   screen: wp.array(dtype=wp.vec2i), depth_weights: wp.array(dtype=wp.float64),
                   binned_face: wp.array(dtype=wp.int32), binned_rect: wp.array(dtype=wp.vec4i),
                   bin_start: wp.array(dtype=wp.int32), bins: wp.array(dtype=wp.int32),
                   samples: wp.array2d(dtype=wp.vec2), spp: int, cam: CameraData, proj: Projection,
                   tiles_x: int, out: wp.array2d(dtype=wp.uint64)):
    """Every triangle of a tile's bin drawn into it, by the one thread that owns it (no atomics)."""
    tile_x0 = (tile % tiles_x) * TILE_SIZE
    tile_y0 = (tile / tiles_x) * TILE_SIZE
    tile_x1 = wp.min(tile_x0 + TILE_SIZE, proj.width) - 1
    tile_y1 = wp.min(tile_y0 + TILE_SIZE, proj.height) - 1
    if bin_start[tile + 1] > bin_start[tile]:
        for row in range(tile_y0, tile_y1 + 1):
            prefetch_row_span(out, row, tile_x0 * spp, (tile_x1 - tile_x0 + 1) * spp)
    for k in range(bin_start[tile], bin_start[tile + 1]):
        slot = bins[k]
        face = binned_face[slot]
        r = binned_rect[slot]
        rect = wp.vec4i(wp.max(r[0], tile_x0), wp.max(r[1], tile_y0), wp.min(r[2], tile_x1), wp.min(r[3], tile_y1))
        c = triangle_corners(indices, face)
        q0 = screen[c[0]]
        q1 = screen[c[1]]
        q2 = screen[c[2]]
        if is_projected(q0) and is_projected(q1) and is_projected(q2):
            rasterize_triangle(face, q0, q1, q2, depth_weights[c[0]], depth_weights[c[1]], depth_weights[c[2]], rect,
                               samples, spp, proj.orthographic, out, False)
        else:
            p0 = positions[c[0]]
            p1 = positions[c[1]]
            p2 = positions[c[2]]
            if not rasterize_homogeneous(face, camera_coordinates(proj, p0), camera_coordinates(proj, p1),
                                         camera_coordinates(proj, p2), rect, samples, spp, proj, out):
                trace_triangle(face, p0, p1, p2, rect, samples, spp, cam, proj, out)




# ---------------------------------------------------------------------- the pipeline
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
# Spins (pause instructions) of a waiting launch between yields of its core (see all_arrived).
SPINS_BEFORE_YIELD = wp.constant(1024)
# Stages a launch may start at.
START = wp.constant(0)
FILL = wp.constant(1)


@wp.func_native("""
    __atomic_add_fetch(sync.data + slot, amount, __ATOMIC_ACQ_REL);
    int spins = 0;
    while (__atomic_load_n(sync.data + slot, __ATOMIC_ACQUIRE) < total) {
        if (__atomic_load_n(sync.data + aborted, __ATOMIC_ACQUIRE) != 0) return false;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
        __builtin_arm_yield();
#endif
        if (++spins < spins_before_yield || os_yield == 0) continue;
        spins = 0;
        ((wp::int32 (*)(void))os_yield)();
    }
    return true;
    """)
def all_done(sync: wp.array(dtype=wp.int32), slot: int, amount: int, total: int, aborted: int,
             spins_before_yield: int, os_yield: wp.uint64) -> bool:
    """A barrier of the call's launches, which run side by side on a thread pool: adds ``amount``
    (the work this launch did) to counter ``slot`` and spins until it reaches ``total`` (what each
    wrote before is then visible to all); False if the call was aborted meanwhile. After every
    spins_before_yield spins (tens of microseconds) it calls ``os_yield`` (the address of the C
    library's sched_yield; 0: never), lest a launch waiting for another that is not running (more
    threads than cores, or cores taken by other processes) hold the core that one needs. Spinning
    rather than returning to Python between stages: a Python barrier's wake-ups, and the GIL
    passed back and forth for each stage's launch, cost ~1.5 ms of a call on two threads
    (development measurement, nothing to draw at 512²: 2.6-3.6 ms on two threads against
    1.1-2.5 on one)."""
    ...


@wp.func_native("""
    int spins = 0;
    while (__atomic_load_n(released.data, __ATOMIC_ACQUIRE) < epoch) {
        if (__atomic_load_n(sync.data + aborted, __ATOMIC_ACQUIRE) != 0) return;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
        __builtin_arm_yield();
#endif
        if (++spins < spins_before_yield || os_yield == 0) continue;
        spins = 0;
        ((wp::int32 (*)(void))os_yield)();
    }
    """)
def wait_for_release(released: wp.array(dtype=wp.int64), epoch: wp.int64, sync: wp.array(dtype=wp.int32),
                     aborted: int, spins_before_yield: int, os_yield: wp.uint64):
    """Spins as all_done does until released[0] >= epoch, which the caller's Python sets once
    launch 0 has returned to it: a pool thread's launch returning with launch 0's took the GIL
    first about half the time, and the caller then waited for the pool thread's way back to its
    queue (2 threads, 1024²: ~0.1 ms a call; development). released[0] only grows, so that a
    launch that sees it late, after the caller's next call began, still stops."""
    ...


@wp.func
def all_arrived(sync: wp.array(dtype=wp.int32), slot: int, launches: int, aborted: int, spins_before_yield: int,
                os_yield: wp.uint64) -> bool:
    """all_done of one unit per launch: a barrier that every launch must reach."""
    return all_done(sync, slot, 1, launches, aborted, spins_before_yield, os_yield)


@wp.func
def share(n: int, parts: int, minimum: int) -> int:
    """The size of each of ``parts`` contiguous shares of n items, at least ``minimum``."""
    return wp.max(minimum, (n + parts - 1) / parts)


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
# costs more than the tests save. Development measurements, 2 threads, in-process A/B: an
# 82k-triangle icosphere at 1024² (13 samples per triangle) 18% faster in two passes, at 2048²
# (51) 5% slower; the Stanford bunny (69k) at 1024² 4% faster.
SAMPLES_PER_TRIANGLE = wp.constant(16)
FACING_SHARE = wp.constant(8)
# Clusters sampled to estimate how many face away from the eye (occlusion_pass_pays).
FACING_SAMPLE = wp.constant(256)


@wp.func
def occlusion_pass_pays(proj: Projection, cluster_lower: wp.array(dtype=wp.vec3),
                        cluster_upper: wp.array(dtype=wp.vec3), cluster_axis: wp.array(dtype=wp.vec3), triangles: int,
                        samples_count: wp.int64) -> bool:
    """Whether drawing in two passes, the clusters facing away tested for occlusion, may pay:
    whether the triangles are small for the samples and enough clusters face away (as faces_eye
    tells them apart, estimated from FACING_SAMPLE clusters evenly spread); see
    SAMPLES_PER_TRIANGLE. Not for a height field seen from above, nor a mesh of few triangles
    for the samples."""
    if wp.int64(triangles) * wp.int64(SAMPLES_PER_TRIANGLE) < samples_count:
        return False
    clusters = cluster_lower.shape[0]
    sampled = int(0)
    away = int(0)
    for cluster in range(0, clusters, wp.max(1, clusters / FACING_SAMPLE)):
        sampled += 1
        if not faces_eye(proj, cluster_lower[cluster], cluster_upper[cluster], cluster_axis[cluster]):
            away += 1
    return away * FACING_SHARE >= sampled


@wp.func
def count_batch(draw: int, batch: int, owner: int, positions: wp.array(dtype=wp.vec3),
                indices: wp.array(dtype=wp.int32), vertex_count: int, screen: wp.array(dtype=wp.vec2i),
                depth_weights: wp.array(dtype=wp.float64), proj: Projection, samples: wp.array2d(dtype=wp.vec2),
                spp: int, batch_size: int, triangles: int, tiles_x: int, cull_back_faces: wp.array(dtype=wp.uint8),
                binned_count: wp.array(dtype=wp.int32), binned_face: wp.array(dtype=wp.int32),
                binned_rect: wp.array(dtype=wp.vec4i), tile_counts: wp.array2d(dtype=wp.int32),
                bad_indices: wp.array(dtype=wp.int32), cluster_lower: wp.array(dtype=wp.vec3),
                cluster_upper: wp.array(dtype=wp.vec3), cluster_axis: wp.array(dtype=wp.vec3),
                cluster_spread: wp.array(dtype=float), cluster_rect: wp.array(dtype=wp.vec4i),
                cluster_nearest: wp.array(dtype=wp.float64), out: wp.array2d(dtype=wp.uint64)) -> wp.vec4i:
    """count_triangle for the triangles of ``batch`` that pass ``draw`` (DRAW_ALL, ...), cluster
    by cluster, the binned ones listed as launch ``owner``'s; DRAW_FIRST records the deferred
    clusters' rectangles and nearest depths. Returns how many clusters were off screen, deferred,
    occluded and culled as facing away."""
    end = wp.min((batch + 1) * batch_size, triangles)
    first_cluster = batch * batch_size / CLUSTER_SIZE
    end_cluster = (end + CLUSTER_SIZE - 1) / CLUSTER_SIZE
    off_screen = int(0)
    facing_away = int(0)
    deferred = int(0)
    occluded = int(0)
    # the clusters' fates first, in a loop of their own, which keeps the drawing loop below as
    # lean as without clusters (development measurement: tests inlined into it cost the terrain
    # ~100 ns per cluster)
    if draw == DRAW_CULLED or draw == DRAW_FIRST:
        for cluster in range(first_cluster, end_cluster):
            fate = NOT_DEFERRED
            lo = cluster_lower[cluster]
            hi = cluster_upper[cluster]
            # cheap tests first: most clusters are drawn or dropped on them
            if outside_view(proj, lo, hi):
                off_screen += 1
                fate = SKIPPED
            elif not faces_eye(proj, lo, hi, cluster_axis[cluster]):
                # (nested: Warp evaluates both sides of ``and``)
                if cull_back_faces.shape[0] > 0:
                    if faces_away(proj, lo, hi, cluster_axis[cluster], cluster_spread[cluster]):
                        if all_flagged(cull_back_faces, cluster * CLUSTER_SIZE,
                                       wp.min((cluster + 1) * CLUSTER_SIZE, end)):
                            facing_away += 1
                            fate = SKIPPED
                if fate == NOT_DEFERRED and draw == DRAW_FIRST:
                    rect, nearest = cluster_view(proj, lo, hi, spp)
                    if rect[0] > rect[2]:
                        off_screen += 1
                        fate = SKIPPED
                    elif nearest > wp.float64(0.0) and rect_pixels(rect) * spp <= MAX_TESTED_SAMPLES:
                        cluster_rect[cluster] = rect
                        fate = nearest
                        deferred += 1
            cluster_nearest[cluster] = fate
    if draw == DRAW_UNOCCLUDED:
        for cluster in range(first_cluster, end_cluster):
            if cluster_nearest[cluster] > wp.float64(0.0):
                # entries order by depth first and positive float32 depths by their bits: one
                # below this bound has a depth under the float32 nearest rounds to, so at most
                # the float32 below it, which lies below nearest
                bound = visibility_entry(float(cluster_nearest[cluster]), 0)
                if is_occluded(out, cluster_rect[cluster], spp, bound):
                    cluster_nearest[cluster] = SKIPPED
                    occluded += 1
    for cluster in range(first_cluster, end_cluster):
        drawn = True
        if draw == DRAW_CULLED or draw == DRAW_FIRST:
            drawn = cluster_nearest[cluster] == NOT_DEFERRED
        elif draw != DRAW_ALL:
            drawn = cluster_nearest[cluster] > wp.float64(0.0)
        if drawn:
            base = cluster * CLUSTER_SIZE
            busy = triangles_to_count(indices, screen, vertex_count, base, wp.min(base + CLUSTER_SIZE, end), spp,
                                      proj.width, proj.height)
            while busy != wp.uint64(0):
                face = base + lowest_set_bit(busy)
                busy = busy & (busy - wp.uint64(1))
                count_triangle(positions, indices, vertex_count, screen, depth_weights, proj, samples, spp, face,
                               owner, tiles_x, cull_back_faces, owner * triangles, binned_count, binned_face,
                               binned_rect, tile_counts, bad_indices, out)
    return wp.vec4i(off_screen, deferred, occluded, facing_away)


@wp.kernel
def visibility_pipeline(launch: int, launches: int, first_stage: int, stop_after_binning: int, os_yield: wp.uint64,
                        positions: wp.array(dtype=wp.vec3),
                        indices: wp.array(dtype=wp.int32), vertex_count: int, screen: wp.array(dtype=wp.vec2i),
                        depth_weights: wp.array(dtype=wp.float64), cam: CameraData, orthographic: int,
                        samples: wp.array2d(dtype=wp.vec2), spp: int, min_vertex_share: int, batch_size: int,
                        batch_stride: int, triangles: int, tiles_x: int,
                        cull_back_faces: wp.array(dtype=wp.uint8), binned_count: wp.array(dtype=wp.int32),
                        binned_face: wp.array(dtype=wp.int32), binned_rect: wp.array(dtype=wp.vec4i),
                        tile_counts: wp.array2d(dtype=wp.int32), bad_indices: wp.array(dtype=wp.int32),
                        cursors: wp.array2d(dtype=wp.int32), bin_start: wp.array(dtype=wp.int32),
                        bin_total: wp.array(dtype=wp.int64), bins: wp.array(dtype=wp.int32),
                        busy_tiles: wp.array(dtype=wp.int32), cluster_lower: wp.array(dtype=wp.vec3),
                        cluster_upper: wp.array(dtype=wp.vec3), cluster_axis: wp.array(dtype=wp.vec3),
                        cluster_spread: wp.array(dtype=float),
                        cluster_rect: wp.array(dtype=wp.vec4i), cluster_nearest: wp.array(dtype=wp.float64),
                        sync: wp.array(dtype=wp.int32), batch_ranges: wp.array(dtype=wp.int64),
                        released: wp.array(dtype=wp.int64), epoch: wp.int64,
                        out: wp.array2d(dtype=wp.uint64)):
    """The whole visibility buffer: launched with one index on each of ``launches`` threads
    (``launch`` = 0, 1, ...) side by side, which meet at spinning barriers (all_arrived) between
    stages.

    From START: the buffer's rows cleared and the vertices projected, in pieces taken from a queue
    (launch 0 first decides on the occlusion pass and sets out the batch ranges), until all are done
    (all_done); then batches of batch_size triangles: launch k owns the range of batch_stride
    batches from k batch_stride (in ``batch_ranges``: a set of ranges per pass, one for the tiles)
    and takes them in order, then takes what is left of the others' ranges from their ends
    (take_next_from_ranges), so that each draws a region of the mesh of its own, on screen mostly
    apart from the others', and finds the buffer's lines there in its own core's cache (the batches
    of one shared queue had each launch draw all over the mesh: 2 threads, 1024², development A/B,
    icosphere 3.8-3.9 -> 3.5 ms, bunny 4.2-4.8 -> 3.9-4.0, happy Buddha 17.4-17.9 -> 16.2-16.4):
    small triangles drawn into the buffer at once (atomically, as another launch may draw the same
    sample), the others that may cover a sample listed by the launch that drew them (their owner)
    with their screen rectangles at binned_face and binned_rect [owner triangles, +
    binned_count[owner]) and counted per tile they touch in row ``owner`` of tile_counts (no
    atomics), or the owner's bad_indices set for a triangle with an index out of range (it is not
    read). Batches are small (a few clusters) so that launches finish a pass together; the
    binning, owned per launch rather than per batch, does not grow with their number. With
    clusters (cluster_lower... nonempty) the batches are drawn cluster by cluster (count_batch),
    but for the clusters off screen or facing away from the eye where every triangle is flagged
    for culling; where occlusion_pass_pays (launch 0 decides it, in ``sync``), in two passes:
    first those facing the eye or not testable, the others deferred (their rectangle and nearest
    depth kept in cluster_rect and cluster_nearest); then, once every launch has drawn its
    first-pass batches, the deferred clusters that what the buffer holds by then does not hide
    (is_occluded), their batches taken from the second pass's ranges. Launch 0 then lays out the
    bins (bin_offsets) and records the OUTCOME in ``sync``; all stop unless it is BINNED (or if
    stop_after_binning, to time the parts apart). From FILL: each listed triangle's slot appended
    to the bin of every tile its rectangle touches, owner by owner from another queue; then the
    tiles with a nonempty bin (busy_tiles, in row-major order), a band of them per launch taken
    as the batches are, each drawn by the launch that took it alone (rasterize_tile). Every queue
    and range hands out work to whichever launch asks first, so one with cheaper work (culled
    back faces, triangles off screen) takes more. The projection is cam's (camera_projection,
    parallel if ``orthographic``); a camera without usable axes draws nothing, its OUTCOME
    BAD_CAMERA. Launch 0 returns only once every launch is done (the FINISHED count), so that the
    buffer is complete when it has, the others once released[0] has reached ``epoch`` too
    (wait_for_release); a call that stops after binning, only once every launch has left the
    barrier before it (the STOPPED_AFTER_BINNING count), as the caller may zero ``sync`` for its
    next call at once: a launch still waiting there would never see its count reached. ``sync``
    must be zeroed before a call (and its FILL barrier, queues and outcome before resuming
    there); ``os_yield`` is all_arrived's.
    """
    # each launch derives the same projection (computing it costs less than packing it in Python)
    proj = camera_projection(cam, orthographic)
    if not has_usable_axes(cam):
        if launch == 0:
            sync[OUTCOME] = BAD_CAMERA
        return
    if first_stage == START:
        samples_count = wp.int64(out.shape[0]) * wp.int64(out.shape[1])
        done = int(0)
        if launch == 0:
            # one unit of the stage's work, done before launch 0 takes any other
            if cluster_lower.shape[0] > 0:
                if occlusion_pass_pays(proj, cluster_lower, cluster_upper, cluster_axis, triangles, samples_count):
                    sync[OCCLUSION_PASS] = 1
            batches = (triangles + batch_size - 1) / batch_size
            for k in range(2 * launches):  # each pass's batch ranges, one per launch
                range_owner = k % launches
                reset_range(batch_ranges, k, range_owner * batch_stride,
                            wp.min((range_owner + 1) * batch_stride, batches))
            done = 1
        # the buffer's rows cleared and the vertices projected in pieces taken from a queue: a
        # launch that starts late (a pool thread's wake-up) finds its share done by the others
        pieces = launches * START_PIECES_PER_LAUNCH
        rows = share(proj.height, pieces, 1)
        row_pieces = (proj.height + rows - 1) / rows
        vertices = share(vertex_count, pieces, min_vertex_share)
        vertex_pieces = (vertex_count + vertices - 1) / vertices
        piece = take_next_item_from(sync, QUEUE_START)
        while piece < row_pieces + vertex_pieces:
            if piece < row_pieces:
                for row in range(piece * rows, wp.min((piece + 1) * rows, proj.height)):
                    clear_row_span(out, row, 0, out.shape[1])
            else:
                first = (piece - row_pieces) * vertices
                project_vertices(positions, proj.to_camera, proj.eye, proj.half_width, proj.half_height,
                                 proj.orthographic, first, wp.min(first + vertices, vertex_count), screen,
                                 depth_weights)
            done += 1
            piece = take_next_item_from(sync, QUEUE_START)
        # small triangles are drawn into the cleared buffer from projected vertices
        if not all_done(sync, BARRIER_PROJECTED, done, row_pieces + vertex_pieces + 1, ABORTED, SPINS_BEFORE_YIELD,
                        os_yield):
            return
        passes = int(1)
        draw = DRAW_ALL
        if cluster_lower.shape[0] > 0:
            draw = DRAW_CULLED
            if sync[OCCLUSION_PASS] != 0:
                passes = 2
                draw = DRAW_FIRST
        tally = wp.vec4i(0)
        for k in range(passes):
            if k == 1:
                # the clusters facing away are tested against what those facing the eye drew
                if not all_arrived(sync, BARRIER_DRAWN_FIRST, launches, ABORTED, SPINS_BEFORE_YIELD, os_yield):
                    return
                draw = DRAW_UNOCCLUDED
            # this launch's own range first, from its start; then the others', from their ends
            # (the owner has a name of its own here and below: reusing `owner`, a for-loop variable
            # elsewhere in this kernel, made these while loops spin forever on warp 1.19; cf.
            # NVIDIA/warp#1534, a for-loop variable's name reused in a while loop)
            batch, batch_owner = take_next_from_ranges(batch_ranges, k * launches, launch, launches, launch)
            while batch >= 0:
                tally = tally + count_batch(draw, batch, launch, positions, indices, vertex_count, screen,
                                            depth_weights, proj, samples, spp, batch_size, triangles, tiles_x,
                                            cull_back_faces, binned_count, binned_face, binned_rect, tile_counts,
                                            bad_indices, cluster_lower, cluster_upper, cluster_axis,
                                            cluster_spread, cluster_rect, cluster_nearest, out)
                batch, batch_owner = take_next_from_ranges(batch_ranges, k * launches, launch, launches,
                                                           batch_owner)
        if draw != DRAW_ALL:
            add_atomically(sync, CLUSTERS_OFF_SCREEN, tally[0])
            add_atomically(sync, CLUSTERS_DEFERRED, tally[1])
            add_atomically(sync, CLUSTERS_OCCLUDED, tally[2])
            add_atomically(sync, CLUSTERS_FACING_AWAY, tally[3])
        if not all_arrived(sync, BARRIER_COUNTED, launches, ABORTED, SPINS_BEFORE_YIELD, os_yield):
            return
        if launch == 0:
            outcome = BINNED
            for owner in range(bad_indices.shape[0]):
                if bad_indices[owner] != 0:
                    outcome = BAD_INDEX
            if outcome == BINNED:
                busy = bin_offsets(tile_counts, cursors, bin_start, bin_total, busy_tiles)
                share = (busy + launches - 1) / launches
                for band in range(launches):  # the tiles' ranges, a band of the image each
                    reset_range(batch_ranges, 2 * launches + band, wp.min(band * share, busy),
                                wp.min((band + 1) * share, busy))
                if bin_total[0] > wp.int64(bins.shape[0]):
                    outcome = BINS_TOO_SMALL
            sync[OUTCOME] = outcome
        if not all_arrived(sync, BARRIER_OFFSETS, launches, ABORTED, SPINS_BEFORE_YIELD, os_yield):
            return
        if sync[OUTCOME] != BINNED or stop_after_binning != 0:
            all_done(sync, STOPPED_AFTER_BINNING, 1, wp.where(launch == 0, launches, 0), ABORTED, SPINS_BEFORE_YIELD,
                     os_yield)
            return
    owner = take_next_item_from(sync, QUEUE_FILL)
    while owner < binned_count.shape[0]:
        first = owner * triangles
        for slot in range(first, first + binned_count[owner]):
            bin_triangle(binned_rect, slot, owner, tiles_x, cursors, bins)
        owner = take_next_item_from(sync, QUEUE_FILL)
    if not all_arrived(sync, BARRIER_FILLED, launches, ABORTED, SPINS_BEFORE_YIELD, os_yield):
        return
    # only tiles with something to draw are handed out: taking one from a queue shared by the
    # launches, its counter fetched from the other core's cache, cost more than an empty tile
    # (2 threads: ~60 us of the 1024 tiles' ~70 at 1024², where dense meshes bin almost nothing;
    # development); each launch draws its own band of them first, then takes the others' from
    # their ends, far from where their owners draw
    listed, tile_owner = take_next_from_ranges(batch_ranges, 2 * launches, launch, launches, launch)
    while listed >= 0:
        rasterize_tile(busy_tiles[listed], positions, indices, screen, depth_weights, binned_face, binned_rect,
                       bin_start, bins, samples, spp, cam, proj, tiles_x, out)
        listed, tile_owner = take_next_from_ranges(batch_ranges, 2 * launches, launch, launches, tile_owner)
    # launch 0 returns once every launch is done drawing, so that the caller need not wait for the
    # pool threads' return to Python and their wake-up of it (~0.1 ms a call, development); the
    # launches that stop earlier all stop at the same stage, having drawn all they draw
    all_done(sync, FINISHED, 1, wp.where(launch == 0, launches, 0), ABORTED, SPINS_BEFORE_YIELD, os_yield)
    if launch != 0:
        wait_for_release(released, epoch, sync, ABORTED, SPINS_BEFORE_YIELD, os_yield)
