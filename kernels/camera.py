"""Primary rays of a pinhole camera."""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.struct
class CameraData:
    eye: wp.vec3
    forward: wp.vec3
    # right and up, scaled by the half-extent of the image plane at distance 1
    right: wp.vec3
    up: wp.vec3
    width: int
    height: int


@wp.func
def camera_ray_direction(cam: CameraData, x: float, y: float) -> wp.vec3:
    """Unit direction through the image point (x, y) in pixels, (0, 0) the top-left corner."""
    # a product with the reciprocal, which a pixel loop computes once, rather than a division
    ndc_x = x * (2.0 / float(cam.width)) - 1.0
    ndc_y = 1.0 - y * (2.0 / float(cam.height))
    return wp.normalize(cam.forward + cam.right * ndc_x + cam.up * ndc_y)


@wp.func
def sample_footprint_side(spp: int) -> float:
    """The side, in pixels, of one sample's share of a pixel taking ``spp`` samples: one of spp
    strata, 1/sqrt(spp). Ray differentials this far apart give each sample the texture footprint
    of its own share, so that the mean of the samples is the pixel's box filter and no wider
    (pbrt-v4's integrators scale their camera ray differentials by 1/sqrt(spp) likewise)."""
    return 1.0 / wp.sqrt(float(spp))
