"""KHR_materials_sheen: a layer of fibres over the material, the "Charlie" sheen of Estevez &
Kulla 2017 ("Production Friendly Microfacet Sheen BRDF"), layered by albedo scaling.

    f = sheen_color D_Charlie V_Charlie + material min(1 - m E(n.v), 1 - m E(n.l)),

m = max(sheen_color), alpha = sheen_roughness^2 (the extension's mapping) and E(n.x, roughness)
the sheen lobe's directional albedo, integrated once numerically into a table (like the DFG
table of kernels/dfg.py) and compiled into the kernel. The base keeps what the fibres leave, so
a white base under a white sheen reflects at most what it receives.

Under environment light the sheen reflects sheen_color E(n.v) times the irradiance over pi (the
lobe's directional albedo times the cosine-weighted mean of the environment, exact for a uniform
one), and the material below is scaled by 1 - m E(n.v), the extension's simplified scaling."""

import functools
import os

import numpy as np
import warp as wp

from .brdf import max_channel, static_table
from .dfg import save_atomically
from .ibl import EnvironmentData, environment_irradiance
from .microfacet import PI
from .robust import MIN_COSINE, safe_normalize
from .scene_data import MaterialData, SceneData
from .texture_coords import SurfaceUV, no_texture

wp.set_module_options({"enable_backward": False})

# Floor of the Charlie alpha (sheen_roughness^2): keeps D's exponent 1 / (2 alpha) and its peak
# (2 + 1 / alpha) / (2 pi) finite in float32 at roughness 0.
MIN_SHEEN_ALPHA = wp.constant(1.0e-4)


@wp.func
def sheen_alpha(roughness: float) -> float:
    """The Charlie distribution's alpha, sheen_roughness^2 (KHR_materials_sheen), floored."""
    return wp.max(roughness * roughness, MIN_SHEEN_ALPHA)


@wp.func
def D_Charlie(alpha: float, n_dot_h: float) -> float:
    """The "Charlie" fibre distribution, (2 + 1/alpha) sin(theta_h)^(1/alpha) / (2 pi)
    (Estevez & Kulla 2017): normalized so that the projected area of the fibres is 1."""
    sin_sq = wp.max(1.0 - n_dot_h * n_dot_h, 0.0)
    inv_alpha = 1.0 / alpha
    return (2.0 + inv_alpha) * wp.pow(sin_sq, 0.5 * inv_alpha) / (2.0 * PI)


@wp.func
def L_CharlieFit(x: float, alpha: float) -> float:
    """The fitted exponent of the Charlie masking term, a / (1 + b x^c) + d x + e, its five
    coefficients interpolated in (1 - alpha)^2 between the fits at alpha = 0 and 1 (Estevez &
    Kulla 2017, Table 1)."""
    t = (1.0 - alpha) * (1.0 - alpha)
    a = wp.lerp(21.5473, 25.3245, t)
    b = wp.lerp(3.82987, 3.32435, t)
    c = wp.lerp(0.19823, 0.16801, t)
    d = wp.lerp(-1.97760, -1.27393, t)
    e = wp.lerp(-4.32054, -4.85967, t)
    return a / (1.0 + b * wp.pow(x, c)) + d * x + e


@wp.func
def Lambda_Charlie(cos_theta: float, alpha: float) -> float:
    """Smith's Lambda of the Charlie distribution from the fit, mirrored about 1/2 above it so
    that it falls to 0 at normal incidence (Estevez & Kulla 2017)."""
    x = wp.abs(cos_theta)
    if x < 0.5:
        return wp.exp(L_CharlieFit(x, alpha))
    return wp.exp(2.0 * L_CharlieFit(0.5, alpha) - L_CharlieFit(1.0 - x, alpha))


@wp.func
def V_Charlie(n_dot_v: float, n_dot_l: float, alpha: float) -> float:
    """The Charlie visibility G / (4 n.l n.v), G = 1 / (1 + Lambda(v) + Lambda(l)), the
    height-correlated Smith form (Estevez & Kulla 2017)."""
    return 1.0 / ((1.0 + Lambda_Charlie(n_dot_v, alpha) + Lambda_Charlie(n_dot_l, alpha)) * (4.0 * n_dot_v * n_dot_l))


@wp.func
def charlie_lobe(n_dot_v: float, n_dot_l: float, n_dot_h: float, roughness: float) -> float:
    """D_Charlie V_Charlie, the sheen BRDF of a white sheen colour."""
    alpha = sheen_alpha(roughness)
    return D_Charlie(alpha, n_dot_h) * V_Charlie(n_dot_v, n_dot_l, alpha)


# The albedo table: rows n.v = (i + 0.5) / SIZE, columns roughness = j / (SIZE - 1) (dfg.py's layout).
SHEEN_TABLE_SIZE = 32
# Midpoint quadrature over half vectors: rows in cos(theta_h), columns in phi_h over [0, pi] (the
# integrand is even in phi_h). Fine enough in cos(theta_h) for the narrowest lobe, whose half
# vectors lie within ~sqrt(alpha) = 0.01 of the tangent plane: five rows across it.
SHEEN_QUADRATURE = (512, 64)
SHEEN_TABLE_VERSION = 1


@wp.kernel
def integrate_sheen_albedo(cos_steps: int, phi_steps: int, out: wp.array2d(dtype=float)):
    """E(n.v, roughness) = integral over l of D V n.l, as an integral over half vectors h with
    dl = 4 (v.h) dh, by the midpoint rule in (cos theta_h, phi_h)."""
    i, j = wp.tid()
    n_dot_v = (float(i) + 0.5) / float(out.shape[0])
    roughness = float(j) / float(out.shape[1] - 1)
    v = wp.vec3(wp.sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v)
    cell = (1.0 / float(cos_steps)) * (PI / float(phi_steps))
    total = float(0.0)
    for a in range(cos_steps):
        cos_h = (float(a) + 0.5) / float(cos_steps)
        sin_h = wp.sqrt(1.0 - cos_h * cos_h)
        row = float(0.0)
        for b in range(phi_steps):
            phi = (float(b) + 0.5) * PI / float(phi_steps)
            h = wp.vec3(sin_h * wp.cos(phi), sin_h * wp.sin(phi), cos_h)
            v_dot_h = wp.dot(v, h)
            n_dot_l = 2.0 * v_dot_h * cos_h - n_dot_v
            if v_dot_h > 0.0 and n_dot_l > 0.0:
                row += charlie_lobe(n_dot_v, n_dot_l, cos_h, roughness) * 4.0 * v_dot_h * n_dot_l
        total += row
    out[i, j] = 2.0 * total * cell


@functools.cache
def sheen_albedo_table(size: int = SHEEN_TABLE_SIZE, quadrature: tuple = SHEEN_QUADRATURE) -> np.ndarray:
    """The (size, size) table of E(n.v, roughness), integrated once and cached on disk beside
    Warp's kernel cache (as the DFG table). The fitted Lambda makes E exceed 1 at grazing views
    of smooth sheens (n.v < 0.05, roughness < 0.3: up to 2.4 at n.v = 1/64, roughness 0); the
    table the kernels use (sheen_for) clamps it to 1, so that the material below keeps a
    non-negative share."""
    wp.init()
    path = os.path.join(wp.config.kernel_cache_dir,
                        f"pbrwarp_sheen_v{SHEEN_TABLE_VERSION}_{size}x{size}_{quadrature[0]}x{quadrature[1]}.npy")
    try:
        table = np.load(path)
        if table.shape == (size, size) and np.all(np.isfinite(table)):
            return table
    except (OSError, ValueError):
        pass
    out = wp.zeros((size, size), dtype=float, device="cpu")
    wp.launch(integrate_sheen_albedo, dim=(size, size), device="cpu", inputs=[quadrature[0], quadrature[1], out])
    table = out.numpy()
    save_atomically(path, table)
    return table


@wp.struct
class Sheen:
    """The sheen at a surface point seen from v: its colour, perceptual roughness, the normal
    it lies on, and m E(n.v) (m = max(colour)), the share of the view's light it keeps from the
    material below."""

    color: wp.vec3
    roughness: float
    normal: wp.vec3
    taken_v: float


@functools.cache
def sheen_for(texture=None):
    """(sheen_at, sheen_layer, sheen_brdf, sheen_scaling, sheen_environment, sheen_albedo);
    ``texture``, the render kernel's lookup texture(scene, index, uv) (kernels/texture_coords.py
    texture_lookups), compiles in the sheen colour (RGB) and roughness (alpha) textures; None
    leaves them out.

    - sheen_at(scene, mat, uv, n, v) -> Sheen: the material's sheen at a hit.
    - sheen_layer(color, roughness, n, v) -> Sheen: the sheen of these inputs.
    - sheen_brdf(sheen, v, l) -> color D V, 0 where n.l <= 0.
    - sheen_scaling(sheen, l) -> min(1 - m E(n.v), 1 - m E(n.l)), the material's weight below.
    - sheen_environment(env, sheen, below) -> ``below`` (the material's environment term) times
      1 - m E(n.v), plus color E(n.v) irradiance(n) / pi.
    - sheen_albedo(n.x, roughness) -> E, bilinear in the table (clamped to 1)."""
    textured = texture is not None
    lookup = texture if textured else no_texture
    size = SHEEN_TABLE_SIZE
    entry = static_table(tuple(np.minimum(sheen_albedo_table(), 1.0).reshape(-1)))

    @wp.func
    def sheen_albedo(n_dot: float, roughness: float) -> float:
        x = wp.clamp(n_dot * float(size) - 0.5, 0.0, float(size - 1))
        y = wp.clamp(roughness * float(size - 1), 0.0, float(size - 1))
        i0 = wp.min(int(x), size - 2)
        j0 = wp.min(int(y), size - 2)
        fx = x - float(i0)
        fy = y - float(j0)
        top = wp.lerp(entry(i0 * size + j0), entry(i0 * size + j0 + 1), fy)
        bottom = wp.lerp(entry((i0 + 1) * size + j0), entry((i0 + 1) * size + j0 + 1), fy)
        return wp.lerp(top, bottom, fx)

    @wp.func
    def sheen_layer(color: wp.vec3, roughness: float, n: wp.vec3, v: wp.vec3) -> Sheen:
        sheen = Sheen()
        sheen.color = color
        sheen.roughness = roughness
        sheen.normal = n
        sheen.taken_v = max_channel(color) * sheen_albedo(wp.max(wp.dot(n, v), MIN_COSINE), roughness)
        return sheen

    @wp.func
    def sheen_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV, n: wp.vec3, v: wp.vec3) -> Sheen:
        color = mat.sheen_color
        roughness = mat.sheen_roughness
        if wp.static(textured):
            texel = lookup(scene, mat.sheen_color_texture, uv)
            color = wp.cw_mul(color, wp.vec3(texel[0], texel[1], texel[2]))
            roughness = roughness * lookup(scene, mat.sheen_roughness_texture, uv)[3]
        return sheen_layer(color, roughness, n, v)

    @wp.func
    def sheen_brdf(sheen: Sheen, v: wp.vec3, l: wp.vec3) -> wp.vec3:
        n = sheen.normal
        n_dot_l = wp.dot(n, l)
        if n_dot_l <= 0.0:
            return wp.vec3(0.0)
        n_dot_v = wp.max(wp.dot(n, v), MIN_COSINE)
        h = safe_normalize(v + l, n)
        lobe = charlie_lobe(n_dot_v, wp.max(n_dot_l, MIN_COSINE), wp.clamp(wp.dot(n, h), 0.0, 1.0), sheen.roughness)
        return sheen.color * lobe

    @wp.func
    def sheen_scaling(sheen: Sheen, l: wp.vec3) -> float:
        taken_l = max_channel(sheen.color) * sheen_albedo(wp.max(wp.dot(sheen.normal, l), 0.0), sheen.roughness)
        return 1.0 - wp.max(sheen.taken_v, taken_l)

    @wp.func
    def sheen_environment(env: EnvironmentData, sheen: Sheen, below: wp.vec3) -> wp.vec3:
        irradiance = environment_irradiance(env, sheen.normal)
        albedo_v = float(0.0)
        m = max_channel(sheen.color)
        if m > 0.0:
            albedo_v = sheen.taken_v / m
        return below * (1.0 - sheen.taken_v) + wp.cw_mul(sheen.color, irradiance) * (albedo_v / PI)

    return sheen_at, sheen_layer, sheen_brdf, sheen_scaling, sheen_environment, sheen_albedo
