"""A pixel's footprint on a surface: uv derivatives from ray differentials.

The method of pbrt-v4 (Pharr, Jakob & Humphreys, Physically Based Rendering, 4th ed., section
10.1.1; src/pbrt/interaction.cpp, SurfaceInteraction::ComputeDifferentials): the rays through
the pixel's right and lower neighbours are intersected with the hit's tangent plane, giving
dp/dx and dp/dy; the uv derivatives are the least-squares solution of dp = dp/du du + dp/dv dv.
Every result is finite: degenerate UVs give zero derivatives (level 0), rays parallel to the
tangent plane (grazing views) the largest footprint (FOOTPRINT_LIMIT).
"""

import warp as wp

wp.set_module_options({"enable_backward": False})

# bound on |du/dx| etc. (uv units a pixel), as pbrt-v4 clamps them: far beyond any mip pyramid
FOOTPRINT_LIMIT = wp.constant(1.0e8)


@wp.func
def triangle_dp_duv(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, uv0: wp.vec2, uv1: wp.vec2, uv2: wp.vec2):
    """(dp/du, dp/dv) of the triangle's linear uv parametrization; zero vectors when its UVs are
    degenerate (zero area in uv) or the result is not finite."""
    duv02 = uv0 - uv2
    duv12 = uv1 - uv2
    dp02 = p0 - p2
    dp12 = p1 - p2
    det = duv02[0] * duv12[1] - duv02[1] * duv12[0]
    dpdu = wp.vec3(0.0)
    dpdv = wp.vec3(0.0)
    if wp.abs(det) > 1.0e-20:
        inv = 1.0 / det
        dpdu = (dp02 * duv12[1] - dp12 * duv02[1]) * inv
        dpdv = (dp12 * duv02[0] - dp02 * duv12[0]) * inv
        if not (wp.length_sq(dpdu) + wp.length_sq(dpdv) < 1.0e30):
            dpdu = wp.vec3(0.0)
            dpdv = wp.vec3(0.0)
    return dpdu, dpdv


@wp.func
def tangent_plane_offset(p: wp.vec3, n: wp.vec3, origin: wp.vec3, direction: wp.vec3) -> wp.vec3:
    """Where the ray origin + t direction meets the plane through p with normal n, minus p; a ray
    parallel to the plane, or meeting it behind its origin, counts as FOOTPRINT_LIMIT away."""
    denom = wp.dot(n, direction)
    t = wp.dot(n, p - origin) / denom if wp.abs(denom) > 1.0e-12 else -1.0
    if not (t >= 0.0 and t < 1.0e30):
        return wp.vec3(FOOTPRINT_LIMIT, 0.0, 0.0)
    return origin + direction * t - p


@wp.func
def uv_derivative(dpdu: wp.vec3, dpdv: wp.vec3, dp: wp.vec3) -> wp.vec2:
    """(du, dv) minimizing |dp/du du + dp/dv dv - dp|, each clamped to +-FOOTPRINT_LIMIT; zero
    when dp/du and dp/dv are parallel or zero (the normal equations are singular)."""
    a00 = wp.dot(dpdu, dpdu)
    a01 = wp.dot(dpdu, dpdv)
    a11 = wp.dot(dpdv, dpdv)
    det = a00 * a11 - a01 * a01
    # relative test: the normal equations are singular up to rounding
    if not (det > 1.0e-12 * a00 * a11) or not (det < 1.0e30):
        return wp.vec2(0.0)
    b0 = wp.dot(dpdu, dp)
    b1 = wp.dot(dpdv, dp)
    du = (a11 * b0 - a01 * b1) / det
    dv = (a00 * b1 - a01 * b0) / det
    if not (wp.abs(du) + wp.abs(dv) < 1.0e30):  # NaN from an infinite dp
        return wp.vec2(FOOTPRINT_LIMIT, FOOTPRINT_LIMIT)
    return wp.vec2(wp.clamp(du, -FOOTPRINT_LIMIT, FOOTPRINT_LIMIT), wp.clamp(dv, -FOOTPRINT_LIMIT, FOOTPRINT_LIMIT))
