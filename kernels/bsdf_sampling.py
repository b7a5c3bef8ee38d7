"""Sampling the glTF BRDF (kernels/brdf.py) for path tracing, and combining strategies.

A direction is drawn from a one-sample mixture of the BRDF's two lobes (Veach 1997, section 9.2.4):
the diffuse lobe by cosine-weighted hemisphere sampling, the specular lobe by reflecting the view
direction about a GGX visible normal (Heitz 2018), the lobe chosen with a probability that
estimates the specular lobe's share of the reflected light. The pdf of the direction, for the
estimator and for multiple importance sampling, is the mixture's: p = P_s p_spec + (1 - P_s)
p_diffuse, whichever lobe drew it. Both lobes' samplers and pdfs live in
kernels/direction_sampling.py; this file only mixes them.

Samplers take their uniform numbers as arguments (kernels/random.py makes them), so a test can
feed them any points.
"""

import warp as wp

from .brdf import F_Schlick, dielectric_specular_f0, max_channel, specular_f90
from .direction_sampling import (orthonormal_basis, pdf_cosine_hemisphere, pdf_ggx_vndf_reflection,
                                 sample_cosine_hemisphere, sample_ggx_vndf)
from .microfacet import D_GGX
from .robust import MIN_COSINE, safe_normalize
from .transmission import reflect

wp.set_module_options({"enable_backward": False})


@wp.func
def specular_lobe_probability(base_color: wp.vec3, metallic: float, specular: float, f0_dielectric: wp.vec3,
                              n_dot_v: float) -> float:
    """The probability of sampling the specular lobe: its Schlick reflectance at n.v over that plus
    the diffuse lobe's albedo, (1 - metallic) base colour (1 - F_dielectric), largest channels. 0
    without a specular lobe (f0 = f90 = 0), 1 without a diffuse one (metals, black base)."""
    c = wp.clamp(n_dot_v, 0.0, 1.0)
    f0 = wp.lerp(dielectric_specular_f0(f0_dielectric, specular), base_color, metallic)
    reflected = max_channel(F_Schlick(f0, specular_f90(metallic, specular), c))
    dielectric = max_channel(F_Schlick(dielectric_specular_f0(f0_dielectric, specular), wp.vec3(specular), c))
    diffused = (1.0 - metallic) * max_channel(base_color) * wp.max(1.0 - dielectric, 0.0)
    total = reflected + diffused
    if total <= 0.0:
        return 0.5
    return reflected / total


@wp.func
def local_view(frame: wp.mat33, v: wp.vec3) -> wp.vec3:
    """The view direction v in the shading frame (columns t, b, n), lifted to at least MIN_COSINE
    above the surface: a shading normal can face away from the viewer (interpolated or
    normal-mapped normals), where the visible-normal sampler needs v.z > 0. The sampler and the
    pdf both use this direction, so they agree."""
    local = wp.transpose(frame) * v
    if local[2] < MIN_COSINE:
        local = safe_normalize(wp.vec3(local[0], local[1], MIN_COSINE), wp.vec3(0.0, 0.0, 1.0))
        if local[2] < MIN_COSINE:  # v straight along the surface: the normal itself
            local = wp.vec3(0.0, 0.0, 1.0)
    return local


@wp.func
def sample_brdf_direction(n: wp.vec3, v: wp.vec3, alpha: float, p_specular: float, u_lobe: float,
                          u: wp.vec2) -> wp.vec3:
    """A world direction from the lobe mixture around the shading normal n for the view direction
    v (both unit, v towards the viewer): the specular lobe (GGX visible normals of width alpha,
    reflected) if u_lobe < p_specular, else the cosine lobe. It may point below the surface (a
    specular reflection about a steep microfacet); its pdf is pdf_brdf_direction's."""
    frame = orthonormal_basis(n)
    local = wp.vec3(0.0)
    if u_lobe < p_specular:
        vl = local_view(frame, v)
        h = sample_ggx_vndf(vl, alpha, u)
        local = reflect(vl, h)
    else:
        local = sample_cosine_hemisphere(u)
    return safe_normalize(frame * local, n)


@wp.func
def pdf_specular_reflection(vl: wp.vec3, ll: wp.vec3, alpha: float) -> float:
    """Solid-angle pdf of local direction ll reflected about a GGX visible normal for local view vl:
    G1(v) D(h) / (4 v.z) with h the half vector, 0 where v.h <= 0 (Heitz 2018, eq. 17)."""
    h = safe_normalize(vl + ll, wp.vec3(0.0, 0.0, 1.0))
    if wp.dot(vl, h) <= 0.0:
        return 0.0
    sin_sq = h[0] * h[0] + h[1] * h[1]
    return pdf_ggx_vndf_reflection(D_GGX(alpha, h[2], sin_sq), vl[2], alpha)


@wp.func
def pdf_brdf_direction(n: wp.vec3, v: wp.vec3, l: wp.vec3, alpha: float, p_specular: float) -> float:
    """Solid-angle pdf with which sample_brdf_direction(n, v, alpha, p_specular, ...) draws the
    world direction l: the mixture P_s p_spec(l) + (1 - P_s) cos(theta_l) / pi."""
    frame = orthonormal_basis(n)
    ll = wp.transpose(frame) * l
    pdf = (1.0 - p_specular) * pdf_cosine_hemisphere(ll[2])
    if p_specular > 0.0:
        pdf = pdf + p_specular * pdf_specular_reflection(local_view(frame, v), ll, alpha)
    return pdf


@wp.func
def sample_coated_direction(n: wp.vec3, v: wp.vec3, alpha: float, p_specular: float, coat_normal: wp.vec3,
                            coat_alpha: float, p_coat: float, u_lobe: float, u: wp.vec2) -> wp.vec3:
    """A world direction from the three-lobe mixture of a clear-coated BRDF: with probability
    p_coat (u_lobe below it) the coat's specular lobe about its own normal (GGX visible normals of
    width coat_alpha), else, u_lobe rescaled, sample_brdf_direction's mixture about n. Its pdf is
    pdf_coated_direction's."""
    if u_lobe < p_coat:
        return sample_brdf_direction(coat_normal, v, coat_alpha, 1.0, 0.0, u)
    choice = (u_lobe - p_coat) / wp.max(1.0 - p_coat, 1.0e-6)
    return sample_brdf_direction(n, v, alpha, p_specular, choice, u)


@wp.func
def pdf_coated_direction(n: wp.vec3, v: wp.vec3, l: wp.vec3, alpha: float, p_specular: float, coat_normal: wp.vec3,
                         coat_alpha: float, p_coat: float) -> float:
    """Solid-angle pdf with which sample_coated_direction draws l: p_coat p_coat_lobe(l) +
    (1 - p_coat) pdf_brdf_direction(l) (one-sample MIS over the lobes, Veach 1997, 9.2.4)."""
    pdf = pdf_brdf_direction(n, v, l, alpha, p_specular)
    if p_coat > 0.0:
        pdf = (1.0 - p_coat) * pdf + p_coat * pdf_brdf_direction(coat_normal, v, l, coat_alpha, 1.0)
    return pdf


@wp.func
def power_heuristic(pdf_a: float, pdf_b: float) -> float:
    """Veach's power heuristic with exponent 2 (Veach 1997, eq. 9.13) for one sample of strategy a
    against one of b: pdf_a^2 / (pdf_a^2 + pdf_b^2), computed from the ratio so that neither
    squaring overflows. w(a, b) + w(b, a) = 1; 0 where pdf_a is 0."""
    if pdf_a <= 0.0:
        return 0.0
    if pdf_b <= 0.0:
        return 1.0
    if pdf_a >= pdf_b:
        r = pdf_b / pdf_a
        return 1.0 / (1.0 + r * r)
    r = pdf_a / pdf_b
    return r * r / (1.0 + r * r)
