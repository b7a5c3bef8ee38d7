"""Morton (Z-order) codes of triangle centroids, by which pbrwarp/locality.py orders a scene's
triangles for memory locality."""

import warp as wp

wp.set_module_options({"enable_backward": False})

# Bits of each coordinate in a code: 3 x 21 fill a uint64. Cells of 2^-21 of the scene's extent
# keep apart what a coarser grid would tie (a small object standing on a huge floor).
MORTON_BITS = 21
MORTON_CELLS = wp.constant(float(2**MORTON_BITS - 1))


@wp.func
def spread_bits(v: wp.uint64) -> wp.uint64:
    """The low 21 bits of v moved to every third bit position (bit i to bit 3 i)."""
    x = v & wp.uint64(0x1FFFFF)
    x = (x | (x << wp.uint64(32))) & wp.uint64(0x1F00000000FFFF)
    x = (x | (x << wp.uint64(16))) & wp.uint64(0x1F0000FF0000FF)
    x = (x | (x << wp.uint64(8))) & wp.uint64(0x100F00F00F00F00F)
    x = (x | (x << wp.uint64(4))) & wp.uint64(0x10C30C30C30C30C3)
    x = (x | (x << wp.uint64(2))) & wp.uint64(0x1249249249249249)
    return x


@wp.func
def morton_cell(x: float, lo: float, scale: float) -> wp.uint64:
    return wp.uint64(wp.clamp((x - lo) * scale, 0.0, MORTON_CELLS))


@wp.kernel
def centroid_morton_codes(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), lo: wp.vec3,
                          scale: float, codes: wp.array(dtype=wp.uint64)):
    """Code of each triangle's centroid, its coordinates quantized as (x - lo) scale on
    [0, 2^21 - 1] (indices must be valid: checked by the caller)."""
    face = wp.tid()
    c = (positions[indices[3 * face]] + positions[indices[3 * face + 1]] + positions[indices[3 * face + 2]]) / 3.0
    codes[face] = (spread_bits(morton_cell(c[0], lo[0], scale))
                   | (spread_bits(morton_cell(c[1], lo[1], scale)) << wp.uint64(1))
                   | (spread_bits(morton_cell(c[2], lo[2], scale)) << wp.uint64(2)))
