"""Coverage: the samples of a screen rectangle that a triangle covers, and their depth, kept in the
visibility buffer where nearer. A projected triangle is decided in exact int64 arithmetic on its
vertices and the samples snapped to 1/4096 pixel, with a tie-breaking rule on edges, so a sample on
an edge shared by two triangles is covered exactly once (rasterize_triangle, pixel_centre_depth); a
triangle that reaches behind the camera or outside the guard band is rasterized homogeneously in
float64 (rasterize_homogeneous), and one whose plane holds the eye by casting each sample's ray
(trace_triangle)."""

import warp as wp

from .camera import CameraData, camera_ray_direction
from .projection import HALF_PIXEL, PIXEL, SUBPIXEL_SCALE, Projection
from .ray_triangle import ray_triangle_intersection
from .robust import to_double
from .visibility_buffer import keep_nearest, visibility_entry

wp.set_module_options({"enable_backward": False})

# Bound, relative to the magnitude of its terms and per step, on how far an edge function stepped
# along a row in float64 strays from its direct evaluation (a few units of rounding, 1.1e-16, per
# addition), with room to spare.
STEPPED_EDGE_ROUNDING = wp.constant(wp.float64(1.0e-15))
# Rows at least this wide solve for their covered run of pixels before stepping along it: the
# solve (three int64 divisions) pays off only where it skips many uncovered pixels; on narrow
# rows, which dense meshes' small triangles mostly have, it costs more than the tests it saves.
SPAN_MIN_WIDTH = wp.constant(16)
# Relative size of c0 . (c1 x c2), for camera-space triangle vertices, below which the eye counts as
# lying in the triangle's plane: far above the float64 rounding of camera coordinates (1e-16).
EYE_IN_PLANE_TOLERANCE = wp.constant(wp.float64(1.0e-9))


@wp.func
def snap(x: float) -> wp.int64:
    """A sample coordinate (>= 0) in fixed point."""
    return wp.int64(wp.float64(x) * SUBPIXEL_SCALE + wp.float64(0.5))


@wp.func
def owns_boundary(a: wp.int64, b: wp.int64) -> bool:
    """Whether samples exactly on the edge with function a x + b y + c belong to its triangle.
    Equivalent to testing the sample moved by (eps, eps^2): the reversed edge (-a, -b), the same
    edge seen from the neighbouring triangle, gets the opposite answer, and at a shared vertex
    exactly one triangle of a fan wins."""
    return a > wp.int64(0) or (a == wp.int64(0) and b > wp.int64(0))


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
