"""World to screen: the rasterizer's projection (kernels/raster.py) and its screen rectangles,
which its occlusion culling (kernels/occlusion.py) and the light buffers (kernels/light_buffer.py)
share."""

import warp as wp

from .camera import CameraData
from .robust import to_double

wp.set_module_options({"enable_backward": False})

# Vertices and samples are snapped to 1/4096 pixel: far below what the float32 ray caster
# resolves, and coarse enough that edge functions fit int64 (see kernels/triangle_setup.py
# GUARD_BAND).
SUBPIXEL_BITS = wp.constant(wp.int64(12))
SUBPIXEL_SCALE = wp.constant(wp.float64(4096.0))
PIXEL = wp.constant(wp.int64(4096))
HALF_PIXEL = wp.constant(wp.int64(2048))


@wp.struct
class Projection:
    """World to screen: camera coordinates (a, b, z) with point - eye = a right + b up + z forward
    (CameraData's scaled axes), then pixel coordinates ((a/z + 1) w/2, (1 - b/z) h/2), the inverse
    of camera_ray_direction."""

    eye: wp.vec3d
    to_camera: wp.mat33d
    half_width: wp.float64
    half_height: wp.float64
    width: int
    height: int
    # 1: parallel projection along z, (a, b) in [-1, 1] spanning the view, depth z linear on screen
    orthographic: int
    # the sign of signed_area for triangles facing away from the eye (their vertices in
    # counter-clockwise order seen from behind): +1, or -1 for a mirrored camera
    back_facing_sign: wp.int64


@wp.func
def camera_projection(cam: CameraData, orthographic: int) -> Projection:
    """The Projection of ``cam`` in float64, the exact inverse of camera_ray_direction: to_camera
    inverts the matrix of columns right, up, forward (its rows b x c, c x a, a x b over the
    determinant, for columns a, b, c); or, ``orthographic`` nonzero, the parallel projection
    along forward whose view spans right and up (half-extents in world units) about the eye.
    Meaningful where has_usable_axes(cam)."""
    a = to_double(cam.right)
    b = to_double(cam.up)
    c = to_double(cam.forward)
    row0 = wp.cross(b, c)
    row1 = wp.cross(c, a)
    row2 = wp.cross(a, b)
    det = wp.dot(a, row0)
    proj = Projection()
    proj.eye = to_double(cam.eye)
    proj.to_camera = wp.mat33d(row0[0] / det, row0[1] / det, row0[2] / det, row1[0] / det, row1[1] / det,
                               row1[2] / det, row2[0] / det, row2[1] / det, row2[2] / det)
    proj.half_width = wp.float64(0.5) * wp.float64(cam.width)
    proj.half_height = wp.float64(0.5) * wp.float64(cam.height)
    proj.width = cam.width
    proj.height = cam.height
    proj.orthographic = wp.where(orthographic != 0, 1, 0)
    # a triangle whose vertices run counter-clockwise seen from the eye projects with area of
    # the sign of det(axes) (screen y points down)
    proj.back_facing_sign = wp.where(det > wp.float64(0.0), wp.int64(-1), wp.int64(1))
    return proj


@wp.func
def has_usable_axes(cam: CameraData) -> bool:
    """Whether cam's axes are finite and linearly independent (a determinant of magnitude at
    least 1e-300), as camera_projection needs. (An eye out of float range, as a camera framing
    a scene near float32's limit has, projects every vertex as not drawable: nothing is drawn.)"""
    det = wp.dot(to_double(cam.right), wp.cross(to_double(cam.up), to_double(cam.forward)))
    finite = wp.isfinite(cam.right) and wp.isfinite(cam.up) and wp.isfinite(cam.forward)
    return finite and wp.abs(det) >= wp.float64(1.0e-300)


@wp.kernel
def projection_of(cam: CameraData, orthographic: int, out: wp.array(dtype=Projection),
                  usable: wp.array(dtype=wp.int32)):
    out[0] = camera_projection(cam, orthographic)
    usable[0] = wp.where(has_usable_axes(cam), 1, 0)


@wp.func
def camera_coordinates(proj: Projection, p: wp.vec3) -> wp.vec3d:
    return proj.to_camera * (to_double(p) - proj.eye)


@wp.func
def screen_point(proj: Projection, c: wp.vec3d) -> wp.vec2d:
    """Pixel coordinates (x, y) of a point with camera coordinates c (c.z > 0 in perspective);
    one reciprocal of z serves both, as division costs several multiplications."""
    if proj.orthographic != 0:
        return wp.vec2d((c[0] + wp.float64(1.0)) * proj.half_width, (wp.float64(1.0) - c[1]) * proj.half_height)
    inverse_z = wp.float64(1.0) / c[2]
    return wp.vec2d((c[0] * inverse_z + wp.float64(1.0)) * proj.half_width,
                    (wp.float64(1.0) - c[1] * inverse_z) * proj.half_height)


@wp.func
def empty_rect() -> wp.vec4i:
    return wp.vec4i(0, 0, -1, -1)


@wp.func
def clamped_rect(x0: int, y0: int, x1: int, y1: int, width: int, height: int) -> wp.vec4i:
    """Pixels [x0, x1] x [y0, y1] (inclusive) inside the image; empty_rect() if none."""
    r = wp.vec4i(wp.max(x0, 0), wp.max(y0, 0), wp.min(x1, width - 1), wp.min(y1, height - 1))
    if r[0] > r[2] or r[1] > r[3]:
        return empty_rect()
    return r


@wp.func
def pixels_around(proj: Projection, bounds: wp.vec4d) -> wp.vec4i:
    """Pixels of the image whose samples (anywhere in [p, p + 1]) may lie within screen bounds
    (min x, min y, max x, max y), with a pixel of margin for the rounding of the projection;
    clamped before the conversion to int, so bounds may be huge or infinite."""
    w = wp.float64(proj.width)
    h = wp.float64(proj.height)
    x0 = int(wp.floor(wp.clamp(bounds[0], wp.float64(-2.0), w + wp.float64(2.0)))) - 1
    x1 = int(wp.floor(wp.clamp(bounds[2], wp.float64(-2.0), w + wp.float64(2.0)))) + 1
    y0 = int(wp.floor(wp.clamp(bounds[1], wp.float64(-2.0), h + wp.float64(2.0)))) - 1
    y1 = int(wp.floor(wp.clamp(bounds[3], wp.float64(-2.0), h + wp.float64(2.0)))) + 1
    return clamped_rect(x0, y0, x1, y1, proj.width, proj.height)


# How far (pixels) a vertex's snapped screen position may lie from where the float64 projection
# of a box around it puts the box's side: the snapping (1/8192 pixel) and the rounding of the two
# projections (~1e-10 pixel within the guard band), with room to spare.
SCREEN_TOLERANCE = wp.constant(wp.float64(1.0 / 1024.0))


@wp.func
def sampled_pixel_range(lo: wp.int64, hi: wp.int64, spp: int) -> wp.vec2i:
    """First and last pixel with a sample in [lo, hi] (fixed point). With spp = 1 a pixel's sample
    is its centre; with more it lies anywhere in [p, p + 1] (float32 p + offset may round up)."""
    if spp == 1:
        return wp.vec2i(int(-((HALF_PIXEL - lo) >> SUBPIXEL_BITS)), int((hi - HALF_PIXEL) >> SUBPIXEL_BITS))
    return wp.vec2i(int((lo - wp.int64(1)) >> SUBPIXEL_BITS), int(hi >> SUBPIXEL_BITS))


@wp.func
def sampled_pixels_within(proj: Projection, bounds: wp.vec4d, spp: int) -> wp.vec4i:
    """Pixels of the image with a sample the rasterizer may find within screen bounds (min x,
    min y, max x, max y) of projected vertices: sampled_pixel_range of the bounds SCREEN_TOLERANCE
    wider, in fixed point (rounded outwards), clamped first (bounds may be huge or infinite)."""
    w = wp.float64(proj.width)
    h = wp.float64(proj.height)
    lo_x = wp.int64(wp.floor(wp.clamp(bounds[0] - SCREEN_TOLERANCE, wp.float64(-2.0), w + wp.float64(2.0))
                             * SUBPIXEL_SCALE))
    lo_y = wp.int64(wp.floor(wp.clamp(bounds[1] - SCREEN_TOLERANCE, wp.float64(-2.0), h + wp.float64(2.0))
                             * SUBPIXEL_SCALE))
    hi_x = wp.int64(wp.ceil(wp.clamp(bounds[2] + SCREEN_TOLERANCE, wp.float64(-2.0), w + wp.float64(2.0))
                            * SUBPIXEL_SCALE))
    hi_y = wp.int64(wp.ceil(wp.clamp(bounds[3] + SCREEN_TOLERANCE, wp.float64(-2.0), h + wp.float64(2.0))
                            * SUBPIXEL_SCALE))
    x = sampled_pixel_range(lo_x, hi_x, spp)
    y = sampled_pixel_range(lo_y, hi_y, spp)
    return clamped_rect(x[0], y[0], x[1], y[1], proj.width, proj.height)
