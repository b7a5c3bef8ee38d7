"""The BRDF: Lambert diffuse plus Cook-Torrance specular, metallic-roughness parameterized as in
glTF, with a ladder of rungs per term. One small function per term, named after its model: the
Fresnel and diffuse terms here, the microfacet distributions and masking terms in
kernels/microfacet.py; the albedo tables of energy compensation and coupling come from
kernels/energy.py.

The default is glTF 2.0's material (its Appendix B): a dielectric BRDF (Lambert under a specular
layer whose achromatic Fresnel comes from the IOR, scaled by KHR_materials_specular) mixed with a
metal BRDF (a specular lobe with f0 = base colour) by metallic, with the terms of the real-time
model of Karis 2013 (Lambert, GGX, Smith/Schlick-GGX, Schlick Fresnel); the other rungs are
cheaper or more exact alternatives chosen at compile time (pbrwarp.BRDF)."""

import functools

import warp as wp

from .anisotropy import D_GGX_Anisotropic, V_SmithGGXCorrelated_Anisotropic, anisotropic_alphas
from .energy import albedo_tables
from .iridescence import F_Iridescence
from .microfacet import (DISTRIBUTIONS, GEOMETRY_MODELS, PI, alpha_from_roughness, blinn_phong_exponent,
                         distribution_for, visibility_for)
from .robust import MIN_COSINE, safe_normalize

wp.set_module_options({"enable_backward": False})

# Dielectric reflectance at normal incidence of glTF's default IOR 1.5, ((1.5 - 1) / (1.5 + 1))^2.
DIELECTRIC_F0 = wp.constant(0.04)


@wp.func
def Fd_Lambert() -> float:
    """Lambertian diffuse, 1/pi (Lambert 1760)."""
    return 1.0 / PI


@wp.func
def Fd_Burley(n_dot_v: float, n_dot_l: float, l_dot_h: float, roughness: float) -> float:
    """Disney diffuse (Burley 2012): Lambert with retro-reflection at grazing angles,
    F_D90 = 0.5 + 2 roughness (l.h)^2."""
    f90 = 0.5 + 2.0 * roughness * l_dot_h * l_dot_h
    xl = 1.0 - n_dot_l
    xv = 1.0 - n_dot_v
    light = 1.0 + (f90 - 1.0) * (xl * xl * xl * xl * xl)
    view = 1.0 + (f90 - 1.0) * (xv * xv * xv * xv * xv)
    return light * view / PI

@wp.func
def F_None(f0: wp.vec3, f90: wp.vec3, v_dot_h: float) -> wp.vec3:
    """No Fresnel effect: the reflectance at normal incidence at every angle."""
    return f0


@wp.func
def F_SphericalGaussian(f0: wp.vec3, f90: wp.vec3, v_dot_h: float) -> wp.vec3:
    """Schlick's Fresnel with (1 - v.h)^5 replaced by the spherical-Gaussian fit
    2^((-5.55473 v.h - 6.98316) v.h) (Lagarde 2012; Karis 2013)."""
    x = wp.clamp(v_dot_h, 0.0, 1.0)
    return f0 + (f90 - f0) * wp.pow(2.0, (-5.55473 * x - 6.98316) * x)


@wp.func
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Unpolarized Fresnel reflectance of a dielectric interface with relative IOR eta (Born & Wolf)."""
    c = wp.clamp(cos_i, 0.0, 1.0)
    g_sq = eta * eta - 1.0 + c * c
    if g_sq <= 0.0:
        return 1.0
    g = wp.sqrt(g_sq)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


@wp.func
def F_Exact(f0: wp.vec3, f90: wp.vec3, v_dot_h: float) -> wp.vec3:
    """Exact dielectric Fresnel per channel, with the IOR that f0 implies,
    eta = (1 + sqrt(f0)) / (1 - sqrt(f0)) (Fresnel 1823), scaled so that grazing reflectance is f90
    (KHR_materials_specular)."""
    out = wp.vec3(0.0)
    for c in range(3):
        if f90[c] > 0.0:
            r = wp.sqrt(wp.clamp(f0[c] / f90[c], 0.0, 0.9999))
            out[c] = f90[c] * fresnel_dielectric(v_dot_h, (1.0 + r) / (1.0 - r))
    return out


@wp.func
def fresnel_conductor(cos_i: float, eta: float, kappa: float) -> float:
    """Unpolarized Fresnel reflectance of a conductor with complex IOR eta + i kappa (Born & Wolf;
    the real-arithmetic form of Lagarde's "Memo on Fresnel equations", 2013)."""
    c = wp.clamp(cos_i, 0.0, 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    t0 = eta * eta - kappa * kappa - s2
    a2_plus_b2 = wp.sqrt(t0 * t0 + 4.0 * eta * eta * kappa * kappa)
    a = wp.sqrt(wp.max(0.5 * (a2_plus_b2 + t0), 0.0))
    t1 = a2_plus_b2 + c2
    t2 = 2.0 * a * c
    rs = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2_plus_b2 + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rs + rp)


@wp.func
def F_Conductor(eta: wp.vec3, kappa: wp.vec3, v_dot_h: float) -> wp.vec3:
    """Exact conductor Fresnel per channel from a complex IOR (n, k per RGB channel)."""
    return wp.vec3(fresnel_conductor(v_dot_h, eta[0], kappa[0]), fresnel_conductor(v_dot_h, eta[1], kappa[1]),
                   fresnel_conductor(v_dot_h, eta[2], kappa[2]))


@wp.func
def Fs_Phong(alpha_p: float, r_dot_v: float) -> float:
    """Normalized Phong BRDF lobe, (a_p + 2) / (2 pi) (r.v)^a_p (Lafortune & Willems 1994)."""
    return (alpha_p + 2.0) / (2.0 * PI) * wp.pow(wp.clamp(r_dot_v, 0.0, 1.0), alpha_p)


@wp.func
def Fs_BlinnPhong(alpha_p: float, n_dot_h: float) -> float:
    """Normalized Blinn-Phong BRDF lobe with Hoffman's cheap normalization (a_p + 8) / (8 pi)
    (n.h)^a_p (Akenine-Möller, Haines & Hoffman 2008)."""
    return (alpha_p + 8.0) / (8.0 * PI) * wp.pow(wp.clamp(n_dot_h, 0.0, 1.0), alpha_p)


@wp.func
def F_Schlick(f0: wp.vec3, f90: wp.vec3, v_dot_h: float) -> wp.vec3:
    """Schlick's Fresnel approximation (Schlick 1994)."""
    x = wp.clamp(1.0 - v_dot_h, 0.0, 1.0)
    x2 = x * x
    return f0 + (f90 - f0) * (x2 * x2 * x)


@wp.func
def dielectric_specular_f0(f0_dielectric: wp.vec3, specular: float) -> wp.vec3:
    """The dielectric layer's f0, min(f0_dielectric, 1) specular (KHR_materials_specular):
    ``f0_dielectric`` is ((ior - 1) / (ior + 1))^2 times the specular colour (KHR_materials_ior),
    which may exceed 1 and is clamped before the specular factor scales it."""
    return wp.min(f0_dielectric, wp.vec3(1.0)) * specular


@wp.func
def max_channel(x: wp.vec3) -> float:
    """The largest component (KHR_materials_specular's max_value)."""
    return wp.max(x[0], wp.max(x[1], x[2]))


@wp.func
def specular_f0(base_color: wp.vec3, metallic: float, specular: float, f0_dielectric: wp.vec3) -> wp.vec3:
    """f0 = mix(dielectric f0, base_color, metallic): the f0 of the single specular lobe of the
    "f0" metallic mix (dielectric_specular_f0 gives the dielectric's)."""
    return wp.lerp(dielectric_specular_f0(f0_dielectric, specular), base_color, metallic)


@wp.func
def specular_f90(metallic: float, specular: float) -> wp.vec3:
    """f90 = mix(specular, 1, metallic): specular = 0 removes the dielectric lobe entirely
    (KHR_materials_specular); for specular = 1 this is Schlick's f90 = 1."""
    return wp.vec3(specular + (1.0 - specular) * metallic)


DIFFUSE_MODELS = ("lambert", "burley")
FRESNEL_MODELS = ("none", "schlick", "spherical_gaussian", "exact")
ENERGY_MODELS = ("single", "multiscatter")
# "microfacet" is Cook-Torrance with the rungs above; the others are the legacy, non-PBR
# baselines it is usually contrasted with, Lambert plus a normalized (Blinn-)Phong lobe.
MODELS = ("microfacet", "phong", "blinn_phong")
FRESNEL_TERMS = {"none": F_None, "schlick": F_Schlick, "spherical_gaussian": F_SphericalGaussian, "exact": F_Exact}


COUPLING_MODELS = ("albedo", "fresnel", "none")
# How metallic combines a dielectric and a metal: "gltf" mixes their BRDFs (glTF 2.0, Appendix B),
# "f0" mixes their f0 into one specular lobe over a diffuse one (Karis 2013).
METALLIC_MIXES = ("gltf", "f0")
# Floor of 1 - E_avg in the albedo coupling: a white metal's lobe reflects all light (E_avg -> 1),
# and its diffuse weight (1 - metallic) is 0 anyway.
MIN_DIFFUSE_SHARE = wp.constant(1.0e-6)


def static_table(values: tuple):
    """entry(i) -> values[i], the values compiled into a static C++ array: a wp.constant matrix
    would be rebuilt on the stack at every call (thousands of floats), costing more than the BRDF."""
    body = ", ".join(f"{float(v)!r}f" for v in values)

    @wp.func_native(f"static const float values[{len(values)}] = {{{body}}};\nreturn values[i];")
    def entry(i: int) -> float: ...

    return entry


@functools.cache
def albedo_lookup(distribution: str, geometry: str, fresnel: str):
    """(lookup, averages) over the energy tables of a rung triple: lookup(n.x, roughness) -> (E1, Ew),
    bilinear like energy.interpolate_rows; averages(roughness) -> the four cosine-weighted means."""
    t = albedo_tables(distribution, geometry, fresnel)
    size = t.size
    table = static_table(t.albedo)
    means = static_table(t.averages)

    @wp.func
    def pair(cell: int) -> wp.vec2:
        return wp.vec2(table(cell), table(cell + 1))

    @wp.func
    def lookup(n_dot: float, roughness: float) -> wp.vec2:
        x = wp.clamp(n_dot * float(size) - 0.5, 0.0, float(size - 1))
        y = wp.clamp(roughness * float(size - 1), 0.0, float(size - 1))
        i0 = wp.min(int(x), size - 2)
        j0 = wp.min(int(y), size - 2)
        cell = i0 * 2 * size + 2 * j0
        next_row = cell + 2 * size
        fx = x - float(i0)
        low = wp.lerp(pair(cell), pair(next_row), fx)
        high = wp.lerp(pair(cell + 2), pair(next_row + 2), fx)
        return wp.lerp(low, high, y - float(j0))

    @wp.func
    def column(j: int) -> wp.vec4:
        return wp.vec4(means(j), means(size + j), means(2 * size + j), means(3 * size + j))

    @wp.func
    def averages(roughness: float) -> wp.vec4:
        y = wp.clamp(roughness * float(size - 1), 0.0, float(size - 1))
        j0 = wp.min(int(y), size - 2)
        return wp.lerp(column(j0), column(j0 + 1), y - float(j0))

    return lookup, averages


@functools.cache
def brdf_for(diffuse_lobe: bool, specular_lobe: bool, diffuse: str = "lambert", distribution: str = "ggx",
             geometry: str = "schlick_ggx", fresnel: str = "schlick", energy: str = "single",
             coupling: str = "albedo", model: str = "microfacet", metallic_mix: str = "gltf",
             anisotropic: bool = False, iridescent: bool = False):
    """brdf(n, v, l, base_color, metallic, roughness, specular, eta=0, kappa=0, f0_dielectric=0.04,
    anisotropy_t=0, anisotropy=0, thin_film=0) -> f(l, v). n.v is clamped to MIN_COSINE, n.l <= 0 gives 0; V = G / (4 n.l n.v) is the
    geometry term in its visibility form, D the distribution, f_d the diffuse term. The names pick
    each term's rung; the defaults are Karis 2013's terms (f_d Lambert, GGX, Smith/Schlick-GGX,
    Schlick, single scattering) in glTF's mix.

    The material: ``base_color`` (linear RGB), ``metallic``, ``roughness`` (perceptual), the
    specular factor ``specular`` and ``f0_dielectric``, ((ior - 1) / (ior + 1))^2 times the
    specular colour (unclamped; KHR_materials_ior and _specular), from which the dielectric's
    f0_d = min(f0_dielectric, 1) specular and f90_d = specular.

    ``metallic_mix="gltf"`` (default) is glTF 2.0's material (Appendix B, with
    KHR_materials_specular): mix(dielectric, metal, metallic), the dielectric
    F_d D V + k c f_d and the metal F_m D V, F_d the Fresnel of (f0_d, f90_d), F_m that of
    (base_color, 1), c = base_color. ``"f0"`` mixes the f0 instead, as Karis 2013:
    F D V + k (1 - metallic) c f_d, F of (mix(f0_d, base_color, metallic), mix(f90_d, 1, metallic)).
    The specular lobes of the two agree for the Fresnel rungs linear in (f0, f90); the diffuse
    shares differ: "f0" weights the diffuse lobe by the mixed, chromatic specular lobe's albedo,
    which tints partly metallic materials.

    ``coupling`` is k, the share of light left to the diffuse lobe: "albedo" (default),
    (1 - E(v))(1 - E(l)) / (1 - E_avg) with E the directional albedo of the specular lobe above
    the diffuse one (Kelemen & Szirmay-Kalos 2001; Kulla & Conty 2017), which is reciprocal and
    conserves energy exactly for Lambert (white-furnace albedo E(v) + (1 - E(v)) = 1); "fresnel",
    one minus the Fresnel at v.h, which gives smooth white dielectrics seen at grazing angles up
    to ~6% more light than they receive; "none", diffuse and specular simply added (Filament).
    In the "gltf" mix the lobe above the diffuse one is the dielectric's, and k is achromatic: E
    of its largest channel (f0 = max_channel(f0_d), f90 = specular) and 1 - max_channel(F_d)
    (KHR_materials_specular's fresnel_mix), so coloured specular never gives the diffuse lobe the
    complementary colour. In the "f0" mix E and F are the single lobe's, per channel.

    ``energy="multiscatter"`` scales each specular lobe by 1 + f0 (1/E1 - 1) with its own f0
    (Fdez-Agüera 2019, as Filament). ``fresnel="exact"`` gives the dielectric the exact
    dielectric Fresnel with the IOR its f0 implies (the material's ior for a white specular
    colour), and metals with a complex IOR (``eta`` + i ``kappa`` per channel; eta = 0 when the
    material gives none) the exact conductor Fresnel.

    ``model="phong"`` or ``"blinn_phong"`` replace all of this by the legacy baselines:
    (1 - c_spec) c_diff / pi plus c_spec times a normalized Phong or Blinn-Phong lobe (Lagarde 2011),
    c_spec = mix(f0_d, base_color, metallic), c_diff = (1 - metallic) base_color; the Phong
    exponent is a quarter of the Blinn-Phong one, which gives highlights of about the same size
    (Akenine-Möller et al. 2008).

    Compiled with only the lobes a scene needs: without ``specular_lobe`` (every material has
    specular = 0 and metallic = 0, so f0 = f90 = 0) the Fresnel, D, V and albedo code is not
    generated; without ``diffuse_lobe`` (every material fully metallic) the diffuse code is not.
    Either gives bit for bit what the full BRDF gives on such materials.

    ``anisotropic`` compiles in KHR_materials_anisotropy: where ``anisotropy`` (its strength, in
    [0, 1]) is above 0, the specular lobes take the anisotropic GGX distribution and
    height-correlated Smith term (kernels/anisotropy.py) with alpha_t = mix(alpha, 1, strength^2)
    along the unit tangent direction ``anisotropy_t`` (orthogonal to n) and alpha across it,
    whatever the distribution and geometry rungs; their Fresnel terms, and the albedo tables of
    the coupling and multiple-scattering compensation, stay those of the isotropic alpha. Legacy
    models ignore it.

    ``iridescent`` compiles in KHR_materials_iridescence: where ``thin_film`` = (factor, film
    IOR, thickness in nm) has a factor above 0, each specular lobe's Fresnel term F becomes
    mix(F, F_Iridescence(v.h), factor) (kernels/iridescence.py), the film over the metal's f0 =
    base colour and over the dielectric's min(f0_dielectric, 1), the latter scaled by the specular
    factor; the coupling's albedo tables stay those of the plain Fresnel term. (For a caller that
    evaluates one material many times, albedo_coupled_brdf_for gives the same BRDF with the
    albedo coupling's normalization taken as an argument.)"""
    _check_rungs(diffuse, distribution, geometry, fresnel, energy, coupling, model, metallic_mix)
    if model != "microfacet":
        return legacy_brdf(diffuse_lobe, specular_lobe, model)
    return _microfacet_brdf(diffuse_lobe, specular_lobe, diffuse, distribution, geometry, fresnel, energy, coupling,
                            metallic_mix, anisotropic, iridescent)[0]


@functools.cache
def albedo_coupled_brdf_for(diffuse_lobe: bool, specular_lobe: bool, diffuse: str = "lambert",
                            distribution: str = "ggx", geometry: str = "schlick_ggx", fresnel: str = "schlick",
                            energy: str = "single", coupling: str = "albedo", model: str = "microfacet",
                            metallic_mix: str = "gltf", anisotropic: bool = False, iridescent: bool = False):
    """(brdf_scaled, diffuse_share_scale) of brdf_for's BRDF where it couples its lobes by
    albedo, else None. diffuse_share_scale(base_color, metallic, roughness, specular,
    f0_dielectric) is the coupling's normalization 1 / (1 - E_avg) per channel, and
    brdf_scaled(n, v, l, base_color, metallic, roughness, specular, eta, kappa, f0_dielectric,
    scale, anisotropy_t=0, anisotropy=0, thin_film=0) the BRDF given it: as it depends on the material alone, not on the directions, a
    caller may compute it once per material (where no texture or vertex colour varies its inputs)
    rather than for every light and pixel, which saves a table lookup and three divisions per
    evaluation."""
    _check_rungs(diffuse, distribution, geometry, fresnel, energy, coupling, model, metallic_mix)
    if model != "microfacet" or coupling != "albedo" or not (diffuse_lobe and specular_lobe):
        return None
    _, brdf_scaled, diffuse_share_scale = _microfacet_brdf(diffuse_lobe, specular_lobe, diffuse, distribution,
                                                           geometry, fresnel, energy, coupling, metallic_mix,
                                                           anisotropic, iridescent)
    return brdf_scaled, diffuse_share_scale


def _check_rungs(diffuse, distribution, geometry, fresnel, energy, coupling, model, metallic_mix):
    for name, value, allowed in (("diffuse", diffuse, DIFFUSE_MODELS), ("distribution", distribution, DISTRIBUTIONS),
                                 ("geometry", geometry, GEOMETRY_MODELS), ("fresnel", fresnel, FRESNEL_MODELS),
                                 ("energy", energy, ENERGY_MODELS), ("coupling", coupling, COUPLING_MODELS),
                                 ("model", model, MODELS), ("metallic_mix", metallic_mix, METALLIC_MIXES)):
        if value not in allowed:
            raise ValueError(f"unknown {name} model {value!r}; choose one of {allowed}")


@functools.cache
def _microfacet_brdf(diffuse_lobe: bool, specular_lobe: bool, diffuse: str, distribution: str, geometry: str,
                     fresnel: str, energy: str, coupling: str, metallic_mix: str, anisotropic: bool,
                     iridescent: bool):
    """(brdf, brdf_scaled, diffuse_share_scale) of a microfacet rung set (see brdf_for and
    albedo_coupled_brdf_for)."""
    fresnel_term = FRESNEL_TERMS[fresnel]
    exact_fresnel = fresnel == "exact"
    gltf_mix = metallic_mix == "gltf"
    visibility = visibility_for(geometry)
    ndf = distribution_for(distribution)
    multiscatter = energy == "multiscatter" and specular_lobe
    albedo_coupling = coupling == "albedo" and specular_lobe and diffuse_lobe
    fresnel_coupling = coupling == "fresnel" and specular_lobe and diffuse_lobe
    if multiscatter or albedo_coupling:
        lookup, averages = albedo_lookup(distribution, geometry, fresnel)
    else:
        lookup, averages = _no_lookup()

    @wp.func
    def energy_compensation(f0: wp.vec3, e1: float) -> wp.vec3:
        """1 + f0 (1 / E1 - 1) (Fdez-Agüera 2019, as Filament): restores the energy of multiple
        bounces between microfacets."""
        return wp.vec3(1.0) + f0 * (1.0 / e1 - 1.0)

    @wp.func
    def lobe_albedo(f0: wp.vec3, f90: wp.vec3, n_dot: float, roughness: float) -> wp.vec3:
        """E(n.x) = f0 (E1 - Ew) + f90 Ew, times the compensation with multiple scattering."""
        e = lookup(n_dot, roughness)
        out = f0 * (e[0] - e[1]) + f90 * e[1]
        if wp.static(multiscatter):
            out = wp.cw_mul(out, energy_compensation(f0, e[0]))
        return out

    @wp.func
    def mean_lobe_albedo(f0: wp.vec3, f90: wp.vec3, roughness: float) -> wp.vec3:
        """E_avg, the cosine-weighted mean of lobe_albedo over the hemisphere."""
        m = averages(roughness)
        out = f0 * m[0] + f90 * m[1]
        if wp.static(multiscatter):
            out = out + wp.cw_mul(f0, f0) * m[2] + wp.cw_mul(f0, f90) * m[3]
        return out

    @wp.func
    def coupled_lobe(base_color: wp.vec3, metallic: float, specular: float, f0_dielectric: wp.vec3):
        """(f0, f90) of the specular lobe whose albedo the diffuse lobe's share is coupled to: the
        dielectric's largest channel in the "gltf" mix, the mixed lobe in the "f0" mix."""
        if wp.static(gltf_mix):
            return wp.vec3(max_channel(dielectric_specular_f0(f0_dielectric, specular))), wp.vec3(specular)
        return specular_f0(base_color, metallic, specular, f0_dielectric), specular_f90(metallic, specular)

    @wp.func
    def diffuse_share_scale(base_color: wp.vec3, metallic: float, roughness: float, specular: float,
                            f0_dielectric: wp.vec3) -> wp.vec3:
        """1 / (1 - E_avg) per channel, the albedo coupling's normalization (1 without it)."""
        if wp.static(albedo_coupling):
            f0, f90 = coupled_lobe(base_color, metallic, specular, f0_dielectric)
            rest = wp.max(wp.vec3(1.0) - mean_lobe_albedo(f0, f90, roughness), wp.vec3(MIN_DIFFUSE_SHARE))
            return wp.cw_div(wp.vec3(1.0), rest)
        return wp.vec3(1.0)

    @wp.func
    def albedo_share(f0: wp.vec3, f90: wp.vec3, n_dot_v: float, n_dot_l: float, roughness: float,
                     scale: wp.vec3) -> wp.vec3:
        """(1 - E(v))(1 - E(l)) / (1 - E_avg) per channel (Kelemen & Szirmay-Kalos 2001), ``scale``
        = 1 / (1 - E_avg) (diffuse_share_scale)."""
        left_v = wp.max(wp.vec3(1.0) - lobe_albedo(f0, f90, n_dot_v, roughness), wp.vec3(0.0))
        left_l = wp.max(wp.vec3(1.0) - lobe_albedo(f0, f90, n_dot_l, roughness), wp.vec3(0.0))
        return wp.cw_mul(wp.cw_mul(left_v, left_l), scale)

    @wp.func
    def diffuse_term(n_dot_v: float, n_dot_l: float, l_dot_h: float, roughness: float) -> float:
        if wp.static(diffuse == "burley"):
            return Fd_Burley(n_dot_v, n_dot_l, l_dot_h, roughness)
        return Fd_Lambert()

    @wp.func
    def specular_fresnel(base_color: wp.vec3, metallic: float, specular: float, eta: wp.vec3, kappa: wp.vec3,
                         f0_dielectric: wp.vec3, v_dot_h: float, e1: float, thin_film: wp.vec3):
        """(the Fresnel weight of D V, with multiple-scattering compensation, and the Fresnel of
        the lobe above the diffuse one, for the "fresnel" coupling)."""
        f0_d = dielectric_specular_f0(f0_dielectric, specular)
        f90_d = wp.vec3(specular)
        if wp.static(gltf_mix):
            dielectric = fresnel_term(f0_d, f90_d, v_dot_h)
            metal = fresnel_term(base_color, wp.vec3(1.0), v_dot_h)
            if wp.static(exact_fresnel):
                if eta[0] > 0.0:
                    metal = F_Conductor(eta, kappa, v_dot_h)
            if wp.static(iridescent):
                if thin_film[0] > 0.0:
                    film_d = F_Iridescence(1.0, thin_film[1], thin_film[2], wp.min(f0_dielectric, wp.vec3(1.0)),
                                           v_dot_h) * specular
                    film_m = F_Iridescence(1.0, thin_film[1], thin_film[2], base_color, v_dot_h)
                    dielectric = wp.lerp(dielectric, film_d, thin_film[0])
                    metal = wp.lerp(metal, film_m, thin_film[0])
            below = dielectric
            if wp.static(multiscatter):
                dielectric = wp.cw_mul(dielectric, energy_compensation(f0_d, e1))
                metal = wp.cw_mul(metal, energy_compensation(base_color, e1))
            return wp.lerp(dielectric, metal, metallic), below
        f0 = specular_f0(base_color, metallic, specular, f0_dielectric)
        F = fresnel_term(f0, specular_f90(metallic, specular), v_dot_h)
        if wp.static(exact_fresnel):
            if eta[0] > 0.0:
                F = wp.lerp(F_Exact(f0_d, f90_d, v_dot_h), F_Conductor(eta, kappa, v_dot_h), metallic)
        if wp.static(iridescent):
            if thin_film[0] > 0.0:
                F = wp.lerp(F, F_Iridescence(1.0, thin_film[1], thin_film[2], f0, v_dot_h), thin_film[0])
        below = F
        if wp.static(multiscatter):
            F = wp.cw_mul(F, energy_compensation(f0, e1))
        return F, below

    @wp.func
    def brdf_scaled(n: wp.vec3, v: wp.vec3, l: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float,
                    specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3,
                    diffuse_scale: wp.vec3, anisotropy_t: wp.vec3 = wp.vec3(0.0), anisotropy: float = 0.0,
                    thin_film: wp.vec3 = wp.vec3(0.0)) -> wp.vec3:
        n_dot_l = wp.dot(n, l)
        if n_dot_l <= 0.0:
            return wp.vec3(0.0)
        n_dot_v = wp.max(wp.dot(n, v), MIN_COSINE)
        h = safe_normalize(v + l, n)
        out = wp.vec3(0.0)
        if wp.static(specular_lobe):
            n_cross_h = wp.cross(n, h)
            n_dot_h = wp.min(wp.dot(n, h), 1.0)
            v_dot_h = wp.clamp(wp.dot(v, h), 0.0, 1.0)
            alpha = alpha_from_roughness(roughness)
            e1 = float(1.0)
            if wp.static(multiscatter):
                e1 = lookup(n_dot_v, roughness)[0]
            F, below = specular_fresnel(base_color, metallic, specular, eta, kappa, f0_dielectric, v_dot_h, e1,
                                        thin_film)
            D = ndf(alpha, n_dot_h, wp.dot(n_cross_h, n_cross_h))
            V = visibility(n_dot_v, n_dot_l, roughness)
            if wp.static(anisotropic):
                if anisotropy > 0.0:
                    across = wp.cross(n, anisotropy_t)
                    a = anisotropic_alphas(alpha, anisotropy)
                    D = D_GGX_Anisotropic(a[0], a[1], n_dot_h, wp.dot(anisotropy_t, h), wp.dot(across, h))
                    V = V_SmithGGXCorrelated_Anisotropic(a[0], a[1], n_dot_v, n_dot_l, wp.dot(anisotropy_t, v),
                                                         wp.dot(across, v), wp.dot(anisotropy_t, l),
                                                         wp.dot(across, l))
            out = F * (D * V)
            if wp.static(diffuse_lobe):
                share = wp.vec3(1.0)
                if wp.static(fresnel_coupling):
                    if wp.static(gltf_mix):
                        share = wp.vec3(1.0 - max_channel(below))
                    else:
                        share = wp.vec3(1.0) - below
                if wp.static(albedo_coupling):
                    f0, f90 = coupled_lobe(base_color, metallic, specular, f0_dielectric)
                    share = albedo_share(f0, f90, n_dot_v, n_dot_l, roughness, diffuse_scale)
                fd = diffuse_term(n_dot_v, n_dot_l, wp.dot(l, h), roughness)
                out = wp.cw_mul(share, base_color) * ((1.0 - metallic) * fd) + out
        elif wp.static(diffuse_lobe):
            fd = diffuse_term(n_dot_v, n_dot_l, wp.dot(l, h), roughness)
            out = base_color * ((1.0 - metallic) * fd)
        return out

    @wp.func
    def brdf(n: wp.vec3, v: wp.vec3, l: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float,
             specular: float, eta: wp.vec3 = wp.vec3(0.0), kappa: wp.vec3 = wp.vec3(0.0),
             f0_dielectric: wp.vec3 = wp.vec3(DIELECTRIC_F0), anisotropy_t: wp.vec3 = wp.vec3(0.0),
             anisotropy: float = 0.0, thin_film: wp.vec3 = wp.vec3(0.0)) -> wp.vec3:
        if wp.dot(n, l) <= 0.0:
            return wp.vec3(0.0)  # as brdf_scaled does, but before the scale's table lookup
        return brdf_scaled(n, v, l, base_color, metallic, roughness, specular, eta, kappa, f0_dielectric,
                           diffuse_share_scale(base_color, metallic, roughness, specular, f0_dielectric),
                           anisotropy_t, anisotropy, thin_film)

    return brdf, brdf_scaled, diffuse_share_scale


@functools.cache
def legacy_brdf(diffuse_lobe: bool, specular_lobe: bool, model: str):
    """The non-PBR baselines: Lambert plus a normalized Phong or Blinn-Phong lobe (see brdf_for);
    isotropic and without thin films, whatever ``anisotropy`` and ``thin_film`` say."""

    @wp.func
    def brdf(n: wp.vec3, v: wp.vec3, l: wp.vec3, base_color: wp.vec3, metallic: float, roughness: float,
             specular: float, eta: wp.vec3 = wp.vec3(0.0), kappa: wp.vec3 = wp.vec3(0.0),
             f0_dielectric: wp.vec3 = wp.vec3(DIELECTRIC_F0), anisotropy_t: wp.vec3 = wp.vec3(0.0),
             anisotropy: float = 0.0, thin_film: wp.vec3 = wp.vec3(0.0)) -> wp.vec3:
        n_dot_l = wp.dot(n, l)
        if n_dot_l <= 0.0:
            return wp.vec3(0.0)
        c_spec = specular_f0(base_color, metallic, specular, f0_dielectric)
        out = wp.vec3(0.0)
        if wp.static(diffuse_lobe):
            # c_diff (1 - c_spec) keeps c_diff + c_spec <= 1 (Lagarde 2011)
            out = wp.cw_mul(wp.vec3(1.0) - c_spec, base_color) * ((1.0 - metallic) * Fd_Lambert())
        if wp.static(specular_lobe):
            power = blinn_phong_exponent(alpha_from_roughness(roughness))
            if wp.static(model == "phong"):
                r = 2.0 * n_dot_l * n - l
                out = out + c_spec * Fs_Phong(0.25 * power, wp.dot(r, v))
            else:
                out = out + c_spec * Fs_BlinnPhong(power, wp.dot(n, safe_normalize(v + l, n)))
        return out

    return brdf


@functools.cache
def _no_lookup():
    """Placeholders for rungs that use no albedo table (never called: wp.static removes the calls)."""

    @wp.func
    def lookup(n_dot: float, roughness: float) -> wp.vec2:
        return wp.vec2(1.0, 0.0)

    @wp.func
    def averages(roughness: float) -> wp.vec4:
        return wp.vec4(0.0)

    return lookup, averages

