"""Float64 NumPy references written from the formulas of the papers the kernels cite (not from the kernels)."""

import numpy as np


def normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def d_ggx(n_dot_h, alpha):
    """Trowbridge-Reitz / GGX: alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)."""
    a2 = alpha**2
    return a2 / (np.pi * (n_dot_h**2 * (a2 - 1.0) + 1.0) ** 2)


def g_schlick_ggx(n_dot_v, n_dot_l, roughness):
    """Smith with Schlick-GGX, k = (roughness + 1)^2 / 8."""
    k = (roughness + 1.0) ** 2 / 8.0

    def g1(x):
        return x / (x * (1.0 - k) + k)

    return g1(n_dot_v) * g1(n_dot_l)


def f_schlick(f0, f90, v_dot_h):
    return f0 + (f90 - f0) * (1.0 - v_dot_h)[..., None] ** 5


def dielectric_f0(ior, specular_color, specular):
    """KHR_materials_ior and _specular: min(((ior - 1) / (ior + 1))^2 specularColor, 1) specular."""
    return np.minimum(((ior - 1) / (ior + 1))[..., None] ** 2 * specular_color, 1.0) * specular[..., None]


def brdf(n, v, l, base, metallic, roughness, specular, share=None, f0_d=None):
    """Lambert + Cook-Torrance with metallic-roughness, f0 = mix(f0_d, base, metallic), f0_d the
    dielectric's f0 (default 0.04 specular, glTF's IOR 1.5; see dielectric_f0) and
    f90 = mix(specular, 1, metallic) (Karis 2013; KHR_materials_specular).
    ``share(f0, f90, n.v, n.l, roughness)`` is the diffuse lobe's share of light; None is the
    1 - F(v.h)."""
    h = normalize(v + l)
    nl = np.sum(n * l, -1)
    nv = np.sum(n * v, -1)
    nh = np.sum(n * h, -1)
    vh = np.sum(v * h, -1)
    m = metallic[..., None]
    s = specular[..., None]
    if f0_d is None:
        f0_d = 0.04 * s
    f0 = (1 - m) * f0_d + m * base
    f90 = (1 - m) * s + m
    F = f_schlick(f0, f90, vh)
    D = d_ggx(nh, roughness**2)
    G = g_schlick_ggx(nv, nl, roughness)
    spec = F * (D * G / (4 * nl * nv))[..., None]
    k = 1 - F if share is None else share(f0, f90, nv, nl, roughness)
    diffuse = k * (1 - m) * base / np.pi
    return diffuse + spec


def gltf_brdf(n, v, l, base, metallic, roughness, specular, ior, specular_color, share=None):
    """glTF 2.0's material, Appendix B, with KHR_materials_ior and KHR_materials_specular:
    mix(dielectric_brdf, metal_brdf, metallic), where
    metal_brdf = specular_brdf (base + (1 - base)(1 - v.h)^5),
    dielectric_brdf = F_d specular_brdf + k diffuse_brdf, F_d = mix(f0_d, specular, (1 - v.h)^5),
    f0_d = dielectric_f0(ior, specular_color, specular), k = 1 - max_value(F_d), and
    specular_brdf = D G / (4 n.l n.v) (GGX, Smith/Schlick-GGX), diffuse_brdf = base / pi.
    ``share(f0, f90, n.v, n.l, roughness)``, when given, replaces k, called with the scalar
    f0 = max_value(f0_d) and f90 = specular."""
    h = normalize(v + l)
    nl, nv, nh, vh = (np.sum(a * b, -1) for a, b in ((n, l), (n, v), (n, h), (v, h)))
    m = metallic[..., None]
    s = specular[..., None]
    f0_d = dielectric_f0(ior, specular_color, specular)
    fresnel_d = f_schlick(f0_d, s, vh)
    fresnel_m = f_schlick(base, 1.0, vh)
    specular_brdf = (d_ggx(nh, roughness**2) * g_schlick_ggx(nv, nl, roughness) / (4 * nl * nv))[..., None]
    if share is None:
        k = 1 - fresnel_d.max(-1, keepdims=True)
    else:
        k = share(f0_d.max(-1, keepdims=True), s, nv, nl, roughness)
    dielectric = fresnel_d * specular_brdf + k * base / np.pi
    metal = fresnel_m * specular_brdf
    return (1 - m) * dielectric + m * metal


def ggx_lobe_albedo(n_dot_v, roughness, samples=200_000, seed=5):
    """(E1, Ew, standard errors) of the Schlick-GGX specular lobe at n.v: the integrals of
    D G / (4 n.l n.v) n.l over the hemisphere with F = 1 and with F = (1 - v.h)^5, by sampling
    GGX half vectors (pdf D n.h / (4 v.h), Walter et al. 2007), whose weight is G v.h / (n.v n.h)."""
    rng = np.random.default_rng(seed)
    a2 = max(roughness**4, 1e-7)
    u1, u2 = rng.random(samples), rng.random(samples)
    cos_h = np.sqrt((1 - u1) / (1 + (a2 - 1) * u1))
    sin_h = np.sqrt(1 - cos_h**2)
    h = np.stack([sin_h * np.cos(2 * np.pi * u2), sin_h * np.sin(2 * np.pi * u2), cos_h], -1)
    v = np.array([np.sqrt(1 - n_dot_v**2), 0.0, n_dot_v])
    v_dot_h = h @ v
    n_dot_l = 2 * v_dot_h * cos_h - n_dot_v
    ok = (n_dot_l > 0) & (v_dot_h > 0)
    weight = np.where(ok, g_schlick_ggx(n_dot_v, np.maximum(n_dot_l, 1e-300), roughness) * v_dot_h / (n_dot_v * cos_h), 0)
    weighted = weight * np.clip(1 - v_dot_h, 0, 1) ** 5
    return weight.mean(), weighted.mean(), weight.std() / np.sqrt(samples), weighted.std() / np.sqrt(samples)


def srgb_encode(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
