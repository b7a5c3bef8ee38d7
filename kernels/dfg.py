"""The split-sum DFG table (Karis 2013, "Real Shading in Unreal Engine 4"): the specular lobe's
directional albedo under a white environment, split by Schlick's Fresnel weight so that

    integral of f_spec(v, l) n.l dl  ~=  f0 A(n.v, roughness) + f90 B(n.v, roughness),

A = integral of (1 - (1 - v.h)^5) G_vis, B = integral of (1 - v.h)^5 G_vis over GGX half vectors,
G_vis = G v.h / (n.h n.v), with Smith/Schlick-GGX G and k = roughness^2 / 2, the remapping for
image-based lighting (Karis 2013's k_IBL = alpha^2 / 2, there with alpha = roughness).
"""

import functools
import os
import tempfile

import numpy as np
import warp as wp

from .direction_sampling import G1_SmithGGX, sample_ggx_vndf
from .energy import radical_inverse_base2
from .microfacet import alpha_from_roughness

wp.set_module_options({"enable_backward": False})

# Rows: n.v = (i + 0.5) / SIZE; columns: roughness = j / (SIZE - 1) (the layout of energy.py's
# albedo table).
DFG_TABLE_SIZE = 32
DFG_SAMPLES = 4096


@wp.func
def G_SchlickGGX_IBL(n_dot_v: float, n_dot_l: float, roughness: float) -> float:
    """Smith's separable G with Schlick-GGX and k = roughness^2 / 2, for image-based lighting
    (Karis 2013)."""
    k = alpha_from_roughness(roughness) / 2.0
    return n_dot_v / (n_dot_v * (1.0 - k) + k) * n_dot_l / (n_dot_l * (1.0 - k) + k)


@wp.kernel
def integrate_dfg(samples: int, out: wp.array2d(dtype=wp.vec2)):
    """(A, B) at each (n.v, roughness) by sampling the GGX normals visible from v (Heitz 2018) at
    Hammersley points: the weight f n.l / pdf = G / G1(v) stays below 1, where sampling D n.h
    (Karis' listing) has weights that blow up at grazing n.v, where it then converges slowly."""
    i, j = wp.tid()
    size = out.shape[0]
    n_dot_v = (float(i) + 0.5) / float(size)
    roughness = float(j) / float(out.shape[1] - 1)
    alpha = alpha_from_roughness(roughness)
    v = wp.vec3(wp.sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v)
    masking = G1_SmithGGX(n_dot_v, alpha)
    a = float(0.0)
    b = float(0.0)
    for k in range(samples):
        u = wp.vec2((float(k) + 0.5) / float(samples), radical_inverse_base2(k))
        h = sample_ggx_vndf(v, alpha, u)
        v_dot_h = wp.dot(v, h)
        n_dot_l = 2.0 * v_dot_h * h[2] - n_dot_v
        if n_dot_l > 0.0:
            weight = G_SchlickGGX_IBL(n_dot_v, n_dot_l, roughness) / masking
            x = 1.0 - v_dot_h
            fc = x * x * x * x * x
            a += (1.0 - fc) * weight
            b += fc * weight
    out[i, j] = wp.vec2(a, b) / float(samples)


# Version of the table's integrator, part of its cache file's name: bump it when the integral changes.
DFG_TABLE_VERSION = 1


@functools.cache
def dfg_table(size: int = DFG_TABLE_SIZE, samples: int = DFG_SAMPLES) -> wp.array2d:
    """The (size, size) table of (A, B): integrated once (``samples`` per cell) and cached on disk
    beside Warp's kernel cache, so later processes only read it."""
    wp.init()  # sets the kernel cache directory
    path = os.path.join(wp.config.kernel_cache_dir, f"pbrwarp_dfg_v{DFG_TABLE_VERSION}_{size}x{size}_{samples}.npy")
    try:
        table = np.load(path)
        if table.shape == (size, size, 2) and np.all(np.isfinite(table)):
            return wp.array(table, dtype=wp.vec2, device="cpu")
    except (OSError, ValueError):
        pass
    out = wp.zeros((size, size), dtype=wp.vec2, device="cpu")
    wp.launch(integrate_dfg, dim=(size, size), device="cpu", inputs=[samples, out])
    save_atomically(path, out.numpy())
    return out


def save_atomically(path: str, table: np.ndarray) -> None:
    """Write ``table`` where concurrent readers see the whole file or none (a read-only cache dir
    is not an error: the table is then recomputed by every process)."""
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd, partial = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".npy.partial")
        with os.fdopen(fd, "wb") as f:
            np.save(f, table)
        os.replace(partial, path)
    except OSError:
        pass


@wp.func
def dfg_lookup(table: wp.array2d(dtype=wp.vec2), n_dot_v: float, roughness: float) -> wp.vec2:
    """(A, B) at (n.v, roughness), bilinear between cell centres and clamped beyond them."""
    rows = table.shape[0]
    columns = table.shape[1]
    x = wp.clamp(n_dot_v * float(rows) - 0.5, 0.0, float(rows - 1))
    y = wp.clamp(roughness, 0.0, 1.0) * float(columns - 1)
    i0 = wp.min(int(x), rows - 2)
    j0 = wp.min(int(y), columns - 2)
    fx = x - float(i0)
    fy = y - float(j0)
    top = table[i0, j0] * (1.0 - fy) + table[i0, j0 + 1] * fy
    bottom = table[i0 + 1, j0] * (1.0 - fy) + table[i0 + 1, j0 + 1] * fy
    return top * (1.0 - fx) + bottom * fx
