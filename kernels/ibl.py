"""Image-based lighting: an environment as the render kernel sees it, and the ambient terms built
on it (SH irradiance for diffuse, split-sum prefiltered radiance for specular).

An environment is stored unrotated and unscaled (so changing its intensity or rotation rebuilds
nothing); lookups turn world directions into the image's frame and scale by the intensity.
Rotation is about +Y: ``rotation`` = r turns the image's content from direction d to R_y(r) d,
with R_y(r) (x, y, z) = (x cos r + z sin r, y, -x sin r + z cos r).
"""

import warp as wp

from .equirect import EquirectLevels, sample_level, sample_levels
from .sh import sh_irradiance

wp.set_module_options({"enable_backward": False})


@wp.struct
class EnvironmentSampler:
    """A piecewise-constant distribution over an H x W equirect image (W = 2H), with which
    kernels/environment_sampling.py draws directions."""

    # the rows' cumulative probabilities, H + 1 of them, from 0 to 1
    row_cdf: wp.array(dtype=float)
    # each row's cumulative conditional probabilities over its columns, W + 1 a row, 0 to 1
    column_cdf: wp.array(dtype=float)
    # each texel's density per steradian (its probability over its solid angle), row-major
    texel_pdf: wp.array(dtype=float)
    width: int
    height: int


@wp.struct
class EnvironmentData:
    # level 0: the source radiance image; level k: GGX-prefiltered for roughness k / (count - 1)
    radiance: EquirectLevels
    # 9 SH coefficients of the source radiance (kernels/sh.py)
    sh: wp.array(dtype=wp.vec3)
    # the importance sampler of the source radiance (kernels/environment_sampling.py)
    sampler: EnvironmentSampler
    intensity: float
    rotation_cos: float
    rotation_sin: float


@wp.func
def to_environment_frame(env: EnvironmentData, w: wp.vec3) -> wp.vec3:
    """World direction w in the image's own frame: R_y(-rotation) w."""
    c = env.rotation_cos
    s = env.rotation_sin
    return wp.vec3(c * w[0] - s * w[2], w[1], s * w[0] + c * w[2])


@wp.func
def environment_radiance(env: EnvironmentData, direction: wp.vec3) -> wp.vec3:
    """Radiance arriving from ``direction`` (world space, towards the environment), bilinear in the
    source image: the background, and the Monte Carlo reference rungs' light."""
    return sample_level(env.radiance, 0, to_environment_frame(env, direction)) * env.intensity


@wp.func
def environment_irradiance(env: EnvironmentData, n: wp.vec3) -> wp.vec3:
    """Irradiance on a surface with unit normal n from the whole environment (unshadowed), from its
    9 SH coefficients; a Lambert surface of albedo c reflects c / pi times this."""
    return sh_irradiance(env.sh, to_environment_frame(env, n)) * env.intensity


@wp.func
def prefiltered_radiance(env: EnvironmentData, r: wp.vec3, roughness: float) -> wp.vec3:
    """The split sum's first factor: radiance around the reflection direction r through a GGX lobe
    of this roughness (Karis 2013), linear between the two nearest prefiltered levels."""
    level = wp.clamp(roughness, 0.0, 1.0) * float(env.radiance.count - 1)
    return sample_levels(env.radiance, to_environment_frame(env, r), level) * env.intensity


@wp.func
def F_SchlickRoughness(f0: wp.vec3, f90: wp.vec3, n_dot_v: float, roughness: float) -> wp.vec3:
    """Lagarde's roughness-aware Fresnel for ambient light (Lagarde 2011, "FresnelSchlickWithRoughness"):
    Schlick's with the grazing value lowered to max(gloss, f0), gloss = 1 - roughness, since a rough
    lobe averages Fresnel over many half vectors; f90 scales the gloss (KHR_materials_specular),
    so f90 = 1 is Lagarde's formula."""
    x = wp.clamp(1.0 - n_dot_v, 0.0, 1.0)
    x2 = x * x
    grazing = wp.max(f90 * (1.0 - roughness), f0)
    return f0 + (grazing - f0) * (x2 * x2 * x)
