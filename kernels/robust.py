"""Robust floating-point helpers: every epsilon, clamp and ray offset pbrwarp uses lives here."""

import warp as wp

wp.set_module_options({"enable_backward": False})

# Half a float32 ulp at 1.0: the unit roundoff of pbrt-v4's error analysis (MachineEpsilon).
UNIT_ROUNDOFF = wp.constant(5.960464477539063e-08)
# Factor on triangle_hit_error's bound. Grazing rays leaving random triangles (sizes 1e-3 to 1e3,
# up to 1e4 from the origin) re-hit their own triangle at factors of 1/16 to 1/64, never at 1/4
# (tests/test_stability_geometry.py, test_spawned_rays_never_hit_their_own_triangle); 1 keeps a
# 4x margin while leaking as little light as possible at contacts.
OFFSET_SAFETY = wp.constant(1.0)
# Smallest ray offset, for hits at the exact origin where every error bound is zero.
MIN_OFFSET = wp.constant(1.0e-30)
# Shading cosines below this are clamped (Filament clamps n.v to 1e-4 to avoid dividing by ~0).
MIN_COSINE = wp.constant(1.0e-4)
# Ray segments towards point and spot lights stop this fraction short of the light, so a light
# lying on a surface is not shadowed by that very surface.
SHADOW_RAY_SHORTENING = wp.constant(1.0e-5)
# Distance used as "infinitely far" for rays and directional lights.
RAY_FAR = wp.constant(1.0e30)
# Largest finite radiance handed to tone mapping (fp16 max): Inf and huge values map to white.
RADIANCE_MAX = wp.constant(65504.0)
# Largest finite float32. Irradiance and radiance are clamped to it: a 1e30 cd light next to a
# surface overflows float32, and an Inf irradiance times a zero BRDF channel would be NaN.
FLOAT32_MAX = wp.constant(3.4028234663852886e38)


@wp.func
def to_double(v: wp.vec3) -> wp.vec3d:
    """v in float64 (exactly: every float32 is a float64)."""
    return wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))


@wp.func
def gamma(n: float) -> float:
    """pbrt-v4's gamma(n) = n u / (1 - n u): the bound on n float32 roundings (Higham 2002)."""
    return n * UNIT_ROUNDOFF / (1.0 - n * UNIT_ROUNDOFF)


@wp.func
def safe_normalize(v: wp.vec3, fallback: wp.vec3) -> wp.vec3:
    """v / |v|, or ``fallback`` when v is zero or not finite (degenerate triangles, v = -l)."""
    length_sq = wp.dot(v, v)
    if length_sq > 1.0e-30 and length_sq < 1.0e30:
        return v / wp.sqrt(length_sq)
    return fallback


@wp.func
def abs_vec3(v: wp.vec3) -> wp.vec3:
    return wp.vec3(wp.abs(v[0]), wp.abs(v[1]), wp.abs(v[2]))


@wp.func
def triangle_hit_error(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> wp.vec3:
    """Error bound, the same in every axis, for a point on triangle (p0, p1, p2) used as a ray origin.

    pbrt-v4 bounds the rounding of p = b0 p0 + b1 p1 + b2 p2 by gamma(7) (|b0 p0| + |b1 p1| +
    |b2 p2|) per axis, and its own ray-triangle test rejects hits with t inside the test's error.
    Warp's test has no such check, and it works in a sheared space whose z axis is the ray
    direction, so its rounding mixes all axes and scales with the vertex magnitudes, not with the
    barycentric weights: a flat triangle at z = 0 has zero pbrt error in z yet reports t ~ 0
    self-hits for grazing rays. The bound used here is therefore gamma(7) times the largest
    component of |p0| + |p1| + |p2|, applied in every axis.
    """
    s = abs_vec3(p0) + abs_vec3(p1) + abs_vec3(p2)
    return wp.vec3(gamma(7.0) * wp.max(s[0], wp.max(s[1], s[2])))


@wp.func
def offset_ray_origin(p: wp.vec3, p_error: wp.vec3, n: wp.vec3, w: wp.vec3) -> wp.vec3:
    """Move p off its surface along the geometric normal n, to the side w points to, far enough
    that rounding error cannot put it back on the surface (pbrt-v4 OffsetRayOrigin)."""
    d = OFFSET_SAFETY * wp.dot(abs_vec3(n), p_error) + MIN_OFFSET
    offset = n * d
    if wp.dot(w, n) < 0.0:
        offset = -offset
    return p + offset


@wp.func
def clamp_to_float32_max(v: wp.vec3) -> wp.vec3:
    """+Inf components become FLOAT32_MAX (NaN passes through, for pw.check to catch)."""
    return wp.vec3(wp.min(v[0], FLOAT32_MAX), wp.min(v[1], FLOAT32_MAX), wp.min(v[2], FLOAT32_MAX))


@wp.func
def finite_or_zero(v: wp.vec3) -> wp.vec3:
    """NaN components become 0 and values are clamped to [0, RADIANCE_MAX] (Inf becomes the max)."""
    out = wp.vec3(0.0)
    for i in range(3):
        x = v[i]
        if x == x:
            out[i] = wp.clamp(x, 0.0, RADIANCE_MAX)
    return out
