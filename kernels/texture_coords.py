"""A hit's texture coordinates and the lookups that use them.

Each uv set (TEXCOORD_0, and TEXCOORD_1 where a texture reads it) comes with its pixel
footprint: the uv derivatives per pixel step from the camera's ray differentials
(kernels/footprint.py). A kernel is built with trilinear filtering over that footprint, or with
level-0 bilinear lookups (no footprint computed), and with or without the second set.
"""

import functools

import warp as wp

from .footprint import tangent_plane_offset, triangle_dp_duv, uv_derivative
from .scene_data import NO_TEXTURE, SceneData
from .surface import SurfaceHit, interpolate, texture_at, texture_or_one

wp.set_module_options({"enable_backward": False})


@wp.struct
class SurfaceUV:
    """The hit's uv sets, each with its derivatives per pixel step in x and y (zero where the
    kernel computes no footprint)."""

    uv: wp.vec2  # TEXCOORD_0
    duv_dx: wp.vec2
    duv_dy: wp.vec2
    uv1: wp.vec2  # TEXCOORD_1 (a copy of TEXCOORD_0 in kernels built without it)
    duv1_dx: wp.vec2
    duv1_dy: wp.vec2


@wp.func
def uv_footprint(uvs: wp.array(dtype=wp.vec2), h: SurfaceHit, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3,
                 dp_dx: wp.vec3, dp_dy: wp.vec3):
    """(duv/dx, duv/dy) of the uv set ``uvs`` over triangle (p0, p1, p2) for the offsets dp_dx,
    dp_dy on the tangent plane of the neighbouring pixels' rays."""
    dpdu, dpdv = triangle_dp_duv(p0, p1, p2, uvs[h.i0], uvs[h.i1], uvs[h.i2])
    return uv_derivative(dpdu, dpdv, dp_dx), uv_derivative(dpdu, dpdv, dp_dy)


@wp.func
def no_texture(scene: SceneData, index: int, c: SurfaceUV) -> wp.vec4:
    """White, the texture of an empty slot: stands in for texture_lookups' ``texture`` where a
    layer's textures are not compiled in."""
    return wp.vec4(1.0)


@functools.cache
def texture_lookups(textured: bool, footprint: bool, second_uv_set: bool):
    """(hit_texcoords, texture) for a kernel whose scenes have UVs (``textured``), filtering
    trilinearly over each pixel's footprint (``footprint``; else bilinearly at level 0) and
    reading TEXCOORD_1 where a texture asks for it (``second_uv_set``).

    - hit_texcoords(scene, h, uv, eye, dir_dx, dir_dy) -> SurfaceUV: the hit's uv sets (``uv`` is
      its TEXCOORD_0, surface_tests' hit_uv) with their footprints, the rays from ``eye`` along
      dir_dx and dir_dy being those through the points one pixel step to the right and below the
      sample (pbrt-v4's ray differentials). The rays of a pinhole camera all leave the eye, so
      the same two serve every surface a camera ray passes through.
    - texture(scene, index, c) -> vec4: texture ``index`` (white for an empty slot) at the uv set
      it reads, filtered as the kernel is built.
    """

    @wp.func
    def hit_texcoords(scene: SceneData, h: SurfaceHit, uv: wp.vec2, eye: wp.vec3, dir_dx: wp.vec3,
                      dir_dy: wp.vec3) -> SurfaceUV:
        c = SurfaceUV()
        c.uv = uv
        c.uv1 = uv
        if wp.static(textured and second_uv_set):
            c.uv1 = interpolate(scene.uvs1, h)
        if wp.static(textured and footprint):
            p0 = scene.positions[h.i0]
            p1 = scene.positions[h.i1]
            p2 = scene.positions[h.i2]
            dp_dx = tangent_plane_offset(h.p, h.ng, eye, dir_dx)
            dp_dy = tangent_plane_offset(h.p, h.ng, eye, dir_dy)
            du_dx, du_dy = uv_footprint(scene.uvs, h, p0, p1, p2, dp_dx, dp_dy)
            c.duv_dx = du_dx
            c.duv_dy = du_dy
            c.duv1_dx = du_dx
            c.duv1_dy = du_dy
            if wp.static(second_uv_set):
                du1_dx, du1_dy = uv_footprint(scene.uvs1, h, p0, p1, p2, dp_dx, dp_dy)
                c.duv1_dx = du1_dx
                c.duv1_dy = du1_dy
        return c

    @wp.func
    def texture(scene: SceneData, index: int, c: SurfaceUV) -> wp.vec4:
        uv = c.uv
        duv_dx = c.duv_dx
        duv_dy = c.duv_dy
        if wp.static(second_uv_set):
            if index != NO_TEXTURE:
                if scene.textures[index].uv_set == 1:
                    uv = c.uv1
                    duv_dx = c.duv1_dx
                    duv_dy = c.duv1_dy
        if wp.static(footprint):
            return texture_at(scene, index, uv, duv_dx, duv_dy)
        return texture_or_one(scene, index, uv)

    return hit_texcoords, texture
