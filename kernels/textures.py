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
def sample_texture(tex: TextureData, texels: Texels, uv: wp.vec2) -> wp.vec4:
    """Bilinearly filtered linear texel at uv (glTF convention: (0, 0) is the top-left of the
    image); the four texels are decoded (fetch_texel) before they are interpolated."""
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
    top = fetch_texel(tex, texels, row_a + xa) * (1.0 - fx) + fetch_texel(tex, texels, row_a + xb) * fx
    bottom = fetch_texel(tex, texels, row_b + xa) * (1.0 - fx) + fetch_texel(tex, texels, row_b + xb) * fx
    return top * (1.0 - fy) + bottom * fy
