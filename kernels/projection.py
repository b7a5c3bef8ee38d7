"""World to screen: the rasterizer's projection (kernels/raster.py), which its occlusion culling
(kernels/occlusion.py) and the light buffers (kernels/light_buffer.py) share."""

import warp as wp

wp.set_module_options({"enable_backward": False})


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
def camera_coordinates(proj: Projection, p: wp.vec3) -> wp.vec3d:
    return proj.to_camera * (wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2])) - proj.eye)


@wp.func
def screen_point(proj: Projection, c: wp.vec3d) -> wp.vec2d:
    """Pixel coordinates (x, y) of a point with camera coordinates c (c.z > 0 in perspective);
    one reciprocal of z serves both, as division costs several multiplications."""
    if proj.orthographic != 0:
        return wp.vec2d((c[0] + wp.float64(1.0)) * proj.half_width, (wp.float64(1.0) - c[1]) * proj.half_height)
    inverse_z = wp.float64(1.0) / c[2]
    return wp.vec2d((c[0] * inverse_z + wp.float64(1.0)) * proj.half_width,
                    (wp.float64(1.0) - c[1] * inverse_z) * proj.half_height)
