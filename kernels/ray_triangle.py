"""The watertight ray-triangle test (Woop, Benthin and Wald 2013), step for step as Warp's
``mesh_query_ray`` runs it, so that a kernel that already knows which triangle a ray meets (the one
a visibility buffer names, one a light buffer's cell lists) gets the very t, u, v a BVH query would
give: the rasterizer's rays for triangles whose plane holds the eye, the render kernel's shading of
rasterized samples and the light buffers' shadow queries share it."""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func_native("return fmaf(a, b, c);")
def fused_multiply_add(a: float, b: float, c: float) -> float: ...


@wp.func
def difference_of_products(a: float, b: float, c: float, d: float) -> float:
    """a b - c d with the rounding of c d compensated (Kahan), as Warp's diff_product."""
    cd = c * d
    return fused_multiply_add(a, b, -cd) + fused_multiply_add(-c, d, cd)


@wp.func
def longest_axis(v: wp.vec3) -> int:
    """Index of the largest |component|, the first on ties (Warp's max_dim)."""
    axis = int(0)
    largest = wp.abs(v[0])
    if wp.abs(v[1]) > largest:
        axis = 1
        largest = wp.abs(v[1])
    if wp.abs(v[2]) > largest:
        axis = 2
    return axis


@wp.func
def ray_triangle_intersection(origin: wp.vec3, direction: wp.vec3, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3):
    """Watertight ray-triangle test (Woop, Benthin and Wald 2013), step for step Warp's
    intersect_ray_tri_woop (warp/native/intersect.h), which ``wp.mesh_query_ray`` runs.

    Returns (hit, t, u, v): the point origin + t direction = p0 u + p1 v + p2 (1 - u - v), Warp's
    barycentric convention. hit is False when the ray misses or t < 0; t, u, v are then those of
    the ray's intersection with the triangle's plane (extrapolated barycentrics), or all 0 when the
    ray is parallel to the plane.
    """
    kz = longest_axis(direction)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    # keep the winding of the sheared triangle
    if direction[kz] < 0.0:
        swap = kx
        kx = ky
        ky = swap
    shear_x = direction[kx] / direction[kz]
    shear_y = direction[ky] / direction[kz]
    shear_z = 1.0 / direction[kz]
    a = p0 - origin
    b = p1 - origin
    c = p2 - origin
    ax = a[kx] - shear_x * a[kz]
    ay = a[ky] - shear_y * a[kz]
    bx = b[kx] - shear_x * b[kz]
    by = b[ky] - shear_y * b[kz]
    cx = c[kx] - shear_x * c[kz]
    cy = c[ky] - shear_y * c[kz]
    eu = difference_of_products(cx, by, cy, bx)
    ev = difference_of_products(ax, cy, ay, cx)
    ew = difference_of_products(bx, ay, by, ax)
    # an edge through the ray: decide its sign in double precision, so neighbours agree
    if eu == 0.0 or ev == 0.0 or ew == 0.0:
        eu = float(wp.float64(cx) * wp.float64(by) - wp.float64(cy) * wp.float64(bx))
        ev = float(wp.float64(ax) * wp.float64(cy) - wp.float64(ay) * wp.float64(cx))
        ew = float(wp.float64(bx) * wp.float64(ay) - wp.float64(by) * wp.float64(ax))
    inside = not ((eu < 0.0 or ev < 0.0 or ew < 0.0) and (eu > 0.0 or ev > 0.0 or ew > 0.0))
    det = eu + ev + ew
    if det == 0.0:
        return False, 0.0, 0.0, 0.0
    scaled_t = eu * (shear_z * a[kz]) + ev * (shear_z * b[kz]) + ew * (shear_z * c[kz])
    behind = (det > 0.0 and scaled_t < 0.0) or (det < 0.0 and scaled_t > 0.0)
    inv_det = 1.0 / det
    return inside and not behind, scaled_t * inv_det, eu * inv_det, ev * inv_det
