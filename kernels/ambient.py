"""Light from the environment reflected at a surface point: the split-sum model (SH irradiance for
diffuse, prefiltered radiance times a DFG table for specular) or its Monte Carlo reference, built
per IBL rung so the render kernel holds only the one in use."""

import functools

import warp as wp

from .anisotropy import anisotropic_bent_normal
from .brdf import dielectric_specular_f0, max_channel, specular_f90
from .dfg import dfg_lookup
from .iridescence import F_Iridescence
from .direction_sampling import (orthonormal_basis, pdf_cosine_hemisphere, pdf_ggx_vndf_reflection,
                                 sample_cosine_hemisphere, sample_ggx_vndf)
from .environment_sampling import pdf_environment, sample_environment
from .ibl import (EnvironmentData, F_SchlickRoughness, environment_irradiance, environment_radiance,
                  prefiltered_radiance)
from .microfacet import D_GGX, PI, alpha_from_roughness
from .robust import MIN_COSINE, RAY_FAR, offset_ray_origin
from .scene_data import SceneData

wp.set_module_options({"enable_backward": False})

# Random-number stream offset of the environment directions: the sub-pixel jitter of sample s uses
# stream s of the pixel's seed, so these start well above any sample count.
ENVIRONMENT_STREAM = wp.constant(1 << 24)


@functools.cache
def ambient_for(method: str, fresnel: str, samples: int, shadowed: bool, multiscatter: bool, coupled: bool, brdf,
                occluded, gltf_mix: bool = True, anisotropic: bool = False, iridescent: bool = False,
                environment_sampled: bool = True):
    """ambient(scene, env, dfg, p, p_error, ng, n, v, base_color, metallic, roughness, specular, eta,
    kappa, f0_dielectric, seed, stream, anisotropy_t=0, anisotropy=0, thin_film=0) -> radiance reflected towards v of the environment's light
    (unoccluded; the caller applies the occlusion texture). ``brdf`` is the render kernel's own
    BRDF, which the Monte Carlo rung integrates; ``multiscatter``, ``coupled`` (the diffuse lobe
    gets only what the specular lobe leaves) and ``gltf_mix`` (glTF's mix of a dielectric and a
    metal, else the mix of their f0; see kernels/brdf.py brdf_for) make the split sum follow the
    same rungs. ``shadowed`` Monte Carlo directions are traced with the render kernel's
    ``occluded(scene, origin, direction, max_t)``, which lets alpha cut-outs through as its shadow
    rays do. ``anisotropic`` compiles in KHR_materials_anisotropy (see brdf_for): the Monte Carlo
    rung integrates the anisotropic BRDF; the split sum looks the prefiltered environment up
    about the bent normal (kernels/anisotropy.py), with the isotropic DFG table. ``iridescent``
    compiles in KHR_materials_iridescence: the Monte Carlo rung integrates the BRDF's thin-film
    Fresnel; the split sum mixes each lobe's f0 with the film's reflectance at n.v by the factor
    before the DFG lookup (as the glTF sample viewer does). ``environment_sampled`` makes every
    third Monte Carlo direction one drawn from the environment's radiance
    (kernels/environment_sampling.py); without it the directions are only the BRDF's."""
    lagarde = fresnel == "lagarde"
    # how many of the samples each strategy draws (k % strategies picks it), for the balance
    # heuristic's mixture pdf, sum of count x pdf over samples
    strategies = 3 if environment_sampled and samples >= 3 else 2
    cosine_share = float((samples + strategies - 1) // strategies) / float(samples)
    vndf_share = float((samples + strategies - 2) // strategies) / float(samples)
    environment_share = 1.0 - cosine_share - vndf_share

    @wp.func
    def lobe_albedo(f0: wp.vec3, f90: wp.vec3, ab: wp.vec2, n_dot_v: float, roughness: float):
        """(the specular lobe's albedo f0 A + f90 B, with multiple-scattering compensation, and
        the f0 after Lagarde's roughness-aware Fresnel where that rung is chosen)."""
        f0_seen = f0
        if wp.static(lagarde):
            f0_seen = F_SchlickRoughness(f0, f90, n_dot_v, roughness)
        albedo = f0_seen * ab[0] + f90 * ab[1]
        if wp.static(multiscatter):
            albedo = wp.cw_mul(albedo, wp.vec3(1.0) + f0_seen * (1.0 / wp.max(ab[0] + ab[1], 1.0e-3) - 1.0))
        return albedo, f0_seen

    @wp.func
    def split_sum(env: EnvironmentData, dfg: wp.array2d(dtype=wp.vec2), n: wp.vec3, v: wp.vec3,
                  base_color: wp.vec3, metallic: float, roughness: float, specular: float,
                  f0_dielectric: wp.vec3, anisotropy_t: wp.vec3, anisotropy: float, thin_film: wp.vec3) -> wp.vec3:
        n_dot_v = wp.max(wp.dot(n, v), MIN_COSINE)
        ab = dfg_lookup(dfg, n_dot_v, roughness)
        f0_d = dielectric_specular_f0(f0_dielectric, specular)
        f0_m = base_color
        if wp.static(iridescent):
            if thin_film[0] > 0.0:
                film_d = F_Iridescence(1.0, thin_film[1], thin_film[2], wp.min(f0_dielectric, wp.vec3(1.0)), n_dot_v)
                f0_d = wp.lerp(f0_d, film_d * specular, thin_film[0])
                f0_m = wp.lerp(f0_m, F_Iridescence(1.0, thin_film[1], thin_film[2], base_color, n_dot_v),
                               thin_film[0])
        albedo = wp.vec3(0.0)
        below = wp.vec3(0.0)  # the albedo of the lobe above the diffuse one
        below_f0 = wp.vec3(0.0)
        if wp.static(gltf_mix):
            dielectric, below_f0 = lobe_albedo(f0_d, wp.vec3(specular), ab, n_dot_v, roughness)
            metal, _ = lobe_albedo(f0_m, wp.vec3(1.0), ab, n_dot_v, roughness)
            albedo = wp.lerp(dielectric, metal, metallic)
            below = wp.vec3(max_channel(dielectric))
            below_f0 = wp.vec3(max_channel(below_f0))
        else:
            albedo, below_f0 = lobe_albedo(wp.lerp(f0_d, f0_m, metallic), specular_f90(metallic, specular), ab,
                                           n_dot_v, roughness)
            below = albedo
        mirror = 2.0 * n_dot_v * n - v
        if wp.static(anisotropic):
            if anisotropy > 0.0:
                bent = anisotropic_bent_normal(n, anisotropy_t, v, anisotropy, roughness)
                mirror = 2.0 * wp.dot(bent, v) * bent - v
        out = wp.cw_mul(prefiltered_radiance(env, mirror, roughness), albedo)
        diffuse_share = wp.vec3(1.0)
        if wp.static(coupled):
            diffuse_share = wp.max(wp.vec3(1.0) - below, wp.vec3(0.0))
            if wp.static(lagarde):
                diffuse_share = wp.vec3(1.0) - below_f0
        diffuse = wp.cw_mul(diffuse_share, base_color) * ((1.0 - metallic) / PI)
        return out + wp.cw_mul(diffuse, environment_irradiance(env, n))

    @wp.func
    def monte_carlo(scene: SceneData, env: EnvironmentData, p: wp.vec3, p_error: wp.vec3, ng: wp.vec3, n: wp.vec3,
                    v: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float, specular: float,
                    eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, seed: int, stream: int,
                    anisotropy_t: wp.vec3, anisotropy: float, thin_film: wp.vec3) -> wp.vec3:
        """Directions cosine-weighted, from GGX's visible normals and (``environment_sampled``)
        from the environment's radiance, in turn, weighted by the balance heuristic (the mixture
        pdf; Veach 1997): unbiased for every BRDF rung."""
        frame = orthonormal_basis(n)
        v_local = wp.transpose(frame) * v
        if v_local[2] <= 0.0:
            return wp.vec3(0.0)
        alpha = alpha_from_roughness(roughness)
        state = wp.rand_init(seed, ENVIRONMENT_STREAM + stream)
        total = wp.vec3(0.0)
        for k in range(samples):
            u = wp.vec2(wp.randf(state), wp.randf(state))
            l_local = wp.vec3(0.0)
            l = wp.vec3(0.0)
            env_pdf = float(0.0)
            strategy = k % wp.static(strategies)
            if strategy == 0:
                l_local = sample_cosine_hemisphere(u)
                l = frame * l_local
            elif strategy == 1:
                h = sample_ggx_vndf(v_local, alpha, u)
                l_local = 2.0 * wp.dot(v_local, h) * h - v_local
                l = frame * l_local
            else:
                l, env_pdf = sample_environment(env.sampler, env, u)
                l_local = wp.transpose(frame) * l
            if l_local[2] <= 0.0:
                continue
            # light from below the geometric surface cannot arrive
            if wp.dot(ng, l) <= 0.0:
                continue
            h_local = wp.normalize(v_local + l_local)
            d = D_GGX(alpha, h_local[2], h_local[0] * h_local[0] + h_local[1] * h_local[1])
            pdf = (wp.static(cosine_share) * pdf_cosine_hemisphere(l_local[2])
                   + wp.static(vndf_share) * pdf_ggx_vndf_reflection(d, v_local[2], alpha))
            if wp.static(strategies == 3):
                if strategy != 2:
                    env_pdf = pdf_environment(env.sampler, env, l)
                pdf = pdf + wp.static(environment_share) * env_pdf
            if pdf <= 0.0:
                continue
            if wp.static(shadowed):
                if occluded(scene, offset_ray_origin(p, p_error, ng, l), l, RAY_FAR):
                    continue
            f = brdf(n, v, l, base_color, metallic, roughness, specular, eta, kappa, f0_dielectric, anisotropy_t,
                     anisotropy, thin_film)
            total = total + wp.cw_mul(f, environment_radiance(env, l)) * (l_local[2] / pdf)
        return total / float(samples)

    @wp.func
    def ambient(scene: SceneData, env: EnvironmentData, dfg: wp.array2d(dtype=wp.vec2), p: wp.vec3, p_error: wp.vec3,
                ng: wp.vec3, n: wp.vec3, v: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float,
                specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, seed: int,
                stream: int, anisotropy_t: wp.vec3 = wp.vec3(0.0), anisotropy: float = 0.0,
                thin_film: wp.vec3 = wp.vec3(0.0)) -> wp.vec3:
        if wp.static(method == "monte_carlo"):
            return monte_carlo(scene, env, p, p_error, ng, n, v, base_color, metallic, roughness, specular, eta,
                               kappa, f0_dielectric, seed, stream, anisotropy_t, anisotropy, thin_film)
        return split_sum(env, dfg, n, v, base_color, metallic, roughness, specular, f0_dielectric, anisotropy_t,
                         anisotropy, thin_film)

    return ambient
