"""Shadow maps: depth seen from each light, rasterized by the visibility-buffer rasterizer
(kernels/raster.py), and the percentage-closer lookup that replaces a shadow ray (Williams 1978;
Reeves, Salesin and Cook 1987)."""

import functools

import warp as wp

from .camera import CameraData, camera_ray_direction
from .robust import RAY_FAR
from .scene_data import SceneData
from .surface import surface_tests
from .visibility_buffer import NO_TRIANGLE, visibility_entry, visible_triangle

wp.set_module_options({"enable_backward": False})

# Cube faces of point lights (and of spot lights too wide for one view), in this order.
CUBE_FACES = 6


@wp.struct
class ShadowView:
    """One depth map's view, as the rasterizer's Projection: camera coordinates (a, b, z) =
    to_camera (p - eye), texel ((a/z + 1) res/2, (1 - b/z) res/2) for a pinhole view (point and
    spot lights), ((a + 1) res/2, (1 - b) res/2) for a parallel one (directional lights)."""

    eye: wp.vec3
    to_camera: wp.mat33
    resolution: int
    orthographic: int
    # world size of a texel: at depth 1 for a pinhole view (2 tan(fov/2) / resolution; it grows
    # with depth), everywhere for a parallel one
    texel_size: float


@wp.struct
class ShadowMaps:
    # (views, resolution, resolution) camera-space depth of the nearest surface, +inf for none
    depth: wp.array3d(dtype=float)
    views: wp.array(dtype=ShadowView)
    # per light: (first view, number of views), (0, 0) for a light without a map
    light_views: wp.array(dtype=wp.vec2i)
    # receiver offset along its normal and depth tolerance, in texels at the receiver's depth
    bias: float
    # side of the square of texels averaged by percentage-closer filtering (1 = a single texel)
    pcf: int


@wp.func
def cube_face(d: wp.vec3) -> int:
    """The cube face (+x, -x, +y, -y, +z, -z) that direction d points into."""
    ax = wp.abs(d[0])
    ay = wp.abs(d[1])
    az = wp.abs(d[2])
    if ax >= ay and ax >= az:
        return wp.where(d[0] >= 0.0, 0, 1)
    if ay >= az:
        return wp.where(d[1] >= 0.0, 2, 3)
    return wp.where(d[2] >= 0.0, 4, 5)


@wp.func
def fraction_lit(maps: ShadowMaps, view_index: int, p: wp.vec3, ng: wp.vec3) -> float:
    """Share of the PCF taps around p's texel whose stored depth does not occlude p.

    p is first moved off its surface along its geometric normal ng (turned towards the light) by
    ``bias`` texels of its own depth ("normal offset", Holbert 2011), and compared with a tolerance
    of as many texels: both scale with the texel footprint, so the result does not depend on the
    scene's scale, and a surface never shadows itself unless it is tilted beyond atan(bias) per
    texel (grazing light), where n.l already darkens it."""
    view = maps.views[view_index]
    depth = (view.to_camera * (p - view.eye))[2]
    if depth <= 0.0:
        return 1.0
    texel = view.texel_size * maps.bias
    if view.orthographic == 0:
        texel = texel * depth
    c = view.to_camera * (p + ng * texel - view.eye)
    if c[2] <= 0.0:
        return 1.0
    a = c[0]
    b = c[1]
    if view.orthographic == 0:
        a = a / c[2]
        b = b / c[2]
    half = 0.5 * float(view.resolution)
    x = (a + 1.0) * half - 0.5
    y = (1.0 - b) * half - 0.5
    if x < -0.5 or y < -0.5 or x > float(view.resolution) - 0.5 or y > float(view.resolution) - 0.5:
        return 1.0
    first_x = int(wp.round(x)) - maps.pcf / 2
    first_y = int(wp.round(y)) - maps.pcf / 2
    last = view.resolution - 1
    lit = int(0)
    for j in range(maps.pcf):
        ty = wp.clamp(first_y + j, 0, last)
        for i in range(maps.pcf):
            tx = wp.clamp(first_x + i, 0, last)
            if c[2] <= maps.depth[view_index, ty, tx] + texel:
                lit += 1
    return float(lit) / float(maps.pcf * maps.pcf)


@wp.func
def shadow_map_visibility(maps: ShadowMaps, light: int, light_position: wp.vec3, p: wp.vec3, ng: wp.vec3) -> float:
    """Fraction of light ``light`` reaching p by its shadow map(s): one view for directional and
    narrow spot lights, the cube face towards p for the others."""
    span = maps.light_views[light]
    if span[1] == 0:
        return 1.0
    view = span[0]
    if span[1] == CUBE_FACES:
        view = span[0] + cube_face(p - light_position)
    return fraction_lit(maps, view, p, ng)


@functools.cache
def cut_out_pass():
    """The kernel that lets a depth map see through alpha cut-outs (built on first use)."""
    _, _, _, nearest_opaque, _ = surface_tests(True, True, True, True)

    @wp.kernel(enable_backward=False, module="unique")
    def see_through_cut_outs(scene: SceneData, cam: CameraData, orthographic: int, first_row: int,
                             buffer: wp.array2d(dtype=wp.uint64)):
        """Per row (from first_row) of a rasterized depth map: each texel whose nearest triangle
        is alpha-masked gets instead the first surface not cut out along its ray (from the eye
        through the texel centre, or along cam.forward from the texel's point on the eye's plane
        in a parallel view), or none."""
        y = first_row + wp.tid()
        for x in range(buffer.shape[1]):
            face = visible_triangle(buffer[y, x])
            if face >= 0:
                if scene.materials[scene.face_material[face]].alpha_mask == 1:
                    fx = float(x) + 0.5
                    fy = float(y) + 0.5
                    origin = cam.eye
                    direction = camera_ray_direction(cam, fx, fy)
                    if orthographic != 0:
                        origin = (cam.eye + cam.right * (2.0 * fx / float(cam.width) - 1.0)
                                  + cam.up * (1.0 - 2.0 * fy / float(cam.height)))
                        direction = cam.forward
                    found, h = nearest_opaque(scene, origin, direction, RAY_FAR)
                    entry = NO_TRIANGLE
                    if found:
                        entry = visibility_entry(wp.dot(h.p - cam.eye, cam.forward), h.face)
                    buffer[y, x] = entry

    return see_through_cut_outs
