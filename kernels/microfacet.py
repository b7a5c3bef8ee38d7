"""The microfacet model's terms (Cook and Torrance 1982; Walter et al. 2007): the normal
distributions D and the masking-shadowing terms in their visibility form V = G / (4 n.l n.v),
one small function per model. The BRDF (kernels/brdf.py) and the albedo tables that compensate
it (kernels/energy.py) both build on them."""

import functools

import warp as wp

wp.set_module_options({"enable_backward": False})

PI = wp.constant(3.14159265358979323846)
# Floor of alpha^2 = roughness^4: keeps D finite at roughness 0 (n.h = 1).
MIN_ALPHA_SQ = wp.constant(1.0e-7)


@wp.func
def alpha_from_roughness(roughness: float) -> float:
    """GGX's alpha from glTF's perceptual roughness, alpha = roughness^2 (Burley 2012; Karis 2013),
    the remapping that makes roughness look about linear. Also called from host code
    (kernels/prefilter.py): Warp then runs this body on the Python float given, in float64."""
    return roughness * roughness


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
    (Karis 2013), divided by 4 n.l n.v: the visibility form (Filament's V).
    With G1(x) = x / (x (1 - k) + k), the n.l and n.v of the denominator cancel exactly, so
    grazing cosines (down to denormals) give no 0/0."""
    r = roughness + 1.0
    k = r * r / 8.0
    return 0.25 / ((n_dot_v * (1.0 - k) + k) * (n_dot_l * (1.0 - k) + k))


@wp.func
def blinn_phong_exponent(alpha: float) -> float:
    """a_p = 2 / alpha^2 - 2, the Blinn-Phong exponent matching GGX's alpha (Walter et al. 2007),
    alpha^2 floored like D_GGX's."""
    return 2.0 / wp.max(alpha * alpha, MIN_ALPHA_SQ) - 2.0


@wp.func
def D_BlinnPhong(alpha: float, n_dot_h: float) -> float:
    """Normalized Blinn-Phong NDF, (a_p + 2) / (2 pi) (n.h)^a_p (Walter et al. 2007)."""
    if n_dot_h <= 0.0:
        return 0.0
    power = blinn_phong_exponent(alpha)
    return (power + 2.0) / (2.0 * PI) * wp.pow(wp.min(n_dot_h, 1.0), power)


@wp.func
def V_Implicit(n_dot_v: float, n_dot_l: float, alpha: float) -> float:
    """The implicit geometry term G = n.l n.v (Hoffman 2010), so G / (4 n.l n.v) = 1/4."""
    return 0.25


@wp.func
def V_SmithGGXSeparable(n_dot_v: float, n_dot_l: float, alpha: float) -> float:
    """Exact separable Smith G1(v) G1(l) for GGX (Walter et al. 2007) over 4 n.l n.v, with
    G1(x) = 2x / (x + sqrt(a^2 + (1 - a^2) x^2)) so that the cosines cancel."""
    a2 = wp.max(alpha * alpha, MIN_ALPHA_SQ)
    gv = n_dot_v + wp.sqrt(a2 + (1.0 - a2) * n_dot_v * n_dot_v)
    gl = n_dot_l + wp.sqrt(a2 + (1.0 - a2) * n_dot_l * n_dot_l)
    return 1.0 / (gv * gl)


@wp.func
def V_SmithGGXCorrelated(n_dot_v: float, n_dot_l: float, alpha: float) -> float:
    """Height-correlated Smith G2 for GGX (Heitz 2014) over 4 n.l n.v (Filament's form)."""
    a2 = wp.max(alpha * alpha, MIN_ALPHA_SQ)
    lambda_v = n_dot_l * wp.sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2)
    lambda_l = n_dot_v * wp.sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2)
    return 0.5 / (lambda_v + lambda_l)


@wp.func
def V_SmithGGXCorrelatedFast(n_dot_v: float, n_dot_l: float, alpha: float) -> float:
    """Hammon's linear approximation of the height-correlated Smith term (GDC 2017; Filament)."""
    a = wp.max(alpha, wp.sqrt(MIN_ALPHA_SQ))
    return 0.5 / (n_dot_l * (n_dot_v * (1.0 - a) + a) + n_dot_v * (n_dot_l * (1.0 - a) + a))


DISTRIBUTIONS = ("ggx", "blinn_phong")
GEOMETRY_MODELS = ("implicit", "schlick_ggx", "smith_separable", "smith_correlated", "smith_correlated_fast")
_VISIBILITY = {"implicit": V_Implicit, "smith_separable": V_SmithGGXSeparable,
               "smith_correlated": V_SmithGGXCorrelated, "smith_correlated_fast": V_SmithGGXCorrelatedFast}


@functools.cache
def visibility_for(geometry: str):
    """V(n.v, n.l, roughness) of a geometry rung (Schlick-GGX is defined on roughness, the others
    on alpha_from_roughness)."""
    v_of_alpha = _VISIBILITY.get(geometry, V_Implicit)

    @wp.func
    def visibility(n_dot_v: float, n_dot_l: float, roughness: float) -> float:
        if wp.static(geometry == "schlick_ggx"):
            return V_SmithSchlickGGX(n_dot_v, n_dot_l, roughness)
        return v_of_alpha(n_dot_v, n_dot_l, alpha_from_roughness(roughness))

    return visibility


@functools.cache
def distribution_for(distribution: str):
    """D(alpha, n.h, |n x h|^2) of a distribution rung."""

    @wp.func
    def ndf(alpha: float, n_dot_h: float, sin_sq: float) -> float:
        if wp.static(distribution == "blinn_phong"):
            return D_BlinnPhong(alpha, n_dot_h)
        return D_GGX(alpha, n_dot_h, sin_sq)

    return ndf
