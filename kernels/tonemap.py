"""Exposure, tone mapping and the sRGB transfer function: linear radiance to 8-bit sRGB."""

import functools

import warp as wp

from .robust import finite_or_zero

wp.set_module_options({"enable_backward": False})

TONEMAPS = ("none", "reinhard", "aces")


@wp.func
def tonemap_reinhard(x: wp.vec3) -> wp.vec3:
    """Reinhard et al. 2002, x / (1 + x) per channel."""
    return wp.vec3(x[0] / (1.0 + x[0]), x[1] / (1.0 + x[1]), x[2] / (1.0 + x[2]))


@wp.func
def rrt_odt_fit(v: float) -> float:
    """Stephen Hill's rational fit of the ACES RRT + sRGB ODT curve."""
    a = v * (v + 0.0245786) - 0.000090537
    b = v * (0.983729 * v + 0.4329510) + 0.238081
    return a / b


@wp.func
def tonemap_aces(x: wp.vec3) -> wp.vec3:
    """ACES filmic tone mapping, Stephen Hill's fit (sRGB -> ACES AP1 -> RRT/ODT -> sRGB)."""
    m_in = wp.mat33(0.59719, 0.35458, 0.04823, 0.07600, 0.90834, 0.01566, 0.02840, 0.13383, 0.83777)
    m_out = wp.mat33(1.60475, -0.53108, -0.07367, -0.10208, 1.10813, -0.00605, -0.00327, -0.07276, 1.07602)
    v = m_in * x
    v = wp.vec3(rrt_odt_fit(v[0]), rrt_odt_fit(v[1]), rrt_odt_fit(v[2]))
    return m_out * v


@wp.func
def srgb_encode(c: float) -> float:
    """The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1]."""
    if c <= 0.0031308:
        return 12.92 * c
    return 1.055 * wp.pow(c, 1.0 / 2.4) - 0.055


@functools.cache
def tonemap_kernel(operator: str):
    """Kernel mapping linear RGB to sRGB uint8 with the given tone map, compiled per operator."""
    if operator not in TONEMAPS:
        raise ValueError(f"unknown tone map {operator!r}; choose one of {TONEMAPS}")

    @wp.kernel(enable_backward=False, module="unique")
    def to_srgb8(rgb: wp.array(dtype=wp.vec3), scale: float, out: wp.array2d(dtype=wp.uint8)):
        i = wp.tid()
        x = finite_or_zero(rgb[i] * scale)
        if wp.static(operator == "reinhard"):
            x = tonemap_reinhard(x)
        elif wp.static(operator == "aces"):
            x = tonemap_aces(x)
        for c in range(3):
            y = srgb_encode(wp.clamp(x[c], 0.0, 1.0))
            out[i, c] = wp.uint8(int(y * 255.0 + 0.5))

    return to_srgb8
