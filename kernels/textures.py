"""Texture sampling: bilinear filtering of linear RGBA texels with glTF wrap modes.

All textures of a scene live in one Texels struct: 8-bit images as they were stored (4 bytes a
texel, sRGB-encoded or not), 16-bit and float images as linear float32. A TextureData row says
where each one starts, its size and format, its wrap modes and KHR_texture_transform. Each of
the four texels a lookup reads is decoded to linear before they are interpolated, so filtering
averages linear values, as the sRGB transfer function asks (IEC 61966-2-1; the glTF 2.0
specification, section 3.9.2, decodes colour textures before any filtering).
"""

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

WRAP_REPEAT = wp.constant(0)
WRAP_CLAMP = wp.constant(1)
WRAP_MIRROR = wp.constant(2)

# TextureData.texel_format: where a texture's texels live and how they decode to linear values.
TEXELS_FLOAT = wp.constant(0)  # Texels.floats, linear already
TEXELS_UNORM8 = wp.constant(1)  # Texels.unorm8, value / 255
TEXELS_SRGB8 = wp.constant(2)  # Texels.unorm8, colour decoded from sRGB, alpha value / 255
DECODE_TABLE_SIZE = 512  # Texels.decode: 256 entries for TEXELS_UNORM8, then 256 for TEXELS_SRGB8


@wp.struct
class TextureData:
    # first texel, in Texels.floats or Texels.unorm8 as texel_format says
    offset: int
    width: int
    height: int
    # mip levels stored (0 or 1: level 0 only). Level l is max(1, width >> l) x max(1, height >> l)
    # texels (pbrwarp.textures.mip_chain); level 1 starts at mip_offset, in the same array, and
    # each further level follows the one before directly (mip_level_offset). Level 0 stands
    # apart so that an 8-bit image read both as colour and as data is stored once.
    levels: int
    mip_offset: int
    # the uv set the texture is sampled with: 0 (TEXCOORD_0, SceneData.uvs) or 1 (SceneData.uvs1)
    uv_set: int
    wrap_s: int
    wrap_t: int
    texel_format: int
    uv_row0: wp.vec3
    uv_row1: wp.vec3


@wp.struct
class Texels:
    floats: wp.array(dtype=wp.vec4)
    unorm8: wp.array(dtype=wp.vec4ub)
    # float32[DECODE_TABLE_SIZE]: the linear value of each byte (pbrwarp.textures.UNORM8_DECODE)
    decode: wp.array(dtype=float)


def texel_store(floats=(), unorm8=(), decode=None) -> Texels:
    """A Texels struct holding the (N, 4) float32 arrays ``floats`` and (N, 4) uint8 arrays
    ``unorm8`` one after the other, in that order (an empty kind gets one unused texel);
    ``decode`` is required with 8-bit texels."""
    store = Texels()
    store.floats = _concatenated(floats, np.float32, wp.vec4)
    store.unorm8 = _concatenated(unorm8, np.uint8, wp.vec4ub)
    if decode is None:
        if any(len(chunk) for chunk in unorm8):
            raise ValueError("texel_store: 8-bit texels need their decode table")
        decode = np.zeros(DECODE_TABLE_SIZE, np.float32)
    if np.shape(decode) != (DECODE_TABLE_SIZE,):
        raise ValueError(f"texel_store: the decode table must have {DECODE_TABLE_SIZE} entries")
    store.decode = wp.array(np.asarray(decode, np.float32), dtype=float, device="cpu")
    return store


def _concatenated(chunks, dtype, vector) -> wp.array:
    """One Warp array of the (N, 4) chunks, filled in place (no concatenated copy in between)."""
    total = sum(len(chunk) for chunk in chunks)
    out = wp.empty(max(total, 1), dtype=vector, device="cpu")
    view = out.numpy()
    if total == 0:
        view[:] = 0
    start = 0
    for chunk in chunks:
        view[start:start + len(chunk)] = np.asarray(chunk, dtype=dtype).reshape(-1, 4)
        start += len(chunk)
    return out


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
def fetch_texel(tex: TextureData, texels: Texels, i: int) -> wp.vec4:
    """Linear RGBA of texel i of ``tex`` (an index into the array its format names)."""
    if tex.texel_format == TEXELS_FLOAT:
        return texels.floats[i]
    b = texels.unorm8[i]
    colour = 256 * (tex.texel_format - TEXELS_UNORM8)
    return wp.vec4(texels.decode[colour + int(b[0])], texels.decode[colour + int(b[1])],
                   texels.decode[colour + int(b[2])], texels.decode[int(b[3])])


@wp.func
def transformed_uv(tex: TextureData, uv: wp.vec2) -> wp.vec2:
    """uv through the texture's KHR_texture_transform."""
    return wp.vec2(tex.uv_row0[0] * uv[0] + tex.uv_row0[1] * uv[1] + tex.uv_row0[2],
                   tex.uv_row1[0] * uv[0] + tex.uv_row1[1] * uv[1] + tex.uv_row1[2])


@wp.func
def bilinear(tex: TextureData, texels: Texels, offset: int, width: int, height: int, uv: wp.vec2) -> wp.vec4:
    """Bilinearly filtered linear texel at (transformed) uv of the width x height image starting
    at ``offset``; the four texels are decoded (fetch_texel) before they are interpolated."""
    # texel centres sit at half-integers
    x = reduce_coordinate(uv[0] * float(width) - 0.5, width, tex.wrap_s)
    y = reduce_coordinate(uv[1] * float(height) - 0.5, height, tex.wrap_t)
    x0f = wp.floor(x)
    y0f = wp.floor(y)
    fx = x - x0f
    fy = y - y0f
    x0 = int(x0f)
    y0 = int(y0f)
    xa = wrap_texel(x0, width, tex.wrap_s)
    xb = wrap_texel(x0 + 1, width, tex.wrap_s)
    ya = wrap_texel(y0, height, tex.wrap_t)
    yb = wrap_texel(y0 + 1, height, tex.wrap_t)
    row_a = offset + ya * width
    row_b = offset + yb * width
    top = fetch_texel(tex, texels, row_a + xa) * (1.0 - fx) + fetch_texel(tex, texels, row_a + xb) * fx
    bottom = fetch_texel(tex, texels, row_b + xa) * (1.0 - fx) + fetch_texel(tex, texels, row_b + xb) * fx
    return top * (1.0 - fy) + bottom * fy


@wp.func
def sample_texture(tex: TextureData, texels: Texels, uv: wp.vec2) -> wp.vec4:
    """Bilinearly filtered linear texel of level 0 at uv (glTF convention: (0, 0) is the top-left
    of the image)."""
    return bilinear(tex, texels, tex.offset, tex.width, tex.height, transformed_uv(tex, uv))


@wp.func
def mip_level_side(side: int, level: int) -> int:
    """A side of ``side`` texels at mip level ``level`` (halved, rounded down, at least 1)."""
    return wp.max(1, side >> level)


@wp.func
def mip_level_offset(tex: TextureData, level: int) -> int:
    """First texel of mip level ``level`` of ``tex``: level 0 at offset, the others one after the
    other from mip_offset."""
    if level == 0:
        return tex.offset
    start = tex.mip_offset
    for l in range(1, level):
        start += mip_level_side(tex.width, l) * mip_level_side(tex.height, l)
    return start


@wp.func
def mip_lod(tex: TextureData, duv_dx: wp.vec2, duv_dy: wp.vec2) -> float:
    """Mip level (fractional) for a pixel whose footprint has the uv derivatives duv_dx, duv_dy
    (per pixel step in x and y, before the texture transform): log2 of the longer footprint side
    in level-0 texels, the isotropic rule of OpenGL 4.6 section 8.14.1 (pbrt-v4's
    MIPMap::Filter without its anisotropic EWA). Clamped to [0, levels - 1]; zero, NaN or
    infinite derivatives (degenerate UVs, grazing views) give a finite level."""
    top = float(wp.max(tex.levels - 1, 0))
    size = wp.abs(duv_dx[0]) + wp.abs(duv_dx[1]) + wp.abs(duv_dy[0]) + wp.abs(duv_dy[1])
    if not (size < 1.0e30):  # NaN, Inf or huge: the coarsest level
        return top
    w = float(tex.width)
    h = float(tex.height)
    # the transform's linear part maps derivatives too (KHR_texture_transform's scale, rotation)
    dx = wp.vec2((tex.uv_row0[0] * duv_dx[0] + tex.uv_row0[1] * duv_dx[1]) * w,
                 (tex.uv_row1[0] * duv_dx[0] + tex.uv_row1[1] * duv_dx[1]) * h)
    dy = wp.vec2((tex.uv_row0[0] * duv_dy[0] + tex.uv_row0[1] * duv_dy[1]) * w,
                 (tex.uv_row1[0] * duv_dy[0] + tex.uv_row1[1] * duv_dy[1]) * h)
    width = wp.max(wp.dot(dx, dx), wp.dot(dy, dy))
    if width <= 1.0:  # magnification (and zero derivatives): level 0, no log of 0
        return 0.0
    return wp.min(0.5 * wp.log2(width), top)


@wp.func
def sample_texture_lod(tex: TextureData, texels: Texels, uv: wp.vec2, lod: float) -> wp.vec4:
    """Trilinearly filtered linear texel at uv: bilinear lookups in the two mip levels around
    ``lod`` (clamped to the stored levels), blended linearly; lod 0 is sample_texture."""
    top = wp.max(tex.levels - 1, 0)
    level = wp.clamp(lod, 0.0, float(top))
    if not (level >= 0.0):  # NaN
        level = 0.0
    l0 = wp.min(int(wp.floor(level)), top)
    l1 = wp.min(l0 + 1, top)
    t = level - float(l0)
    st = transformed_uv(tex, uv)
    a = bilinear(tex, texels, mip_level_offset(tex, l0), mip_level_side(tex.width, l0),
                 mip_level_side(tex.height, l0), st)
    if t <= 0.0 or l1 == l0:
        return a
    b = bilinear(tex, texels, mip_level_offset(tex, l1), mip_level_side(tex.width, l1),
                 mip_level_side(tex.height, l1), st)
    return a * (1.0 - t) + b * t
