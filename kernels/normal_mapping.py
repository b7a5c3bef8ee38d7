"""Tangent-space normal mapping as glTF specifies it (MikkTSpace frame, +Y green channel)."""

import warp as wp

from .robust import safe_normalize

wp.set_module_options({"enable_backward": False})


@wp.func
def orthonormal_tangent(n: wp.vec3, t: wp.vec3) -> wp.vec3:
    """t made perpendicular to the unit normal n (Gram-Schmidt) after interpolation; any
    perpendicular when t is degenerate or parallel to n."""
    fallback = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(n[0]) > 0.9:
        fallback = wp.vec3(0.0, 1.0, 0.0)
    return safe_normalize(t - n * wp.dot(n, t), wp.normalize(wp.cross(n, fallback)))


@wp.func
def perturb_normal(n: wp.vec3, tangent: wp.vec4, texel: wp.vec4, scale: float) -> wp.vec3:
    """The shading normal from a normal-map texel: n' = normalize(T x + B y + N z) with
    (x, y) = (2 texel.rg - 1) scale, z = 2 texel.b - 1 and B = cross(N, T) w (glTF 2.0, 3.9.3)."""
    t = orthonormal_tangent(n, wp.vec3(tangent[0], tangent[1], tangent[2]))
    handedness = 1.0
    if tangent[3] < 0.0:
        handedness = -1.0
    b = wp.cross(n, t) * handedness
    x = (2.0 * texel[0] - 1.0) * scale
    y = (2.0 * texel[1] - 1.0) * scale
    z = 2.0 * texel[2] - 1.0
    return safe_normalize(t * x + b * y + n * z, n)
