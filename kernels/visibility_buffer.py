"""The visibility buffer's entries: one uint64 per sample, (float32 bits of depth) << 32 | triangle
id, so that an unsigned minimum keeps the nearest triangle (the lower id on an exact depth tie) and
NO_TRIANGLE (all ones) means nothing was hit. Depth is camera-space z, the coefficient of
``cam.forward`` in (point - eye): monotone along every camera ray, which is all a per-sample
comparison needs. The rasterizer (kernels/raster.py) writes them; the render kernel and the shadow
maps read them."""

import warp as wp

wp.set_module_options({"enable_backward": False})

NO_TRIANGLE = wp.constant(wp.uint64(0xFFFFFFFFFFFFFFFF))
TRIANGLE_MASK = wp.constant(wp.uint64(0xFFFFFFFF))
DEPTH_SHIFT = wp.constant(wp.uint64(32))


@wp.struct
class VisibilityTarget:
    """A visibility buffer being drawn: ``out``, (height, width spp) entries, sample s of pixel
    (px, py) at [py, px spp + s], and the image positions of those samples (``samples``, of the
    same shape; see sampling.sample_positions)."""

    out: wp.array2d(dtype=wp.uint64)
    samples: wp.array2d(dtype=wp.vec2)
    spp: int


@wp.func_native("wp::uint32 bits; memcpy(&bits, &x, sizeof(bits)); return bits;")
def float_bits(x: float) -> wp.uint32: ...


@wp.func
def visibility_entry(depth: float, triangle: int) -> wp.uint64:
    """The buffer entry of a hit; smaller entries are nearer (depth >= 0)."""
    return (wp.uint64(float_bits(depth)) << DEPTH_SHIFT) | wp.uint64(triangle)


@wp.func
def visible_triangle(entry: wp.uint64) -> int:
    """The triangle id of a buffer entry, -1 for NO_TRIANGLE."""
    if entry == NO_TRIANGLE:
        return -1
    return int(entry & TRIANGLE_MASK)


@wp.func_native("""
    wp::uint64* slot = (wp::uint64*)((char*)out.data + (size_t)row * out.strides[0]) + col;
    if (!shared) { if (entry < *slot) *slot = entry; return; }
    wp::uint64 current = __atomic_load_n(slot, __ATOMIC_RELAXED);
    while (entry < current &&
           !__atomic_compare_exchange_n(slot, &current, entry, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {}
    """)
def keep_nearest(out: wp.array2d(dtype=wp.uint64), row: int, col: int, entry: wp.uint64, shared: bool):
    """out[row, col] = min(out[row, col], entry); atomically if ``shared`` (the sample may be
    written by another thread at the same time), else plainly (its tile is this thread's)."""
    ...


@wp.func_native("memset((wp::uint64*)((char*)out.data + (size_t)row * out.strides[0]) + first, 0xFF, "
                "sizeof(wp::uint64) * (size_t)count);")
def clear_row_span(out: wp.array2d(dtype=wp.uint64), row: int, first: int, count: int):
    """out[row, first:first + count] = NO_TRIANGLE (all bits set) with one memset, which the
    compiler vectorizes where it does not an element-by-element loop; rows must be contiguous."""
    ...


@wp.func_native("""
    const char* base = (const char*)out.data + (size_t)row * out.strides[0] + sizeof(wp::uint64) * (size_t)first;
    for (int offset = 0; offset < (int)(sizeof(wp::uint64) * count); offset += 64) __builtin_prefetch(base + offset, 1, 3);
    """)
def prefetch_row_span(out: wp.array2d(dtype=wp.uint64), row: int, first: int, count: int):
    """Asks for the cache lines of out[row, first:first + count], to be written soon: a tile's
    rows lie a whole image row apart, where the hardware prefetchers do not follow."""
    ...
