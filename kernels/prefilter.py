"""GGX-prefiltered environment levels for split-sum specular lighting (Karis 2013, "Real Shading
in Unreal Engine 4"): level k holds, for each reflection direction r, the n.l-weighted mean
radiance through a GGX lobe of roughness k / (levels - 1) under Karis' n = v = r assumption,
integral of L D(h) n.l dl / integral of D(h) n.l dl. Level 0 is the source: a mirror sees it unfiltered.

Two ways to compute a level, whichever is affordable: a gather sums over every texel of a mip
pyramid level fine enough for the lobe (exact up to that resolution, noise-free: a sun of a few
texels is neither missed nor sprayed), used for the rough levels; the narrow lobes of smooth
levels, where a gather would read too many texels per texel, are importance sampled at
Hammersley points, each sample read from the pyramid level whose texels cover its share of the
sphere (filtered importance sampling, Colbert & Krivanek 2007, GPU Gems 3 ch. 20).
"""

import math

import numpy as np
import warp as wp

from .microfacet import D_GGX, alpha_from_roughness
from .direction_sampling import orthonormal_basis
from .equirect import (EquirectLevels, make_levels, mip_pyramid, sample_levels, texel_centre_direction,
                       texel_solid_angles)

wp.set_module_options({"enable_backward": False})

# Levels of the prefiltered chain: roughness 0, 0.2, ..., 1 (linear in roughness, Lagarde 2011's
# linear mip mapping; a lookup interpolates between the two nearest).
PREFILTER_LEVELS = 6
# GGX samples per texel of prefiltered level 1; a sampled level with 4x fewer texels takes 4x more.
# Enough that sampled (not gathered) levels stay close to brute-force prefiltering even with a
# small, very bright sun in the image (tests/test_ibl.py bounds the mean error).
PREFILTER_SAMPLES = 256
# Rows of prefiltered level 1 (roughness 0.2) at most; level k has half the rows of level k - 1.
# A GGX lobe of roughness 0.2 is ~6 degrees wide at half maximum, 4 texels at this size, and its
# samples read the pyramid at level 2 or coarser (texels of 1.4 degrees at 1024 x 512) anyway.
LEVEL1_MAX_HEIGHT = 128
# ... but never fewer rows than this: 16 rows (11 degree texels) resolve a rough lobe lit by a sun.
LEVEL_MIN_HEIGHT = 16
# The source's mip pyramid, read by sampling and gathers, stops at this many rows.
PYRAMID_MIN_HEIGHT = 4
# A level is gathered when that takes at most this many weight evaluations (output texels times
# pyramid texels), which bounds a gather's cost, else sampled. At 1024 x 512 roughness 0.4 and
# up are gathered.
GATHER_BUDGET = 1 << 26
# Rows of the coarsest pyramid level a gather reads.
GATHER_MIN_HEIGHT = 64


@wp.kernel
def prefilter_rows(source: EquirectLevels, lobe: wp.array(dtype=wp.vec4), first_row: int, width: int,
                   out: wp.array2d(dtype=wp.vec3)):
    """Texels of one prefiltered level: the n.l-weighted mean of the source over the lobe's
    samples (Karis 2013), each turned into the frame of the texel's reflection direction."""
    i, column = wp.tid()
    row = first_row + i
    frame = orthonormal_basis(texel_centre_direction(row, column, width, width / 2))
    total = wp.vec3(0.0)
    weight = float(0.0)
    for k in range(lobe.shape[0]):
        sample = lobe[k]
        l = frame * wp.vec3(sample[0], sample[1], sample[2])
        n_dot_l = sample[2]
        total += sample_levels(source, l, sample[3]) * n_dot_l
        weight += n_dot_l
    out[row, column] = total / weight


@wp.kernel
def gather_rows(radiance: wp.array(dtype=wp.vec3), directions: wp.array(dtype=wp.vec4), alpha: float,
                first_row: int, width: int, out: wp.array2d(dtype=wp.vec3)):
    """Texels of one prefiltered level by summing over every texel of a pyramid level (direction
    and solid angle in ``directions``) with weight D(h) n.l dw, n = v = r: the integral the
    sampled estimate converges to, without its noise (a sun of a few texels is not missed)."""
    i, column = wp.tid()
    row = first_row + i
    r = texel_centre_direction(row, column, width, width / 2)
    total = wp.vec3(0.0)
    weight = float(0.0)
    for k in range(directions.shape[0]):
        texel = directions[k]
        l = wp.vec3(texel[0], texel[1], texel[2])
        n_dot_l = wp.dot(r, l)
        if n_dot_l > 0.0:
            h = wp.normalize(l + r)
            sin_sq = wp.length_sq(wp.cross(r, h))
            w = D_GGX(alpha, wp.dot(r, h), sin_sq) * n_dot_l * texel[3]
            total += radiance[k] * w
            weight += w
    out[row, column] = total / weight


def hammersley(samples: int) -> np.ndarray:
    """(samples, 2) Hammersley points ((k + 0.5) / N, radical inverse of k in base 2)."""
    k = np.arange(samples, dtype=np.uint64)
    bits = np.zeros(samples, dtype=np.float64)
    for b in range(32):
        bits += ((k >> np.uint64(b)) & np.uint64(1)) * 0.5 ** (b + 1)
    return np.stack([(np.arange(samples) + 0.5) / samples, bits], axis=1)


def ggx_lobe(roughness: float, samples: int, source_height: int) -> np.ndarray:
    """(M, 4) float32 rows (l_x, l_y, l_z, pyramid level) of the lobe's samples with n.l = l_z > 0,
    in the frame z = n = v = r, the same for every texel (Karis 2013). Half vectors importance
    sample GGX by inverting the cdf of D n.h (Walter et al. 2007) at Hammersley points; a sample of
    pdf p stands for a solid angle 1 / (N p), read from the pyramid level whose texels cover it
    (Colbert & Krivanek 2007, without their +1 level: against brute-force prefiltering of the
    shared HDRs it only added blur)."""
    alpha = alpha_from_roughness(roughness)
    a2 = max(alpha * alpha, 1e-7)
    u = hammersley(samples)
    denominator = 1.0 + (a2 - 1.0) * u[:, 0]
    cos_h = np.sqrt((1.0 - u[:, 0]) / denominator)
    sin_h = np.sqrt(a2 * u[:, 0] / denominator)
    phi = 2.0 * np.pi * u[:, 1]
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=1)
    l = 2.0 * cos_h[:, None] * h - np.array([0.0, 0.0, 1.0])
    # pdf of l = D n.h / (4 v.h) = D / 4 with n = v; D = a2 / (pi (cos^2 (a2 - 1) + 1)^2)
    pdf = a2 / (np.pi * (cos_h**2 * (a2 - 1.0) + 1.0) ** 2) / 4.0
    # a pyramid texel at the equator covers (pi / H)^2 at level 0
    texel = (np.pi / source_height) ** 2
    lod = np.maximum(0.5 * np.log2(1.0 / (samples * pdf * texel)), 0.0)
    keep = l[:, 2] > 0.0
    return np.concatenate([l[keep], lod[keep, None]], axis=1).astype(np.float32)


def level_heights(source_height: int, levels: int = PREFILTER_LEVELS) -> list:
    """Rows of each prefiltered level: the source's at level 0, then halving from at most
    LEVEL1_MAX_HEIGHT, never below 4."""
    heights = [source_height]
    height = min(source_height, 2 * LEVEL1_MAX_HEIGHT)
    for _ in range(1, levels):
        height = max(height // 2, LEVEL_MIN_HEIGHT)
        heights.append(height)
    return heights


def level_roughness(level: int, levels: int = PREFILTER_LEVELS) -> float:
    return level / (levels - 1)


def texel_directions(height: int) -> np.ndarray:
    """(H * 2H, 4) float32 rows (direction, solid angle) of a 2H x H image's texel centres, row-major."""
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2.0 * np.pi * ((np.arange(2 * height) + 0.5) / (2 * height) - 0.5)
    sin_t = np.sin(theta)[:, None]
    rows = np.broadcast_arrays(sin_t * np.cos(phi), np.cos(theta)[:, None], sin_t * np.sin(phi),
                               texel_solid_angles(height)[:, None])
    return np.stack(rows, axis=-1).reshape(-1, 4).astype(np.float32)


def gather_height(roughness: float) -> int:
    """Rows of the pyramid level a gather reads for this roughness: texels of at most alpha / 3
    radians (pi / H <= alpha / 3), across which D varies little, and at least GATHER_MIN_HEIGHT
    rows, so that n.l, which falls to 0 at the hemisphere's edge, is sampled finely too."""
    alpha = alpha_from_roughness(roughness)
    return max(GATHER_MIN_HEIGHT, 1 << math.ceil(math.log2(3.0 * math.pi / alpha)))


def prefilter(source: np.ndarray, run_bands=None, levels: int = PREFILTER_LEVELS,
              samples: int = PREFILTER_SAMPLES) -> tuple:
    """The prefiltered chain of an (H, 2H, 3) float32 radiance image, as (EquirectLevels, list of
    the level images). A level is gathered over a pyramid level when that costs at most
    GATHER_BUDGET weight evaluations, else importance sampled. ``run_bands(launch, rows)`` may
    split each level's rows among threads: it calls ``launch(first_row, row_count)`` for
    disjoint bands covering ``rows``."""
    pyramid_images = mip_pyramid(source, PYRAMID_MIN_HEIGHT)
    pyramid = make_levels(pyramid_images)
    images = [np.asarray(source, dtype=np.float32)]
    heights = level_heights(source.shape[0], levels)
    for level, height in enumerate(heights[1:], start=1):
        out = wp.empty((height, 2 * height), dtype=wp.vec3, device="cpu")
        roughness = level_roughness(level, levels)
        # the finest pyramid level at least as fine as the gather needs (the source when none is coarser)
        reads = [image for image in pyramid_images if image.shape[0] >= gather_height(roughness)]
        read = reads[-1] if reads else pyramid_images[0]
        if 2 * height * height * read.shape[0] * read.shape[1] <= GATHER_BUDGET:
            radiance = wp.array(read.reshape(-1, 3), dtype=wp.vec3, device="cpu")
            directions = wp.array(texel_directions(read.shape[0]), dtype=wp.vec4, device="cpu")
            kernel, inputs = gather_rows, [radiance, directions, alpha_from_roughness(roughness)]
        else:
            count = samples * (heights[1] // height) ** 2
            lobe = wp.array(ggx_lobe(roughness, count, source.shape[0]), dtype=wp.vec4, device="cpu")
            kernel, inputs = prefilter_rows, [pyramid, lobe]

        def launch(first_row, row_count, out=out, kernel=kernel, inputs=inputs, height=height):
            wp.launch(kernel, dim=(row_count, 2 * height), device="cpu", inputs=[*inputs, first_row, 2 * height, out])

        if run_bands is None:
            launch(0, height)
        else:
            run_bands(launch, height)
        images.append(out.numpy())
    return make_levels(images), images
