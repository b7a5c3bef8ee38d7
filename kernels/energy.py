"""Directional albedo of the specular lobe, integrated by a Warp kernel: the tables that
multiple-scattering compensation and the energy-conserving diffuse coupling need (Kelemen &
Szirmay-Kalos 2001; Kulla & Conty 2017; Fdez-Agüera 2019).

For a Fresnel term linear in (f0, f90), F = f0 (1 - w(v.h)) + f90 w(v.h) (Schlick: w = (1 - v.h)^5),
the albedo splits as Karis' DFG table does:

    E(mu, f0, f90) = f0 (E1 - Ew) + f90 Ew,  E1 = integral of D V n.l,  Ew = integral of D V n.l w,

so two numbers per (mu = n.v, roughness) serve every material.
"""

from concurrent.futures import ThreadPoolExecutor
import functools
import os
import threading
from typing import NamedTuple

import numpy as np
import warp as wp

from .microfacet import D_GGX, alpha_from_roughness, distribution_for, visibility_for
from .loading import CPU_BLOCK_DIM, load_for_cpu

wp.set_module_options({"enable_backward": False})

# Rows: n.v = (i + 0.5) / SIZE; columns: roughness = j / (SIZE - 1). 32 rows resolve the steep
# rise of Fresnel reflectance near grazing views, which fewer rows blur (the furnace tests see it).
ALBEDO_TABLE_SIZE = 32
ALBEDO_SAMPLES = 8192
# Points of the midpoint rule for the cosine-weighted averages over n.l (of the interpolated table).
AVERAGE_POINTS = 4096


@wp.func
def fresnel_weight(shape: int, v_dot_h: float) -> float:
    """w(v.h) of F = f0 (1 - w) + f90 w: 0 for "none", Schlick's (1 - v.h)^5, or the spherical-Gaussian fit."""
    if shape == 0:
        return 0.0
    if shape == 1:
        x = 1.0 - v_dot_h
        return x * x * x * x * x
    return wp.pow(2.0, (-5.55473 * v_dot_h - 6.98316) * v_dot_h)


# The exact dielectric Fresnel is not linear in f0: its albedo uses Schlick's split, which is
# close to it over dielectrics' f0.
FRESNEL_SHAPES = {"none": 0, "schlick": 1, "exact": 1, "spherical_gaussian": 2}


@wp.func
def radical_inverse_base2(k: int) -> float:
    """Van der Corput's radical inverse of k >= 0 in base 2, the second Hammersley coordinate: k's
    bits mirrored about the binary point (exact in float32 for k < 2^24)."""
    bits = k
    weight = float(0.5)
    out = float(0.0)
    while bits > 0:
        if bits % 2 == 1:
            out += weight
        bits = bits / 2
        weight *= 0.5
    return out


@functools.cache
def albedo_kernel(distribution: str, geometry: str):
    """E1 and Ew at each (n.v, roughness) by importance sampling GGX half vectors (Walter et al.
    2007) at the points of a Hammersley set (deterministic, and far less noisy than random points)."""
    visibility = visibility_for(geometry)
    ndf = distribution_for(distribution)

    @wp.kernel(enable_backward=False, module="unique")
    def integrate(samples: int, shape: int, first_row: int, out: wp.array3d(dtype=float)):
        row, j = wp.tid()
        i = first_row + row
        size = out.shape[0]
        n_dot_v = (float(i) + 0.5) / float(size)
        roughness = float(j) / float(size - 1)
        alpha = wp.max(alpha_from_roughness(roughness), 3.1622776e-4)
        a2 = alpha * alpha
        v = wp.vec3(wp.sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v)
        total = float(0.0)
        weighted = float(0.0)
        for k in range(samples):
            u1 = (float(k) + 0.5) / float(samples)
            phi = 2.0 * 3.14159265358979 * radical_inverse_base2(k)
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
                value = d * visibility(n_dot_v, n_dot_l, roughness) * n_dot_l / pdf
                total += value
                weighted += value * fresnel_weight(shape, v_dot_h)
        out[i, j, 0] = total / float(samples)
        out[i, j, 1] = weighted / float(samples)

    return integrate


class AlbedoTables(NamedTuple):
    """Row-major tuples (hashable, so kernels can be specialized on them).

    ``albedo``: SIZE x 2 SIZE, E1 at column 2j and Ew at 2j + 1 (row i: n.v = (i + 0.5) / SIZE).
    ``averages``: 4 x SIZE, per roughness column the cosine-weighted hemispherical averages
    2 integral of x(mu) mu dmu of x = E1 - Ew, Ew, (E1 - Ew)(1/E1 - 1), Ew (1/E1 - 1), so that
    E_avg = f0 <E1 - Ew> + f90 <Ew> single-scattering, plus f0^2 <..> + f0 f90 <..> with
    multiple-scattering compensation. They average the table as bilinear_albedo interpolates it.
    """

    albedo: tuple
    averages: tuple
    size: int


def interpolate_rows(table: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """table[:, j] at n.v = mu, linearly between row centres and clamped beyond them: the
    interpolation the kernels' lookup does."""
    size = table.shape[0]
    x = np.clip(mu * size - 0.5, 0.0, size - 1.0)
    i0 = np.minimum(x.astype(int), size - 2)
    f = (x - i0)[:, None]
    return table[i0] * (1.0 - f) + table[i0 + 1] * f


def integrated_albedo(distribution: str, geometry: str, fresnel: str, cache_dir: str | None = None) -> np.ndarray:
    """The integrating kernel's (SIZE, SIZE, 2) float32 output for a rung triple. Kept in
    ``cache_dir`` (default: Warp's kernel cache directory), named by the kernel's module hash
    (which covers its code and every function it calls) and its inputs, so that only the first
    process pays for the integration; computed in row bands on every core where no valid copy is
    there."""
    size = ALBEDO_TABLE_SIZE
    kernel = albedo_kernel(distribution, geometry)
    shape = FRESNEL_SHAPES[fresnel]
    wp.init()
    key = f"{kernel.module.get_module_hash(CPU_BLOCK_DIM).hex()[:16]}_{shape}_{size}_{ALBEDO_SAMPLES}"
    path = os.path.join(cache_dir or wp.config.kernel_cache_dir or "", f"pbrwarp_albedo_{key}.npy")
    try:
        kept = np.load(path, allow_pickle=False)
        if kept.shape == (size, size, 2) and kept.dtype == np.float32 and np.all(np.isfinite(kept)):
            return kept
    except (OSError, ValueError):
        pass  # absent, unreadable or damaged: computed again
    out = wp.zeros((size, size, 2), dtype=float, device="cpu")
    workers = min(os.cpu_count() or 1, size)
    rows = -(-size // workers)

    def band(first_row):
        wp.launch(kernel, dim=(min(rows, size - first_row), size), device="cpu",
                  inputs=[ALBEDO_SAMPLES, shape, first_row, out])

    load_for_cpu(kernel)
    with ThreadPoolExecutor(workers) as pool:
        list(pool.map(band, range(0, size, rows)))
    raw = out.numpy()
    try:  # written whole under another name, then renamed: readers never see part of it
        partial = f"{path}.{os.getpid()}.{threading.get_ident()}.tmp"
        with open(partial, "wb") as file:
            np.save(file, raw, allow_pickle=False)
        os.replace(partial, path)
    except OSError:
        pass  # a read-only cache: computed again next time
    return raw


@functools.cache
def albedo_tables(distribution: str, geometry: str, fresnel: str) -> AlbedoTables:
    """The tables of a rung triple; computed once per process from integrated_albedo."""
    size = ALBEDO_TABLE_SIZE
    raw = integrated_albedo(distribution, geometry, fresnel).astype(np.float64)
    e1 = np.clip(raw[..., 0], 1e-3, 1.0)
    ew = np.clip(raw[..., 1], 0.0, e1)
    mu = (np.arange(AVERAGE_POINTS) + 0.5) / AVERAGE_POINTS
    e1_mu, ew_mu = interpolate_rows(e1, mu), interpolate_rows(ew, mu)
    loss = 1.0 / e1_mu - 1.0
    weights = (2.0 * mu / AVERAGE_POINTS)[:, None]
    averages = np.stack([((e1_mu - ew_mu) * weights).sum(0), (ew_mu * weights).sum(0),
                         ((e1_mu - ew_mu) * loss * weights).sum(0), (ew_mu * loss * weights).sum(0)])
    albedo = np.stack([e1, ew], axis=-1).reshape(size, 2 * size)
    return AlbedoTables(tuple(float(x) for x in albedo.ravel()), tuple(float(x) for x in averages.ravel()), size)
