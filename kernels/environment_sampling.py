"""Importance sampling of an environment: directions drawn in proportion to the radiance arriving
from them, for Monte Carlo estimates of environment light with few samples.

The distribution is piecewise constant over the texels of the equirect image (Pharr, Jakob and
Humphreys, "Physically Based Rendering", 4th ed., section A.5, piecewise-constant 2D
distributions: a marginal distribution over the rows, a conditional one over each row's
columns). A texel's weight is its luminance times its solid angle (the luminance x sin(theta)
weight, integrated over the texel exactly), and inside a texel directions are uniform in solid
angle (uniform in phi and in cos(theta)), so the density is constant over each texel: its
probability over its solid angle.

The luminance weighed is each texel's mean, over the texel in image coordinates, of the
bilinear radiance that ``environment_radiance`` returns (a 3 x 3 filter: 3/4 on the texel, 1/8 on
each side, per axis), so every direction from which any radiance arrives has a positive density;
a small uniform share (UNIFORM_SHARE of the mean) keeps it so against rounding. An environment
without radiance is sampled uniformly.

The distribution is of the image's own frame; ``sample_environment`` and ``pdf_environment``
turn directions to and from the world by the environment's rotation (kernels/ibl.py). Intensity
scales radiance, not the distribution.
"""

import numpy as np
import warp as wp

from .equirect import PI, equirect_coordinates, texel_solid_angles
# EnvironmentSampler lives in kernels/ibl.py, as a field of EnvironmentData (env.sampler)
from .ibl import EnvironmentData, EnvironmentSampler, to_environment_frame  # noqa: F401

wp.set_module_options({"enable_backward": False})

# Rec. 709 luminance of linear RGB (ITU-R BT.709): what the distribution follows.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
# The share of the mean luminance added to every texel's weight: with it about 0.1 % of the samples
# spread uniformly over the sphere.
UNIFORM_SHARE = 1.0e-3


def sampling_weights(texels: np.ndarray) -> np.ndarray:
    """(H, W) float64 weights of an (H, W, 3) image's texels: the mean luminance of its bilinear
    radiance over each texel (columns wrap, rows clamp at the poles, as the lookups do), plus
    UNIFORM_SHARE of the image's mean luminance, times the texel's solid angle. All ones times the
    solid angle (uniform) where the image has no radiance."""
    luminance = np.asarray(texels, dtype=np.float64) @ LUMINANCE
    rows = np.concatenate([luminance[:1], luminance, luminance[-1:]])
    luminance = 0.75 * rows[1:-1] + 0.125 * (rows[:-2] + rows[2:])
    luminance = 0.75 * luminance + 0.125 * (np.roll(luminance, 1, axis=1) + np.roll(luminance, -1, axis=1))
    solid_angle = texel_solid_angles(luminance.shape[0])[:, None]
    mean = (luminance * solid_angle).sum() / (solid_angle.sum() * luminance.shape[1])
    if not mean > 0.0:
        return np.broadcast_to(solid_angle, luminance.shape).copy()
    return (luminance + UNIFORM_SHARE * mean) * solid_angle


def build_sampler(texels: np.ndarray) -> EnvironmentSampler:
    """The EnvironmentSampler of an (H, 2H, 3) linear RGB image (finite, non-negative)."""
    weights = sampling_weights(texels)
    height, width = weights.shape
    row_sums = weights.sum(axis=1)
    total = row_sums.sum()
    row_cdf = np.concatenate([[0.0], np.cumsum(row_sums) / total])
    column_cdf = np.concatenate([np.zeros((height, 1)), np.cumsum(weights, axis=1) / row_sums[:, None]], axis=1)
    row_cdf[-1] = 1.0
    column_cdf[:, -1] = 1.0
    texel_pdf = weights / total / texel_solid_angles(height)[:, None]
    sampler = EnvironmentSampler()
    sampler.row_cdf = wp.array(row_cdf.astype(np.float32), dtype=float, device="cpu")
    sampler.column_cdf = wp.array(column_cdf.astype(np.float32).ravel(), dtype=float, device="cpu")
    sampler.texel_pdf = wp.array(texel_pdf.astype(np.float32).ravel(), dtype=float, device="cpu")
    sampler.width = width
    sampler.height = height
    return sampler


@wp.func
def search_cdf(cdf: wp.array(dtype=float), start: int, count: int, u: float) -> int:
    """The interval i in [0, count) of a cumulative distribution cdf[start : start + count + 1]
    (from 0 to 1) holding u in [0, 1): the last i with cdf[start + i] <= u, so never an empty one."""
    lo = int(0)
    hi = count
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[start + mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@wp.func
def fraction_in(cdf: wp.array(dtype=float), at: int, u: float) -> float:
    """Where u falls in [cdf[at], cdf[at + 1]), as a fraction in [0, 1)."""
    low = cdf[at]
    width = cdf[at + 1] - low
    f = float(0.0)
    if width > 0.0:
        f = (u - low) / width
    return wp.clamp(f, 0.0, 0.99999994)


@wp.func
def from_environment_frame(env: EnvironmentData, w: wp.vec3) -> wp.vec3:
    """Direction w of the image's frame in the world: R_y(rotation) w, the inverse of
    kernels/ibl.py's to_environment_frame."""
    c = env.rotation_cos
    s = env.rotation_sin
    return wp.vec3(c * w[0] + s * w[2], w[1], -s * w[0] + c * w[2])


@wp.func
def sample_environment(sampler: EnvironmentSampler, env: EnvironmentData, u: wp.vec2):
    """(world direction towards the environment, its density per steradian): a texel drawn by
    its weight (u[1] picks the row, u[0] the column in it), and a direction uniform in solid
    angle inside it."""
    row = search_cdf(sampler.row_cdf, 0, sampler.height, u[1])
    fy = fraction_in(sampler.row_cdf, row, u[1])
    start = row * (sampler.width + 1)
    column = search_cdf(sampler.column_cdf, start, sampler.width, u[0])
    fx = fraction_in(sampler.column_cdf, start + column, u[0])
    # uniform in cos(theta) between the row's edges, and in phi across the column
    top = wp.cos(PI * float(row) / float(sampler.height))
    bottom = wp.cos(PI * float(row + 1) / float(sampler.height))
    cos_theta = top + (bottom - top) * fy
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * PI * ((float(column) + fx) / float(sampler.width) - 0.5)
    local = wp.vec3(sin_theta * wp.cos(phi), cos_theta, sin_theta * wp.sin(phi))
    return from_environment_frame(env, local), sampler.texel_pdf[row * sampler.width + column]


@wp.func
def pdf_environment(sampler: EnvironmentSampler, env: EnvironmentData, direction: wp.vec3) -> float:
    """The density per steradian with which sample_environment draws the world ``direction``
    (need not be unit length; non-zero)."""
    uv = equirect_coordinates(to_environment_frame(env, direction))
    column = wp.clamp(int(uv[0] * float(sampler.width)), 0, sampler.width - 1)
    row = wp.clamp(int(uv[1] * float(sampler.height)), 0, sampler.height - 1)
    return sampler.texel_pdf[row * sampler.width + column]
