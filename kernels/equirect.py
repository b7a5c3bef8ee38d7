"""Equirectangular (latitude-longitude) images of radiance: the direction <-> texel mapping,
bilinear lookups and chains of levels (a mip pyramid or a prefiltered chain) in one flat array.

Mapping (three.js's ``equirectUv``, Y up as in glTF), for a unit direction d = (x, y, z):

    u = 0.5 + atan2(z, x) / (2 pi)     column fraction, 0 at the left edge of the image
    t = acos(y) / pi                   row fraction, 0 at the top row (+Y) and 1 at the bottom (-Y)

so the image's centre column looks along +X, its left and right edges along -X, the column at
u = 0.75 along +Z and u = 0.25 along -Z. Inversely, with phi = 2 pi (u - 0.5) and theta = pi t,
d = (sin theta cos phi, cos theta, sin theta sin phi). Every image here is W x H = 2H x H.
"""

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

PI = wp.constant(3.14159265358979323846)


@wp.struct
class EquirectLevels:
    """Equirect images of decreasing (or equal) size, row-major RGB, row 0 = +Y, all in one array:
    level k starts at ``offset[k]`` and is ``width[k]`` x ``width[k] / 2`` texels."""

    texels: wp.array(dtype=wp.vec3)
    offset: wp.array(dtype=wp.int32)
    width: wp.array(dtype=wp.int32)
    count: int


@wp.func
def equirect_direction(u: float, t: float) -> wp.vec3:
    """Unit direction at column fraction u and row fraction t (the module's mapping)."""
    phi = 2.0 * PI * (u - 0.5)
    theta = PI * t
    s = wp.sin(theta)
    return wp.vec3(s * wp.cos(phi), wp.cos(theta), s * wp.sin(phi))


@wp.func
def equirect_coordinates(d: wp.vec3) -> wp.vec2:
    """(u, t) of direction d (need not be unit); theta by atan2, which unlike acos(y) keeps its
    precision near the poles."""
    u = 0.5 + wp.atan2(d[2], d[0]) / (2.0 * PI)
    t = wp.atan2(wp.sqrt(d[0] * d[0] + d[2] * d[2]), d[1]) / PI
    return wp.vec2(u, t)


@wp.func
def texel_centre_direction(row: int, column: int, width: int, height: int) -> wp.vec3:
    return equirect_direction((float(column) + 0.5) / float(width), (float(row) + 0.5) / float(height))


@wp.func
def sample_level_at(levels: EquirectLevels, level: int, uv: wp.vec2) -> wp.vec3:
    """Bilinear radiance of one level at equirect coordinates uv = (u, t): columns wrap around,
    rows clamp at the poles."""
    width = levels.width[level]
    height = width / 2
    # texel centres sit at half-integers
    x = uv[0] * float(width) - 0.5
    y = wp.clamp(uv[1] * float(height) - 0.5, 0.0, float(height - 1))
    x0f = wp.floor(x)
    y0f = wp.floor(y)
    fx = x - x0f
    fy = y - y0f
    xa = ((int(x0f) % width) + width) % width
    xb = (xa + 1) % width
    ya = int(y0f)
    yb = wp.min(ya + 1, height - 1)
    row_a = levels.offset[level] + ya * width
    row_b = levels.offset[level] + yb * width
    top = levels.texels[row_a + xa] * (1.0 - fx) + levels.texels[row_a + xb] * fx
    bottom = levels.texels[row_b + xa] * (1.0 - fx) + levels.texels[row_b + xb] * fx
    return top * (1.0 - fy) + bottom * fy


@wp.func
def sample_level(levels: EquirectLevels, level: int, d: wp.vec3) -> wp.vec3:
    """Bilinear radiance of one level towards direction d."""
    return sample_level_at(levels, level, equirect_coordinates(d))


@wp.func
def sample_levels(levels: EquirectLevels, d: wp.vec3, level: float) -> wp.vec3:
    """Trilinear radiance towards d: bilinear in the two levels around ``level`` (clamped to the
    chain), linear between them."""
    x = wp.clamp(level, 0.0, float(levels.count - 1))
    k = int(wp.floor(x))
    k1 = wp.min(k + 1, levels.count - 1)
    f = x - float(k)
    uv = equirect_coordinates(d)
    return sample_level_at(levels, k, uv) * (1.0 - f) + sample_level_at(levels, k1, uv) * f


def texel_solid_angles(height: int) -> np.ndarray:
    """Float64 solid angle of one texel of each row of a 2H x H equirect image:
    (2 pi / W)(cos theta_top - cos theta_bottom); the rows' texels sum to 4 pi exactly."""
    edges = np.cos(np.pi * np.arange(height + 1) / height)
    return (2.0 * np.pi / (2 * height)) * (edges[:-1] - edges[1:])


def downsample(image: np.ndarray) -> np.ndarray:
    """Half-size equirect image (height must be even): each 2x2 block's mean radiance weighted by
    its texels' solid angles, so the image's integral over the sphere is kept."""
    height, width = image.shape[:2]
    weights = texel_solid_angles(height).reshape(height // 2, 2, 1, 1, 1)
    blocks = image.astype(np.float64).reshape(height // 2, 2, width // 2, 2, 3)
    block_weight = 2.0 * weights.sum(axis=1).reshape(height // 2, 1, 1)
    return ((blocks * weights).sum(axis=(1, 3)) / block_weight).astype(np.float32)


def mip_pyramid(image: np.ndarray, smallest_height: int) -> list:
    """The image and its successive halvings, down to ``smallest_height`` rows or an odd height."""
    levels = [np.asarray(image, dtype=np.float32)]
    while levels[-1].shape[0] % 2 == 0 and levels[-1].shape[0] // 2 >= smallest_height:
        levels.append(downsample(levels[-1]))
    return levels


def make_levels(images: list) -> EquirectLevels:
    """An EquirectLevels holding the given (H, 2H, 3) float images, first to last."""
    for k, image in enumerate(images):
        if image.ndim != 3 or image.shape[2] != 3 or image.shape[1] != 2 * image.shape[0]:
            raise ValueError(f"level {k} must be an (H, 2H, 3) image, got shape {image.shape}")
    sizes = [image.shape[0] * image.shape[1] for image in images]
    levels = EquirectLevels()
    levels.texels = wp.array(np.concatenate([image.reshape(-1, 3) for image in images]).astype(np.float32),
                             dtype=wp.vec3, device="cpu")
    levels.offset = wp.array(np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32), dtype=wp.int32, device="cpu")
    levels.width = wp.array(np.array([image.shape[1] for image in images], dtype=np.int32), dtype=wp.int32, device="cpu")
    levels.count = len(images)
    return levels
