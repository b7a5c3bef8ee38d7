"""Diffuse environment lighting from 9 spherical-harmonic coefficients (Ramamoorthi & Hanrahan
2001, "An Efficient Representation for Irradiance Environment Maps").

The radiance L of an equirect image is projected onto the real SH basis of bands 0-2 by a Warp
kernel; irradiance is then E(n) = sum_lm A_l L_lm Y_lm(n) with the clamped cosine's band
factors A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4 (bands 3 and up are dropped; odd ones vanish).
E is in radiance units times steradians: a white Lambert surface reflects E / pi.

Error of dropping bands >= 4: E(n) - E_2(n) = integral of (L - P2 L)(cos+ - P2 cos+), so by
Cauchy-Schwarz |E - E_2| <= ||cos+ - P2 cos+|| ||L - P2 L|| = SH_CLAMPED_COSINE_RESIDUAL ||L - P2 L||
(L2 norms on the sphere), a bound for any lighting and any normal; tests/test_ibl.py checks it.
"""

import math

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

PI = wp.constant(3.14159265358979323846)
SH_COUNT = 9
sh9 = wp.types.vector(length=9, dtype=float)
# normalization constants of the real SH functions (R&H 2001 print them to 6 digits)
Y0 = wp.constant(0.5 / math.sqrt(math.pi))
Y1 = wp.constant(math.sqrt(3.0 / (4.0 * math.pi)))
Y2 = wp.constant(math.sqrt(15.0 / (4.0 * math.pi)))
Y20 = wp.constant(math.sqrt(5.0 / (16.0 * math.pi)))
Y22 = wp.constant(math.sqrt(15.0 / (16.0 * math.pi)))
# ||cos+ - P2 cos+||: ||cos+||^2 = 2 pi / 3 minus sum over l <= 2 of A_l^2 (2l + 1) / (4 pi).
SH_CLAMPED_COSINE_RESIDUAL = math.sqrt(2.0 * math.pi / 3.0 - (math.pi / 4.0 + math.pi / 3.0 + 5.0 * math.pi / 64.0))


@wp.func
def sh_basis(d: wp.vec3) -> sh9:
    """The 9 real SH functions of bands 0-2 at the unit direction d = (x, y, z), in the order
    Y00, Y1-1, Y10, Y11, Y2-2, Y2-1, Y20, Y21, Y22 (Ramamoorthi & Hanrahan 2001, eq. 3, with their
    z as this function's third component; any fixed orthonormal choice serves projection and
    evaluation alike)."""
    x = d[0]
    y = d[1]
    z = d[2]
    return sh9(Y0, Y1 * y, Y1 * z, Y1 * x,
               Y2 * x * y, Y2 * y * z, Y20 * (3.0 * z * z - 1.0), Y2 * x * z, Y22 * (x * x - y * y))


@wp.func
def sh_band_factor(k: int) -> float:
    """A_l of coefficient k: the clamped cosine's SH convolution factor for its band."""
    if k == 0:
        return PI
    if k < 4:
        return 2.0 * PI / 3.0
    return PI / 4.0


@wp.func
def sh_irradiance(coeffs: wp.array(dtype=wp.vec3), n: wp.vec3) -> wp.vec3:
    """Irradiance E(n) at unit normal n from the radiance's 9 SH coefficients (R&H 2001, eq. 7)."""
    basis = sh_basis(n)
    e = wp.vec3(0.0)
    for k in range(SH_COUNT):
        e += coeffs[k] * (sh_band_factor(k) * basis[k])
    # strong light sources make the truncated series ring below zero on the far side
    return wp.max(e, wp.vec3(0.0))


sh9d = wp.types.vector(length=9, dtype=wp.float64)


@wp.func
def texel_sh_integrals(row: int, column: int, width: int, height: int) -> sh9d:
    """Exact integrals of the 9 SH functions over one texel, theta in [pi i / H, pi (i + 1) / H],
    phi in [2 pi (j / W - 0.5), 2 pi ((j + 1) / W - 0.5)]: each function is a sum of products of a
    power of (sin theta, cos theta) and 1, cos, sin of phi or 2 phi, integrated in closed form, so
    that coarse images (a 4-row uniform environment) project exactly."""
    pi = wp.float64(3.14159265358979323846)
    t0 = pi * wp.float64(row) / wp.float64(height)
    t1 = pi * wp.float64(row + 1) / wp.float64(height)
    p0 = wp.float64(2.0) * pi * (wp.float64(column) / wp.float64(width) - wp.float64(0.5))
    p1 = wp.float64(2.0) * pi * (wp.float64(column + 1) / wp.float64(width) - wp.float64(0.5))
    c0 = wp.cos(t0)
    c1 = wp.cos(t1)
    s0 = wp.sin(t0)
    s1 = wp.sin(t1)
    # integrals over theta of f(theta) sin(theta)
    m_one = c0 - c1
    m_cos = (s1 * s1 - s0 * s0) / wp.float64(2.0)
    m_sin = (t1 - t0) / wp.float64(2.0) - (wp.sin(wp.float64(2.0) * t1) - wp.sin(wp.float64(2.0) * t0)) / wp.float64(4.0)
    m_sin_cos = (s1 * s1 * s1 - s0 * s0 * s0) / wp.float64(3.0)
    m_cos2 = (c0 * c0 * c0 - c1 * c1 * c1) / wp.float64(3.0)
    m_sin2 = m_one - m_cos2
    # integrals over phi
    f_one = p1 - p0
    f_cos = wp.sin(p1) - wp.sin(p0)
    f_sin = wp.cos(p0) - wp.cos(p1)
    f_cos2 = (wp.sin(wp.float64(2.0) * p1) - wp.sin(wp.float64(2.0) * p0)) / wp.float64(2.0)
    f_sin2 = (wp.cos(wp.float64(2.0) * p0) - wp.cos(wp.float64(2.0) * p1)) / wp.float64(2.0)
    half = wp.float64(0.5)
    # x = sin(t) cos(p), y = cos(t), z = sin(t) sin(p); x^2 and z^2 are sin^2(t) (1 +- cos(2p)) / 2
    x2 = m_sin2 * (f_one + f_cos2) * half
    z2 = m_sin2 * (f_one - f_cos2) * half
    return sh9d(wp.float64(Y0) * m_one * f_one,
                wp.float64(Y1) * m_cos * f_one,
                wp.float64(Y1) * m_sin * f_sin,
                wp.float64(Y1) * m_sin * f_cos,
                wp.float64(Y2) * m_sin_cos * f_cos,
                wp.float64(Y2) * m_sin_cos * f_sin,
                wp.float64(Y20) * (wp.float64(3.0) * z2 - m_one * f_one),
                wp.float64(Y2) * m_sin2 * f_sin2 * half,
                wp.float64(Y22) * (x2 - m_cos2 * f_one))


@wp.kernel
def project_rows(texels: wp.array(dtype=wp.vec3), width: int, height: int, out: wp.array2d(dtype=wp.vec3d)):
    """out[row, k]: that row's share of L_k = sum over its texels of L times the integral of Y_k
    over the texel, summed in float64 (the rows are then added pairwise by NumPy)."""
    row = wp.tid()
    for column in range(width):
        integrals = texel_sh_integrals(row, column, width, height)
        radiance = wp.vec3d(texels[row * width + column])
        for k in range(SH_COUNT):
            out[row, k] = out[row, k] + radiance * integrals[k]


def project_sh(texels: wp.array, width: int, height: int) -> np.ndarray:
    """(9, 3) float64 SH coefficients of a W x H equirect radiance image (texels: vec3, row-major,
    the first W H of the array), each texel's radiance constant over the texel."""
    out = wp.zeros((height, SH_COUNT), dtype=wp.vec3d, device="cpu")
    wp.launch(project_rows, dim=height, device="cpu", inputs=[texels, width, height, out])
    return out.numpy().sum(axis=0)
