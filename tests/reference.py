"""Float64 NumPy references written from the formulas in the seeds and papers (not from the kernels)."""

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


def brdf(n, v, l, base, metallic, roughness, specular):
    """Lambert + Cook-Torrance with metallic-roughness and KHR_materials_specular's strength."""
    h = normalize(v + l)
    nl = np.sum(n * l, -1)
    nv = np.sum(n * v, -1)
    nh = np.sum(n * h, -1)
    vh = np.sum(v * h, -1)
    m = metallic[..., None]
    s = specular[..., None]
    f0 = (1 - m) * 0.04 * s + m * base
    f90 = (1 - m) * s + m
    F = f_schlick(f0, f90, vh)
    D = d_ggx(nh, roughness**2)
    G = g_schlick_ggx(nv, nl, roughness)
    spec = F * (D * G / (4 * nl * nv))[..., None]
    diffuse = (1 - F) * (1 - m) * base / np.pi
    return diffuse + spec


def srgb_encode(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
