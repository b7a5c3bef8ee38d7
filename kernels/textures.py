"""Texture sampling: bilinear filtering of linear RGBA texels with glTF wrap modes.

All textures of a scene live in one flat texel array; a TextureData row says where each one
starts, its size, wrap modes and KHR_texture_transform.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})

WRAP_REPEAT = wp.constant(0)
WRAP_CLAMP = wp.constant(1)
WRAP_MIRROR = wp.constant(2)


@wp.struct
class TextureData:
    offset: int
    width: int
    height: int
    wrap_s: int
    wrap_t: int
    uv_row0: wp.vec3
    uv_row1: wp.vec3


@wp.func
def wrap_texel(i: int, size: int, mode: int) -> int:
    """Texel index i (any integer) mapped into [0, size) by the wrap mode."""
    if mode == WRAP_CLAMP:
        return wp.clamp(i, 0, size - 1)
    if mode == WRAP_MIRROR:
        period = 2 * size
        k = ((i % period) + period) % period
        if k >= size:
            k = period - 1 - k
        return k
    return ((i % size) + size) % size


@wp.func
def reduce_coordinate(x: float, size: int, mode: int) -> float:
    """Texel coordinate brought into a small range the wrap mode maps identically, so huge UVs
    (1e6 and beyond) never overflow the int conversion: clamped to [-1, size] for clamp, reduced
    modulo 2 size (a period of both repeat and mirror) otherwise. NaN and Inf become 0, so a
    broken UV samples a texel instead of poisoning the pixel or indexing out of bounds."""
    if not (wp.abs(x) < 1.0e30):
        return 0.0
    if mode == WRAP_CLAMP:
        return wp.clamp(x, -1.0, float(size))
    period = 2.0 * float(size)
    return x - period * wp.floor(x / period)


@wp.func
def sample_texture(tex: TextureData, texels: wp.array(dtype=wp.vec4), uv: wp.vec2) -> wp.vec4:
    """Bilinearly filtered texel at uv (glTF convention: (0, 0) is the top-left of the image)."""
    u = tex.uv_row0[0] * uv[0] + tex.uv_row0[1] * uv[1] + tex.uv_row0[2]
    v = tex.uv_row1[0] * uv[0] + tex.uv_row1[1] * uv[1] + tex.uv_row1[2]
    # texel centres sit at half-integers
    x = reduce_coordinate(u * float(tex.width) - 0.5, tex.width, tex.wrap_s)
    y = reduce_coordinate(v * float(tex.height) - 0.5, tex.height, tex.wrap_t)
    x0f = wp.floor(x)
    y0f = wp.floor(y)
    fx = x - x0f
    fy = y - y0f
    x0 = int(x0f)
    y0 = int(y0f)
    xa = wrap_texel(x0, tex.width, tex.wrap_s)
    xb = wrap_texel(x0 + 1, tex.width, tex.wrap_s)
    ya = wrap_texel(y0, tex.height, tex.wrap_t)
    yb = wrap_texel(y0 + 1, tex.height, tex.wrap_t)
    row_a = tex.offset + ya * tex.width
    row_b = tex.offset + yb * tex.width
    top = texels[row_a + xa] * (1.0 - fx) + texels[row_a + xb] * fx
    bottom = texels[row_b + xa] * (1.0 - fx) + texels[row_b + xb] * fx
    return top * (1.0 - fy) + bottom * fy
