"""Sampling directions for Monte Carlo integration over the hemisphere: cosine-weighted for the
diffuse lobe, GGX visible normals for the specular lobe, each with its pdf (per solid angle).

Samplers take two uniform numbers u in [0, 1)^2 rather than a random state: Warp passes scalars
to functions by value, so a function could not advance its caller's state, and the caller can
feed random (``wp.randf``), stratified or Hammersley points alike. Directions are in a local
frame whose z axis is the normal; ``orthonormal_basis`` takes them to world space.
"""

import warp as wp

from .microfacet import MIN_ALPHA_SQ, PI

wp.set_module_options({"enable_backward": False})


@wp.func
def orthonormal_basis(n: wp.vec3) -> wp.mat33:
    """Columns (t, b, n): a right-handed frame around the unit vector n, continuous everywhere but
    at n = -z (Duff et al. 2017, "Building an Orthonormal Basis, Revisited")."""
    sign = 1.0
    if n[2] < 0.0:
        sign = -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    bt = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return wp.matrix_from_cols(t, bt, n)


@wp.func
def sample_cosine_hemisphere(u: wp.vec2) -> wp.vec3:
    """Local direction with pdf cos(theta) / pi (Malley's method: a uniform point on the unit disk,
    projected up; the disk point by Shirley & Chiu's concentric map, which keeps strata compact)."""
    a = 2.0 * u[0] - 1.0
    b = 2.0 * u[1] - 1.0
    r = float(0.0)
    phi = float(0.0)
    if a * a > b * b:
        r = a
        phi = (PI / 4.0) * (b / a)
    elif b != 0.0:
        r = b
        phi = PI / 2.0 - (PI / 4.0) * (a / b)
    x = r * wp.cos(phi)
    y = r * wp.sin(phi)
    return wp.vec3(x, y, wp.sqrt(wp.max(0.0, 1.0 - x * x - y * y)))


@wp.func
def pdf_cosine_hemisphere(cos_theta: float) -> float:
    """Solid-angle pdf of sample_cosine_hemisphere: cos(theta) / pi above the surface, 0 below."""
    return wp.max(cos_theta, 0.0) / PI


@wp.func
def sample_ggx_vndf(v: wp.vec3, alpha: float, u: wp.vec2) -> wp.vec3:
    """Local microfacet normal h drawn from the GGX distribution of normals visible from the local
    direction v (v.z > 0), pdf G1(v) max(v.h, 0) D(h) / v.z (Heitz 2018, "Sampling the GGX
    Distribution of Visible Normals", listing 1, isotropic)."""
    a = wp.max(alpha, wp.sqrt(MIN_ALPHA_SQ))
    # the view direction in the hemisphere configuration (the stretched, alpha = 1 space)
    vh = wp.normalize(wp.vec3(a * v[0], a * v[1], v[2]))
    len_sq = vh[0] * vh[0] + vh[1] * vh[1]
    t1 = wp.vec3(1.0, 0.0, 0.0)
    if len_sq > 0.0:
        t1 = wp.vec3(-vh[1], vh[0], 0.0) / wp.sqrt(len_sq)
    t2 = wp.cross(vh, t1)
    # a uniform point on the disk, squeezed onto the part of the projected hemisphere v sees
    r = wp.sqrt(u[0])
    phi = 2.0 * PI * u[1]
    p1 = r * wp.cos(phi)
    p2 = r * wp.sin(phi)
    s = 0.5 * (1.0 + vh[2])
    p2 = (1.0 - s) * wp.sqrt(wp.max(0.0, 1.0 - p1 * p1)) + s * p2
    nh = p1 * t1 + p2 * t2 + wp.sqrt(wp.max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh
    # back to the ellipsoid configuration
    return wp.normalize(wp.vec3(a * nh[0], a * nh[1], wp.max(0.0, nh[2])))


@wp.func
def G1_SmithGGX(n_dot_v: float, alpha: float) -> float:
    """Smith's masking for GGX, 2 n.v / (n.v + sqrt(alpha^2 + (1 - alpha^2) (n.v)^2)) (Walter et al. 2007)."""
    a2 = wp.max(alpha * alpha, MIN_ALPHA_SQ)
    return 2.0 * n_dot_v / (n_dot_v + wp.sqrt(a2 + (1.0 - a2) * n_dot_v * n_dot_v))


@wp.func
def pdf_ggx_vndf_reflection(d: float, n_dot_v: float, alpha: float) -> float:
    """Solid-angle pdf of the reflected direction l = reflect(-v, h) for h from sample_ggx_vndf,
    given d = D_GGX(h): D_v(h) / (4 v.h) = G1(v) D(h) / (4 n.v) (Heitz 2018, eq. 17)."""
    return G1_SmithGGX(n_dot_v, alpha) * d / (4.0 * n_dot_v)
