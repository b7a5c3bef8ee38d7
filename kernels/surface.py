"""What a ray hit: the hit record and the surface attributes interpolated at it, whether an
alpha-masked material is cut out there, and occlusion tests that pass such cut-outs. Shared by
the render kernel and the shadow maps."""

import functools
from typing import Any

import warp as wp

from .lights import LightSample
from .robust import RAY_FAR, SHADOW_RAY_SHORTENING, offset_ray_origin, safe_normalize, triangle_hit_error
from .scene_data import NO_TEXTURE, MaterialData, SceneData, triangle_corners
from .textures import mip_lod, sample_texture, sample_texture_lod

wp.set_module_options({"enable_backward": False})

# How many culled surfaces (single-sided back faces, alpha-masked texels) a ray may pass through
# before it gives up: a camera ray then reports a miss, an occlusion ray a blocker.
MAX_PASS_THROUGH = wp.constant(16)
# A camera ray stops once what lies further along it weighs no more than this (the part of the
# sample left uncovered by alpha-blended surfaces): below float32's resolution of a pixel's sum.
NEGLIGIBLE_THROUGHPUT = wp.constant(1.0e-7)


@wp.struct
class SurfaceHit:
    p: wp.vec3
    p_error: wp.vec3
    # geometric normal, turned towards the side the ray came from
    ng: wp.vec3
    b0: float
    b1: float
    b2: float
    i0: int
    i1: int
    i2: int
    material: int
    back_face: int
    face: int


@wp.func
def surface_hit(scene: SceneData, face: int, u: float, v: float, ray_dir: wp.vec3) -> SurfaceHit:
    """Hit point from barycentrics (Warp: p = p0 u + p1 v + p2 (1 - u - v)) and the error bound of a ray leaving it."""
    h = SurfaceHit()
    c = triangle_corners(scene.indices, face)
    h.i0 = c[0]
    h.i1 = c[1]
    h.i2 = c[2]
    p0 = scene.positions[h.i0]
    p1 = scene.positions[h.i1]
    p2 = scene.positions[h.i2]
    h.b0 = u
    h.b1 = v
    h.b2 = 1.0 - u - v
    h.p = p0 * h.b0 + p1 * h.b1 + p2 * h.b2
    h.p_error = triangle_hit_error(p0, p1, p2)
    ng = safe_normalize(wp.cross(p1 - p0, p2 - p0), -ray_dir)
    h.back_face = 0
    if wp.dot(ng, ray_dir) > 0.0:
        h.back_face = 1
        ng = -ng
    h.ng = ng
    h.material = scene.face_material[face]
    h.face = face
    return h


@wp.func
def interpolate(a: wp.array(dtype=Any), h: SurfaceHit):
    """A per-vertex attribute at the hit, from its barycentrics."""
    return a[h.i0] * h.b0 + a[h.i1] * h.b1 + a[h.i2] * h.b2


@wp.func
def texture_or_one(scene: SceneData, index: int, uv: wp.vec2) -> wp.vec4:
    """Texture ``index`` at uv, or white for an empty slot."""
    if index == NO_TEXTURE:
        return wp.vec4(1.0)
    return sample_texture(scene.textures[index], scene.texels, uv)


@wp.func
def texture_at(scene: SceneData, index: int, uv: wp.vec2, duv_dx: wp.vec2, duv_dy: wp.vec2) -> wp.vec4:
    """Texture ``index`` at uv, filtered trilinearly over a pixel footprint with the uv
    derivatives duv_dx, duv_dy (kernels/footprint.py): the mip level mip_lod chooses; white for
    an empty slot."""
    if index == NO_TEXTURE:
        return wp.vec4(1.0)
    tex = scene.textures[index]
    return sample_texture_lod(tex, scene.texels, uv, mip_lod(tex, duv_dx, duv_dy))


@wp.func
def segment_to_point(h: SurfaceHit, target: wp.vec3, to_target: wp.vec3):
    """(origin, direction, max_t) of the shadow ray from the hit towards the point ``target``
    (``to_target`` the unit direction from the hit to it): from the hit's offset origin, stopping
    short of the target, so that a surface through the target does not block it."""
    origin = offset_ray_origin(h.p, h.p_error, h.ng, to_target)
    to_point = target - origin
    return origin, safe_normalize(to_point, to_target), wp.length(to_point) * (1.0 - SHADOW_RAY_SHORTENING)


# inlined: a call would copy the scene's struct (~0.6 KB) per shadow ray
@wp.func(inline=True)
def shadow_segment(scene: SceneData, light: int, h: SurfaceHit, ls: LightSample):
    """(origin, direction, max_t) of the shadow ray from the hit to light ``light``: towards the
    light's position (segment_to_point), or along a directional light."""
    if ls.distance < RAY_FAR:
        return segment_to_point(h, scene.lights[light].position, ls.to_light)
    return offset_ray_origin(h.p, h.p_error, h.ng, ls.to_light), ls.to_light, RAY_FAR


@functools.cache
def surface_tests(textured: bool, base_color_texture: bool, masked: bool, second_uv_set: bool):
    """(hit_uv, alpha_at, is_cut_out, nearest_opaque, occluded) for a kernel whose scenes have UVs
    (``textured``), base colour textures, alpha-masked materials (``masked``) and textures read
    with TEXCOORD_1 (``second_uv_set``): each compiled with only what those need.

    - hit_uv(scene, h): the hit's TEXCOORD_0 (0 without textures).
    - alpha_at(scene, h, mat, uv): the material's coverage at the hit, glTF's alpha: base colour
      alpha times vertex colour alpha times base colour texture alpha; ``uv`` is the hit's
      TEXCOORD_0 (TEXCOORD_1 is interpolated here for a base colour texture that reads it). The
      texture is read at level 0, whatever the pixel's footprint: a cut-out is a yes-or-no test,
      and thresholding a coarser level's averaged alpha would thin or thicken cut-outs with
      distance and disagree with the shadow rays, which have no footprint.
    - is_cut_out(scene, h, mat, uv): whether an alpha-masked material (glTF alphaMode MASK) is cut
      out at the hit: its alpha_at below the cutoff.
    - nearest_opaque(scene, origin, direction, max_t) -> (found, hit): the nearest hit of origin
      + t direction, 0 <= t < max_t, not cut out: nearest hit after nearest hit past cut-outs (as
      camera rays pass them); after MAX_PASS_THROUGH cut-outs the last one counts as opaque.
    - occluded(scene, origin, direction, max_t): whether a surface blocks that segment: an any-hit
      query, or nearest_opaque's verdict with masked materials.
    """

    @wp.func
    def hit_uv(scene: SceneData, h: SurfaceHit) -> wp.vec2:
        uv = wp.vec2(0.0)
        if wp.static(textured):
            uv = interpolate(scene.uvs, h)
        return uv

    @wp.func
    def alpha_at(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> float:
        alpha = mat.base_color[3] * interpolate(scene.colors, h)[3]
        if wp.static(base_color_texture):
            at = uv
            if wp.static(second_uv_set):
                if mat.base_color_texture != NO_TEXTURE:
                    if scene.textures[mat.base_color_texture].uv_set == 1:
                        at = interpolate(scene.uvs1, h)
            alpha = alpha * texture_or_one(scene, mat.base_color_texture, at)[3]
        return alpha

    @wp.func
    def is_cut_out(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> bool:
        if mat.alpha_mask == 1:
            return alpha_at(scene, h, mat, uv) < mat.alpha_cutoff
        return False

    # inlined: a call would copy the scene's struct (~0.6 KB) per ray
    @wp.func(inline=True)
    def nearest_opaque(scene: SceneData, origin: wp.vec3, direction: wp.vec3, max_t: float):
        o = origin
        reach = max_t
        h = SurfaceHit()
        for _ in range(MAX_PASS_THROUGH):
            q = wp.mesh_query_ray(scene.mesh, o, direction, reach)
            if not q.result:
                return False, h
            h = surface_hit(scene, q.face, q.u, q.v, direction)
            if not is_cut_out(scene, h, scene.materials[h.material], hit_uv(scene, h)):
                return True, h
            o = offset_ray_origin(h.p, h.p_error, h.ng, direction)
            reach = reach - q.t
        return True, h

    @wp.func
    def occluded(scene: SceneData, origin: wp.vec3, direction: wp.vec3, max_t: float) -> bool:
        if wp.static(not masked):
            return wp.mesh_query_ray_anyhit(scene.mesh, origin, direction, max_t)
        found, h = nearest_opaque(scene, origin, direction, max_t)
        return found

    return hit_uv, alpha_at, is_cut_out, nearest_opaque, occluded
