"""Light buffers (Haines and Greenberg 1986, "The Light Buffer: A Shadow-Testing Accelerator"): per
light, a grid over the directions it shines in, each cell listing the triangles seen through it,
nearest to the light first. A shadow ray runs from its origin towards the light, so seen from the
light it stays in the cell of its origin: it is tested against that cell's triangles nearer to the
light than its origin only, with the ray caster's own ray-triangle test, and gets the verdict a
BVH any-hit query would give at a fraction of the cost.

Most shadow rays need not even that: where every triangle a cell lists nearer than a triangle T
lies on or behind T's plane (seen from the light), no ray leaving T's lit side through that cell
can meet one, so T's entry there is marked clear; a triangle clear in every cell its rays can
land in (pinhole views) is marked clear of the light, and its rays are lit without a query. On a
convex surface that is every triangle facing the light. On a noisy scanned one, neighbours across
concave creases rise in front of each other's planes; there a triangle's interior (the triangle
shrunk about its centroid) is marked clear where no listed triangle comes near the solid its rays
sweep towards the light (a pyramid to a point or spot light, a prism towards a directional one),
and rays leaving that interior are lit without a query too. A large triangle that something
shadows in part (a floor under a mesh) is cut into regions, squares of its barycentric plane
a few cells across, each marked clear as an interior would be, so that the rays from its lit
part need no query either.

Views are the shadow maps' (kernels/shadow_map.py): a cube of six for point lights and wide spot
lights, one pinhole view for narrow spots, a parallel view behind the scene for directional lights,
in the rasterizer's Projection (cells are its pixels). A ray from a point or spot light whose
origin lies farther inside its cell than the ray can stray (its rounding, in cells) is known to
stay in that cell from its origin's projection alone. A ray whose cells cannot be named cheaply
(it leaves its cube face or its view, or spans more than MAX_QUERY_CELLS cells) is left to the BVH.

The build runs in phases, a file each: the cells' lists (kernels/light_buffer_cells.py), the
triangles' planes as each light sees them (light_buffer_planes.py), the marks of entries and of
whole triangles (light_buffer_marks.py), of triangle interiors (light_buffer_interiors.py) and of
regions of large triangles (light_buffer_regions.py); a shadow ray's query is
light_buffer_query.py's. This file holds what they share: the LightBuffers struct, the marks'
codes and the bounds on a shadow ray's rounding.
"""

import warp as wp

from .projection import Projection

wp.set_module_options({"enable_backward": False})

# Triangles per Warp thread in the per-triangle launches: a CPU launch calls the kernel once per
# thread and copies its arguments each time, which cost more than one triangle's work.
ITEMS_PER_THREAD = wp.constant(64)
# Bound on the angle between a shadow ray's float32 direction and the exact one towards the light,
# relative to (1 + the coordinates' magnitude over the distance): the difference of light and
# origin rounds to half an ulp of the larger per component, the normalization to a few ulps.
DIRECTION_ROUNDING = wp.constant(1.0e-6)
# Nearness values are lowered by this fraction so that rounding never makes a triangle seem
# farther from the light than a point on it.
NEAR_SHRINK = wp.constant(1.0e-6)
# Bound, relative to a triangle's largest coordinate, on how far a shadow ray's origin may lie from
# it: the hit point's rounding and the origin's offset (kernels/robust.py), each at most
# sqrt(3) gamma(7) 3 ~ 2.2e-6 of it.
ORIGIN_DEVIATION = wp.constant(wp.float64(1.0e-5))
# triangle_clear codes: no mark, every ray of the triangle clear, (INTERIOR_CLEAR + k) the rays
# leaving its part shrunk about its centroid by INTERIOR_SHRINKS[k] clear (interior_clear_level),
# or (REGIONS_CLEAR + t) the rays leaving some of its regions clear, as the light's t-th entry of
# region_grids says (mark_clear_regions).
NOT_CLEAR = wp.constant(wp.uint8(0))
CLEAR = wp.constant(wp.uint8(1))
INTERIOR_CLEAR = wp.constant(wp.uint8(2))
# Shrinks tried in turn, the smallest first: a ray whose hit point's barycentric coordinates are
# all at least s / 3 leaves the triangle shrunk by s (it keeps 1 - s of each corner's distance to
# the centroid). The first, 0, is the whole triangle, which the solids can show clear where the
# cells' plane tests (mark_clear_triangles) could not.
INTERIOR_LEVELS = 7
InteriorShrinks = wp.types.vector(length=INTERIOR_LEVELS, dtype=wp.float32)
INTERIOR_SHRINKS = wp.constant(InteriorShrinks(0.0, 0.02, 0.05, 0.1, 0.2, 0.35, 0.6))
REGIONS_CLEAR = wp.constant(wp.uint8(int(INTERIOR_CLEAR) + INTERIOR_LEVELS))
# Large triangles (a floor) are shadowed in parts: their regions are marked one by one. A region
# is a square of the barycentric plane, (b0, b1) in [i, i + 1) x [j, j + 1) over the grid size n,
# so that a hit point finds its region from its barycentrics alone; at most MAX_REGION_TRIANGLES
# triangles per light have regions (the codes left in a uint8).
MAX_REGION_TRIANGLES = wp.constant(255 - int(REGIONS_CLEAR))


@wp.struct
class LightBuffers:
    views: wp.array(dtype=Projection)
    # per pinhole view: a bound on the cells a direction crosses per radian it turns, anywhere in
    # the view (cells_per_radian)
    view_cells_per_radian: wp.array(dtype=wp.float64)
    # per light: (first view, number of views), (0, 0) for a light whose rays go to the BVH
    light_views: wp.array(dtype=wp.vec2i)
    # per light: no triangle lies nearer than this to it (point and spot lights)
    clearance: wp.array(dtype=float)
    # cell c of view v is entry v * resolution^2 + c; its triangles are cell_faces[cell_start[e]:
    # cell_start[e + 1]], ascending in cell_near (a lower bound of their distance to the light, or
    # of their depth in a parallel view)
    cell_start: wp.array(dtype=wp.int32)
    cell_faces: wp.array(dtype=wp.int32)
    cell_near: wp.array(dtype=float)
    # 1 where the entry's triangle is clear in its cell: no triangle listed there can block a shadow
    # ray leaving it towards the light (every one that may lie nearer is behind its plane)
    cell_clear: wp.array(dtype=wp.uint8)
    # per light and triangle (light * triangles + face): CLEAR where every shadow ray leaving the
    # triangle lands in cells where it is clear (pinhole views only), INTERIOR_CLEAR + k where
    # every ray leaving its interior (shrunk by INTERIOR_SHRINKS[k]) meets nothing, so that those
    # need no query, REGIONS_CLEAR + t where its regions are marked (region_grids' t-th entry of
    # the light), else NOT_CLEAR
    triangle_clear: wp.array(dtype=wp.uint8)
    # per light and region triangle (light * MAX_REGION_TRIANGLES + t): (grid size n, first entry of
    # region_clear); region (i, j) is entry first + i n + j, 1 where every ray leaving it is clear
    region_grids: wp.array(dtype=wp.vec2i)
    region_clear: wp.array(dtype=wp.uint8)
    triangles: int
    resolution: int
