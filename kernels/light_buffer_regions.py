"""Marks of regions of large triangles. A triangle that something shadows in part (a floor under a
mesh) gets a grid of regions, squares of its barycentric plane a few cells across, each marked
clear of a light as an interior would be (mark_clear_regions), so that the shadow rays from its lit
part need no query either; a hit point finds its region from its barycentrics alone
(region_is_clear)."""

import warp as wp

from .light_buffer import ITEMS_PER_THREAD, MAX_REGION_TRIANGLES, REGIONS_CLEAR, LightBuffers
from .light_buffer_interiors import interior_clear_level
from .light_buffer_planes import origin_magnitude
from .robust import to_double
from .scene_data import triangle_corners
from .shadow_map import CUBE_FACES

wp.set_module_options({"enable_backward": False})

# A hit point's float32 barycentrics are within this of the exact ones (a few ulps of 1): the
# regions are grown by three times it (b0 = 1 - b1 - b2 adds two), and a point whose barycentrics
# lie farther than it outside the triangle (an edge sample's extrapolated ones) is not looked up.
REGION_SLACK = wp.constant(1.0e-5)


@wp.func
def region_corner(p0: wp.vec3d, p1: wp.vec3d, p2: wp.vec3d, b0: wp.float64, b1: wp.float64) -> wp.vec3:
    """The point with barycentric coordinates (b0, b1, 1 - b0 - b1), in float32."""
    return wp.vec3(p2 + (p0 - p2) * b0 + (p1 - p2) * b1)


# inlined: a call would copy the light buffers' struct (~0.6 KB) per region part
@wp.func(inline=True)
def region_part_is_clear(buffers: LightBuffers, light: int, face: int, positions: wp.array(dtype=wp.vec3),
                         indices: wp.array(dtype=wp.int32), c0: wp.vec3, c1: wp.vec3, c2: wp.vec3,
                         origin_scale: wp.float64) -> bool:
    """Whether every shadow ray towards ``light`` leaving triangle c (a part of triangle ``face``)
    meets nothing, in every view of the light: its first interior level, the whole of it."""
    span = buffers.light_views[light]
    for v in range(span[0], span[0] + span[1]):
        if interior_clear_level(buffers, v, span[1] == CUBE_FACES, face, positions, indices, c0, c1, c2, 0,
                                origin_scale) != 0:
            return False
    return True


@wp.kernel
def mark_clear_regions(buffers: LightBuffers, light: int, positions: wp.array(dtype=wp.vec3),
                       indices: wp.array(dtype=wp.int32), face: int, grid: wp.vec2i, first: int, end: int):
    """Per region r = i n + j in [first, end) of triangle ``face``'s grid (size n = grid[0], flags
    from grid[1] on): 1 in region_clear where every shadow ray towards ``light`` leaving the region
    meets nothing. The region, grown by three REGION_SLACKs, is a parallelogram: two triangles,
    each shown clear as an interior would be (the float32 rounding of their corners is far within
    the origins' deviation, taken from the whole triangle's coordinates)."""
    c = triangle_corners(indices, face)
    p0 = to_double(positions[c[0]])
    p1 = to_double(positions[c[1]])
    p2 = to_double(positions[c[2]])
    scale = origin_magnitude(p0, p1, p2, wp.float64(0.0))
    n = grid[0]
    grow = wp.float64(3.0 * REGION_SLACK)
    start = first + wp.tid() * ITEMS_PER_THREAD
    for r in range(start, wp.min(start + ITEMS_PER_THREAD, end)):
        i = r // n
        j = r % n
        clear = wp.uint8(0)
        if i + j < n:
            a0 = wp.float64(i) / wp.float64(n) - grow
            a1 = wp.float64(i + 1) / wp.float64(n) + grow
            e0 = wp.float64(j) / wp.float64(n) - grow
            e1 = wp.float64(j + 1) / wp.float64(n) + grow
            q00 = region_corner(p0, p1, p2, a0, e0)
            q10 = region_corner(p0, p1, p2, a1, e0)
            q11 = region_corner(p0, p1, p2, a1, e1)
            q01 = region_corner(p0, p1, p2, a0, e1)
            if (region_part_is_clear(buffers, light, face, positions, indices, q00, q10, q11, scale)
                    and region_part_is_clear(buffers, light, face, positions, indices, q00, q11, q01, scale)):
                clear = wp.uint8(1)
        buffers.region_clear[grid[1] + r] = clear


@wp.func
def region_is_clear(buffers: LightBuffers, light: int, mark: wp.uint8, b0: float, b1: float, b2: float) -> bool:
    """Whether the region of the point with barycentric coordinates (b0, b1, b2) of a triangle with
    region mark ``mark`` is marked clear (mark_clear_regions)."""
    if b0 < -REGION_SLACK or b1 < -REGION_SLACK or b2 < -REGION_SLACK:
        return False
    grid = buffers.region_grids[light * MAX_REGION_TRIANGLES + int(mark - REGIONS_CLEAR)]
    n = grid[0]
    i = wp.clamp(int(b0 * float(n)), 0, n - 1)
    # where b0 + b1 rounds above 1, the region below it (grown by the slack) holds the point
    j = wp.clamp(int(b1 * float(n)), 0, n - 1 - i)
    return buffers.region_clear[grid[1] + i * n + j] != wp.uint8(0)
