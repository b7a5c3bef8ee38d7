"""The BRDF of the seeds: Lambert diffuse plus Cook-Torrance specular (GGX, Smith/Schlick-GGX,
Schlick Fresnel), metallic-roughness parameterized as in glTF. One small function per term."""

import functools

import warp as wp

from .robust import MIN_COSINE, safe_normalize

wp.set_module_options({"enable_backward": False})

PI = wp.constant(3.14159265358979323846)
# Floor of alpha^2 = roughness^4 (the seeds' MIN_ROUGHNESS): keeps D finite at roughness 0.
MIN_ALPHA_SQ = wp.constant(1.0e-7)
# Dielectric reflectance at normal incidence for specular = 1 (IOR 1.5; seeds, glTF).
DIELECTRIC_F0 = wp.constant(0.04)


@wp.func
def Fd_Lambert() -> float:
    """Lambertian diffuse, 1/pi (Lambert 1760; seeds 000-004)."""
    return 1.0 / PI


@wp.func
def D_GGX(alpha: float, n_dot_h: float, one_minus_n_dot_h_sq: float) -> float:
    """Trowbridge-Reitz/GGX distribution (Walter et al. 2007); 1 - (n.h)^2 is passed in, computed
    as |n x h|^2, since 1 - (n.h)^2 loses all precision near n.h = 1 in float32 (Filament).
    Zero for n.h <= 0 (Walter's chi+): a half vector below the surface, e.g. a view direction
    under a back-facing shading normal, would otherwise read |n x h| ~ 0 as the lobe's peak."""
    if n_dot_h <= 0.0:
        return 0.0
    a2 = wp.max(alpha * alpha, MIN_ALPHA_SQ)
    d = one_minus_n_dot_h_sq + n_dot_h * n_dot_h * a2
    return a2 / (PI * d * d)


@wp.func
def V_SmithSchlickGGX(n_dot_v: float, n_dot_l: float, roughness: float) -> float:
    """Smith's separable G with Schlick-GGX, k = (roughness + 1)^2 / 8 for punctual lights
    (Karis 2013, seeds 001/004), divided by 4 n.l n.v: the visibility form (Filament's V).
    With G1(x) = x / (x (1 - k) + k), the n.l and n.v of the denominator cancel exactly, so
    grazing cosines (down to denormals) give no 0/0."""
    r = roughness + 1.0
    k = r * r / 8.0
    return 0.25 / ((n_dot_v * (1.0 - k) + k) * (n_dot_l * (1.0 - k) + k))


@wp.func
def F_Schlick(f0: wp.vec3, f90: wp.vec3, v_dot_h: float) -> wp.vec3:
    """Schlick's Fresnel approximation (Schlick 1994; seeds 001/002)."""
    x = wp.clamp(1.0 - v_dot_h, 0.0, 1.0)
    x2 = x * x
    return f0 + (f90 - f0) * (x2 * x2 * x)


@wp.func
def specular_f0(base_color: wp.vec3, metallic: float, specular: float) -> wp.vec3:
    """f0 = mix(0.04 specular, base_color, metallic) (seeds; KHR_materials_specular)."""
    return wp.lerp(wp.vec3(DIELECTRIC_F0 * specular), base_color, metallic)


@wp.func
def specular_f90(metallic: float, specular: float) -> wp.vec3:
    """f90 = mix(specular, 1, metallic): specular = 0 removes the dielectric lobe entirely
    (KHR_materials_specular); for specular = 1 this is the seeds' f90 = 1."""
    return wp.vec3(specular + (1.0 - specular) * metallic)


@functools.cache
def brdf_for(diffuse_lobe: bool, specular_lobe: bool):
    """brdf(n, v, l, base_color, metallic, roughness, specular) -> f(l, v), the seeds' model:
    (1 - F)(1 - metallic) c/pi + D F G / (4 n.l n.v), with G / (4 n.l n.v) evaluated as
    V_SmithSchlickGGX; n.v is clamped to MIN_COSINE, n.l <= 0 gives 0.

    Compiled with only the lobes a scene needs: without ``specular_lobe`` (every material has
    specular = 0 and metallic = 0, so F = 0) the Fresnel, D and V code is not generated; without
    ``diffuse_lobe`` (every material fully metallic) the Lambert code is not. Either gives bit for bit
    what the full BRDF gives on such materials."""

    @wp.func
    def brdf(n: wp.vec3, v: wp.vec3, l: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float,
             specular: float) -> wp.vec3:
        n_dot_l = wp.dot(n, l)
        if n_dot_l <= 0.0:
            return wp.vec3(0.0)
        out = wp.vec3(0.0)
        if wp.static(specular_lobe):
            n_dot_v = wp.max(wp.dot(n, v), MIN_COSINE)
            h = safe_normalize(v + l, n)
            n_cross_h = wp.cross(n, h)
            n_dot_h = wp.min(wp.dot(n, h), 1.0)
            v_dot_h = wp.clamp(wp.dot(v, h), 0.0, 1.0)
            alpha = roughness * roughness
            f0 = specular_f0(base_color, metallic, specular)
            F = F_Schlick(f0, specular_f90(metallic, specular), v_dot_h)
            D = D_GGX(alpha, n_dot_h, wp.dot(n_cross_h, n_cross_h))
            out = F * (D * V_SmithSchlickGGX(n_dot_v, n_dot_l, roughness))
            if wp.static(diffuse_lobe):
                out = wp.cw_mul(wp.vec3(1.0) - F, base_color) * ((1.0 - metallic) * Fd_Lambert()) + out
        elif wp.static(diffuse_lobe):
            out = base_color * ((1.0 - metallic) * Fd_Lambert())
        return out

    return brdf


# The full model, every lobe compiled in.
brdf_cook_torrance = brdf_for(True, True)
