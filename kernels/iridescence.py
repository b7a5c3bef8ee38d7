"""Thin-film iridescence (KHR_materials_iridescence): the Fresnel reflectance of a base under a
dielectric film, with the interference of the light reflected at its two interfaces integrated
over the visible spectrum analytically, after Belcour & Barla 2017 ("A Practical Extension to
Microfacet Theory for the Modeling of Varying Iridescence") in the approximation the extension
gives: Schlick reflectances at both interfaces, polarization ignored, phase shifts 0 or pi, the
series of multiple reflections cut after its second oscillating term."""

import warp as wp

from .microfacet import PI

wp.set_module_options({"enable_backward": False})

# CIE XYZ -> linear Rec. 709 RGB (sRGB primaries, D65).
XYZ_TO_REC709 = wp.constant(wp.mat33(3.2404542, -1.5371385, -0.4985314,
                                     -0.9692660, 1.8760108, 0.0415560,
                                     0.0556434, -0.2040259, 1.0572252))


@wp.func
def thin_film_sensitivity(opd_nm: float, shift: wp.vec3) -> wp.vec3:
    """Linear Rec. 709 RGB of the spectral integral of cos(2 pi opd / lambda + shift) against
    the CIE 1931 matching functions, normalized so that Y = 1 at opd 0 and shift 0: Belcour &
    Barla 2017's Gaussian fits of the matching functions' Fourier transforms (their section 4;
    the constants are theirs)."""
    phase = 2.0 * PI * opd_nm * 1.0e-9
    p2 = phase * phase
    x = 5.4856e-13 * wp.sqrt(2.0 * PI * 4.3278e9) * wp.cos(1.6810e6 * phase + shift[0]) * wp.exp(-4.3278e9 * p2)
    x = x + 9.7470e-14 * wp.sqrt(2.0 * PI * 4.5282e9) * wp.cos(2.2399e6 * phase + shift[0]) * wp.exp(-4.5282e9 * p2)
    y = 4.4201e-13 * wp.sqrt(2.0 * PI * 9.3046e9) * wp.cos(1.7953e6 * phase + shift[1]) * wp.exp(-9.3046e9 * p2)
    z = 5.2481e-13 * wp.sqrt(2.0 * PI * 6.6121e9) * wp.cos(2.2084e6 * phase + shift[2]) * wp.exp(-6.6121e9 * p2)
    return XYZ_TO_REC709 * (wp.vec3(x, y, z) / 1.0685e-7)


@wp.func
def reflectance_from_ior(transmitted: float, incident: float) -> float:
    """Reflectance at normal incidence of an interface between two dielectrics,
    ((n_t - n_i) / (n_t + n_i))^2 (Fresnel 1823)."""
    r = (transmitted - incident) / (transmitted + incident)
    return r * r


@wp.func
def ior_from_reflectance(f0: float) -> float:
    """The IOR against air whose normal-incidence reflectance is f0, (1 + sqrt f0) / (1 - sqrt f0),
    f0 kept below 1 (the extension infers metals' IOR this way too, without extinction)."""
    s = wp.sqrt(wp.clamp(f0, 0.0, 0.9999))
    return (1.0 + s) / (1.0 - s)


@wp.func
def schlick_scalar(f0: float, cos_theta: float) -> float:
    x = wp.clamp(1.0 - cos_theta, 0.0, 1.0)
    x2 = x * x
    return f0 + (1.0 - f0) * (x2 * x2 * x)


@wp.func
def F_Iridescence(outside_ior: float, film_ior: float, thickness_nm: float, base_f0: wp.vec3,
                  cos_theta1: float) -> wp.vec3:
    """Reflectance of a base of normal-incidence reflectance ``base_f0`` under a film of
    ``film_ior`` and ``thickness_nm``, seen from a medium of ``outside_ior`` at cos theta1
    (Belcour & Barla 2017, KHR_materials_iridescence's approximation); total internal reflection
    in the film reflects everything. The optical path difference is 2 n_film d cos theta2, theta2
    the angle inside the film (Belcour & Barla's; the extension's text writes cos theta1). The
    result is clamped to [0, 1] (the extension's sample code clamps below only)."""
    cos1 = wp.clamp(cos_theta1, 0.0, 1.0)
    ratio = outside_ior / film_ior
    sin2_sq = ratio * ratio * (1.0 - cos1 * cos1)
    if sin2_sq >= 1.0:
        return wp.vec3(1.0)
    cos2 = wp.sqrt(1.0 - sin2_sq)
    # outside -> film
    r12 = schlick_scalar(reflectance_from_ior(film_ior, outside_ior), cos1)
    t121 = 1.0 - r12
    phi12 = float(0.0)
    if film_ior < outside_ior:
        phi12 = PI
    phi21 = PI - phi12
    # film -> base, per channel: the mean reflectance over wavelengths (out), the amplitude of the
    # first oscillating term (cm), and the ratio between successive terms (root)
    out = wp.vec3(0.0)
    cm = wp.vec3(0.0)
    root = wp.vec3(0.0)
    phi = wp.vec3(0.0)
    for c in range(3):
        base_ior = ior_from_reflectance(base_f0[c])
        r23 = schlick_scalar(reflectance_from_ior(base_ior, film_ior), cos2)
        phi[c] = phi21
        if base_ior < film_ior:
            phi[c] = phi21 + PI
        r123 = wp.clamp(r12 * r23, 1.0e-5, 0.9999)
        rs = t121 * t121 * r23 / (1.0 - r123)
        out[c] = r12 + rs
        cm[c] = rs - t121
        root[c] = wp.sqrt(r123)
    opd = 2.0 * film_ior * thickness_nm * cos2
    for m in range(1, 3):
        cm = wp.cw_mul(cm, root)
        out = out + 2.0 * wp.cw_mul(cm, thin_film_sensitivity(float(m) * opd, phi * float(m)))
    # the cut series and the colour conversion's negative lobes can leave [0, 1] where both
    # interfaces reflect strongly (about 2% of random films); a reflectance stays a reflectance
    return wp.min(wp.max(out, wp.vec3(0.0)), wp.vec3(1.0))
