"""Single-scattering directional albedo of the specular lobe, integrated by a Warp kernel: the
table multiple-scattering energy compensation needs (Kulla & Conty 2017; Fdez-Agüera 2019)."""

import functools

import numpy as np
import warp as wp

from .brdf import D_GGX, distribution_for, visibility_for

wp.set_module_options({"enable_backward": False})

# Rows: n.v = (i + 0.5) / SIZE; columns: roughness = j / (SIZE - 1).
ALBEDO_TABLE_SIZE = 16
ALBEDO_SAMPLES = 8192


@functools.cache
def albedo_kernel(distribution: str, geometry: str):
    """E(n.v, roughness) = integral of D V n.l over the hemisphere with F = 1, by importance
    sampling GGX half vectors (Walter et al. 2007) with a fixed seed."""
    visibility = visibility_for(geometry)
    ndf = distribution_for(distribution)

    @wp.kernel(enable_backward=False, module="unique")
    def integrate(samples: int, out: wp.array2d(dtype=float)):
        i, j = wp.tid()
        size = out.shape[0]
        n_dot_v = (float(i) + 0.5) / float(size)
        roughness = float(j) / float(size - 1)
        alpha = wp.max(roughness * roughness, 3.1622776e-4)
        a2 = alpha * alpha
        v = wp.vec3(wp.sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v)
        state = wp.rand_init(9871, i * size + j)
        total = float(0.0)
        for _ in range(samples):
            u1 = wp.randf(state)
            phi = 2.0 * 3.14159265358979 * wp.randf(state)
            cos_h = wp.sqrt((1.0 - u1) / (1.0 + (a2 - 1.0) * u1))
            sin_h = wp.sqrt(wp.max(0.0, 1.0 - cos_h * cos_h))
            h = wp.vec3(sin_h * wp.cos(phi), sin_h * wp.sin(phi), cos_h)
            v_dot_h = wp.dot(v, h)
            l = 2.0 * v_dot_h * h - v
            n_dot_l = l[2]
            if n_dot_l > 0.0 and v_dot_h > 0.0:
                sampled_d = D_GGX(alpha, cos_h, sin_h * sin_h)
                pdf = sampled_d * cos_h / (4.0 * v_dot_h)
                d = ndf(alpha, cos_h, sin_h * sin_h)
                total += d * visibility(n_dot_v, n_dot_l, roughness) * n_dot_l / pdf
        out[i, j] = total / float(samples)

    return integrate


@functools.cache
def specular_albedo(distribution: str, geometry: str) -> tuple:
    """The table, row-major, as a tuple (hashable, so kernels can be specialized on it); computed
    once per process and rung pair (about 0.1 s plus the kernel's first compile)."""
    out = wp.zeros((ALBEDO_TABLE_SIZE, ALBEDO_TABLE_SIZE), dtype=float, device="cpu")
    wp.launch(albedo_kernel(distribution, geometry), dim=out.shape, inputs=[ALBEDO_SAMPLES, out], device="cpu")
    table = np.clip(out.numpy(), 1e-3, 1.0)
    return tuple(float(x) for x in table.ravel())
