"""Anisotropic GGX (KHR_materials_anisotropy): the distribution and masking terms of a lobe whose
roughness differs along the surface's anisotropy direction t and across it, b = n x t, and the
frame and bent normal that the render kernel and environment light derive from the material.

The extension raises the alpha roughness along t only, alpha_t = mix(alpha, 1, strength^2), and
keeps alpha_b = alpha, so strength 0 is the isotropic lobe."""

import warp as wp

from .microfacet import MIN_ALPHA_SQ, PI
from .robust import safe_normalize

wp.set_module_options({"enable_backward": False})


@wp.func
def anisotropic_alphas(alpha: float, strength: float) -> wp.vec2:
    """(alpha_t, alpha_b) = (mix(alpha, 1, strength^2), alpha), each floored like D_GGX's alpha
    (KHR_materials_anisotropy)."""
    floor = wp.sqrt(MIN_ALPHA_SQ)
    at = alpha + (1.0 - alpha) * strength * strength
    return wp.vec2(wp.max(at, floor), wp.max(alpha, floor))


@wp.func
def D_GGX_Anisotropic(at: float, ab: float, n_dot_h: float, t_dot_h: float, b_dot_h: float) -> float:
    """Anisotropic GGX distribution (Burley 2012, after Walter et al. 2007):
    1 / (pi at ab ((t.h / at)^2 + (b.h / ab)^2 + (n.h)^2)^2), written as Filament does so that
    nothing is divided by a small alpha; zero for n.h <= 0 as D_GGX."""
    if n_dot_h <= 0.0:
        return 0.0
    a2 = at * ab
    f = wp.vec3(ab * t_dot_h, at * b_dot_h, a2 * n_dot_h)
    w2 = a2 / wp.dot(f, f)
    return a2 * w2 * w2 / PI


@wp.func
def V_SmithGGXCorrelated_Anisotropic(at: float, ab: float, n_dot_v: float, n_dot_l: float, t_dot_v: float,
                                     b_dot_v: float, t_dot_l: float, b_dot_l: float) -> float:
    """Height-correlated Smith masking-shadowing of anisotropic GGX (Heitz 2014) over
    4 n.l n.v: 0.5 / (n.l |(at t.v, ab b.v, n.v)| + n.v |(at t.l, ab b.l, n.l)|)."""
    lambda_v = n_dot_l * wp.length(wp.vec3(at * t_dot_v, ab * b_dot_v, n_dot_v))
    lambda_l = n_dot_v * wp.length(wp.vec3(at * t_dot_l, ab * b_dot_l, n_dot_l))
    return 0.5 / (lambda_v + lambda_l)


@wp.func
def anisotropy_direction(n: wp.vec3, tangent: wp.vec4, direction: wp.vec2) -> wp.vec3:
    """The unit anisotropy direction t in the plane of the unit normal ``n`` (the front side's):
    ``direction`` (x along the tangent, y along the bitangent, as KHR_materials_anisotropy's
    texture and rotation give it) in the frame of the vertex ``tangent`` made orthogonal to n,
    bitangent n x tangent times the sign of ``tangent``.w (glTF's convention, as normal maps use
    it). The zero vector where the mesh has no tangent frame (the caller then shades
    isotropically) or the tangent is parallel to n."""
    t = wp.vec3(tangent[0], tangent[1], tangent[2])
    t = t - n * wp.dot(n, t)
    if wp.dot(t, t) < 1.0e-12:
        return wp.vec3(0.0)
    t = wp.normalize(t)
    handedness = 1.0
    if tangent[3] < 0.0:
        handedness = -1.0
    return safe_normalize(t * direction[0] + wp.cross(n, t) * (handedness * direction[1]), wp.vec3(0.0))


@wp.func
def anisotropic_bent_normal(n: wp.vec3, t: wp.vec3, v: wp.vec3, strength: float, roughness: float) -> wp.vec3:
    """The normal about which environment light is looked up for a lobe stretched along ``t``: n
    bent towards the normal of the plane holding the smooth direction b = n x t and v, the more
    the stronger the anisotropy and the smoother the material (McAuley 2015, "Rendering the world
    of Far Cry 4", as Filament and the glTF sample viewer bend the reflection vector), so that the
    reflections spread along t; n itself for strength 0."""
    b = wp.cross(n, t)
    across = wp.cross(b, v)
    towards = safe_normalize(wp.cross(across, b), n)
    bend = 1.0 - strength * (1.0 - roughness)
    bend4 = bend * bend * bend * bend
    return safe_normalize(towards + (n - towards) * bend4, n)
