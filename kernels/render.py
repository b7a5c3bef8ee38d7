"""The render kernel: camera rays, closest hit, surface attributes, direct lighting with shadow
rays, accumulated over stratified sub-pixel samples. Built per feature set, so the compiled
code holds only what a scene needs."""

import dataclasses
import functools
from typing import Any

import warp as wp

from .ambient import ambient_for
from .brdf import brdf_for
from .ibl import EnvironmentData, environment_radiance
from .camera import CameraData, camera_ray_direction
from .light_buffer import LightBuffers, UNDECIDED, OCCLUDED, light_buffer_occlusion, triangle_is_clear
from .lights import LightSample, light_sampler
from .normal_mapping import perturb_normal
from .raster import ray_triangle_intersection, triangle_corners, visible_triangle
from .robust import (
    RAY_FAR,
    clamp_to_float32_max,
    SHADOW_RAY_SHORTENING,
    triangle_hit_error,
    offset_ray_origin,
    safe_normalize,
)
from .sampling import multi_jittered_sample
from .scene_data import NO_TEXTURE, MaterialData, SceneData
from .shadow_map import ShadowMaps, shadow_map_visibility
from .textures import sample_texture

wp.set_module_options({"enable_backward": False})

# How many culled surfaces (single-sided back faces, alpha-masked texels) a camera ray may pass
# through before it gives up and reports a miss.
MAX_PASS_THROUGH = wp.constant(16)


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


@functools.cache
def render_kernel(features):
    """The tile kernel for a ``features`` value (hashable; see pbrwarp.features.Features).

    Each flag is a compile-time constant: code for an absent effect is not generated at all.
    """
    f = features
    textured = f.textures
    brdf = brdf_for(f.diffuse, f.specular, **dataclasses.asdict(f.brdf))
    sample_light = light_sampler(f.point_lights, f.directional_lights, f.spot_lights)
    lit = f.point_lights or f.directional_lights or f.spot_lights
    ibl = f.environment
    shaded = lit or bool(ibl)

    @wp.func
    def is_cut_out(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> bool:
        """Whether an alpha-masked material is cut out at the hit (glTF alphaMode MASK)."""
        if mat.alpha_mask == 1:
            alpha = mat.base_color[3] * interpolate(scene.colors, h)[3]
            if wp.static(f.base_color_texture):
                alpha = alpha * texture_or_one(scene, mat.base_color_texture, uv)[3]
            return alpha < mat.alpha_cutoff
        return False

    @wp.func
    def is_culled(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> bool:
        if h.back_face == 1 and mat.double_sided == 0:
            return True
        return is_cut_out(scene, h, mat, uv)

    @wp.func
    def hit_uv(scene: SceneData, h: SurfaceHit) -> wp.vec2:
        uv = wp.vec2(0.0)
        if wp.static(textured):
            uv = interpolate(scene.uvs, h)
        return uv

    @wp.func
    def occluded(scene: SceneData, origin: wp.vec3, direction: wp.vec3, max_t: float) -> bool:
        """Whether a surface blocks origin + t direction, 0 <= t < max_t (shadow rays, shadowed
        environment directions). With alpha-masked materials the ray passes their cut-outs, nearest
        hit after nearest hit as camera rays do; still blocked after MAX_PASS_THROUGH, it counts as
        occluded."""
        if wp.static(not f.masked_occlusion):
            return wp.mesh_query_ray_anyhit(scene.mesh, origin, direction, max_t)
        o = origin
        reach = max_t
        for _ in range(MAX_PASS_THROUGH):
            q = wp.mesh_query_ray(scene.mesh, o, direction, reach)
            if not q.result:
                return False
            h = surface_hit(scene, q.face, q.u, q.v, direction)
            if not is_cut_out(scene, h, scene.materials[h.material], hit_uv(scene, h)):
                return True
            o = offset_ray_origin(h.p, h.p_error, h.ng, direction)
            reach = reach - q.t
        return True

    if ibl:
        ambient = ambient_for(ibl.method, ibl.fresnel, ibl.samples, ibl.shadowed, f.brdf.energy == "multiscatter",
                              f.brdf.coupling != "none" and f.diffuse and f.specular, brdf, occluded)

    @wp.func
    def shade(scene: SceneData, maps: ShadowMaps, buffers: LightBuffers, env: EnvironmentData,
              dfg: wp.array2d(dtype=wp.vec2), h: SurfaceHit, mat: MaterialData, uv: wp.vec2, view: wp.vec3,
              n: wp.vec3, seed: int, stream: int) -> wp.vec3:
        radiance = wp.vec3(0.0)
        if wp.static(f.emission):
            radiance = mat.emissive
            if wp.static(f.emissive_texture):
                em = texture_or_one(scene, mat.emissive_texture, uv)
                radiance = wp.cw_mul(radiance, wp.vec3(em[0], em[1], em[2]))
        if wp.static(shaded):
            base = wp.vec3(mat.base_color[0], mat.base_color[1], mat.base_color[2])
            if wp.static(f.vertex_colors):
                vertex_color = interpolate(scene.colors, h)
                base = wp.cw_mul(base, wp.vec3(vertex_color[0], vertex_color[1], vertex_color[2]))
            metallic = mat.metallic
            roughness = mat.roughness
            if wp.static(f.base_color_texture):
                bc = texture_or_one(scene, mat.base_color_texture, uv)
                base = wp.cw_mul(base, wp.vec3(bc[0], bc[1], bc[2]))
            if wp.static(f.metallic_roughness_texture):
                mr = texture_or_one(scene, mat.metallic_roughness_texture, uv)
                roughness = roughness * mr[1]
                metallic = metallic * mr[2]
            for i in range(scene.num_lights):
                ls = sample_light(scene.lights[i], h.p)
                # light below the geometric surface: shading normals must not leak it through
                if wp.dot(h.ng, ls.to_light) <= 0.0:
                    continue
                n_dot_l = wp.dot(n, ls.to_light)
                if n_dot_l <= 0.0:
                    continue
                if wp.static(f.spot_lights):
                    if ls.irradiance == wp.vec3(0.0):
                        continue  # outside a spot's cone: no shadow ray
                unshadowed = float(1.0)
                if wp.static(f.shadows == "rays"):
                    if shadow_ray_occluded(scene, buffers, i, h, ls):
                        continue
                if wp.static(f.shadows == "map"):
                    unshadowed = shadow_map_visibility(maps, i, scene.lights[i].position, h.p, h.ng)
                    if unshadowed == 0.0:
                        continue
                fr = brdf(n, view, ls.to_light, base, metallic, roughness, mat.specular, mat.ior_eta, mat.ior_kappa)
                radiance = radiance + wp.cw_mul(fr, ls.irradiance) * (n_dot_l * unshadowed)
            if wp.static(bool(ibl)):
                from_environment = ambient(scene, env, dfg, h.p, h.p_error, h.ng, n, view, base, metallic,
                                           roughness, mat.specular, mat.ior_eta, mat.ior_kappa, seed, stream)
                if wp.static(f.occlusion_texture):
                    if mat.occlusion_texture != NO_TEXTURE:
                        occlusion = texture_or_one(scene, mat.occlusion_texture, uv)[0]
                        from_environment = from_environment * (1.0 + mat.occlusion_strength * (occlusion - 1.0))
                radiance = radiance + from_environment
        return radiance

    @wp.func
    def shadow_ray_occluded(scene: SceneData, buffers: LightBuffers, light: int, h: SurfaceHit, ls: LightSample) -> bool:
        """Whether a surface blocks the segment from the hit to light ``light``: aimed from the
        offset origin at the light's position, so that the light buffer's cell holds it, or along
        a directional light; the BVH answers where the light buffer cannot."""
        if triangle_is_clear(buffers, light, h.face):
            return False
        origin = offset_ray_origin(h.p, h.p_error, h.ng, ls.to_light)
        direction = ls.to_light
        max_t = RAY_FAR
        position = scene.lights[light].position
        if ls.distance < RAY_FAR:
            to_light = position - origin
            distance = wp.length(to_light)
            direction = safe_normalize(to_light, ls.to_light)
            max_t = distance * (1.0 - SHADOW_RAY_SHORTENING)
        verdict, blocker = light_buffer_occlusion(buffers, light, position, scene.positions, scene.indices, origin,
                                                  direction, max_t, h.face)
        if verdict == UNDECIDED:
            return occluded(scene, origin, direction, max_t)
        if wp.static(f.masked_occlusion):
            # the blocker the light buffer found may be cut out there
            if verdict == OCCLUDED and scene.materials[scene.face_material[blocker]].alpha_mask == 1:
                return occluded(scene, origin, direction, max_t)
        return verdict == OCCLUDED

    @wp.func
    def shading_normal(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> wp.vec3:
        """Interpolated (and normal-mapped) normal, turned to the side the ray came from."""
        front_ng = h.ng
        if h.back_face == 1:
            front_ng = -h.ng
        n = safe_normalize(interpolate(scene.normals, h), front_ng)
        if wp.static(f.normal_mapping):
            if mat.normal_texture != NO_TEXTURE:
                texel = texture_or_one(scene, mat.normal_texture, uv)
                n = perturb_normal(n, interpolate(scene.tangents, h), texel, mat.normal_scale)
        if h.back_face == 1:
            n = -n
        return n

    @wp.func
    def primary_hit(scene: SceneData, vbuffer: wp.array2d(dtype=wp.uint64), py: int, column: int, origin: wp.vec3,
                    d: wp.vec3):
        """(face, u, v) of the nearest surface along a camera ray, face -1 for none: from the
        visibility buffer, the hit recomputed by the ray caster's own ray-triangle test, or by a BVH
        query."""
        if wp.static(f.visibility == "raster"):
            face = visible_triangle(vbuffer[py, column])
            if face < 0:
                return -1, 0.0, 0.0
            c = triangle_corners(scene.indices, face)
            p0 = scene.positions[c[0]]
            p1 = scene.positions[c[1]]
            p2 = scene.positions[c[2]]
            # barycentrics of the ray's crossing of the triangle's plane even where the raster's
            # and the ray test's verdicts on an edge sample differ
            hit, t, u, v = ray_triangle_intersection(origin, d, p0, p1, p2)
            return face, u, v
        q = wp.mesh_query_ray(scene.mesh, origin, d, RAY_FAR)
        if not q.result:
            return -1, 0.0, 0.0
        return q.face, q.u, q.v

    @wp.kernel(enable_backward=False, module="unique")
    def render_tile(
        scene: SceneData,
        cam: CameraData,
        spp: int,
        grid_m: int,
        grid_n: int,
        seed: int,
        x0: int,
        y0: int,
        tile_width: int,
        background: wp.vec3,
        out_rgb: wp.array2d(dtype=wp.vec3),
        out_alpha: wp.array2d(dtype=float),
        out_depth: wp.array2d(dtype=float),
        out_normal: wp.array2d(dtype=wp.vec3),
        vbuffer: wp.array2d(dtype=wp.uint64),
        maps: ShadowMaps,
        buffers: LightBuffers,
        env: EnvironmentData,
        dfg: wp.array2d(dtype=wp.vec2),
    ):
        # one row per thread index: Warp's CPU code copies the kernel's arguments (structs of
        # arrays, about a kilobyte) for every index, which per pixel cost ~10% of a frame
        py = y0 + wp.tid()
        for px in range(x0, x0 + tile_width):
            pixel_seed = seed + py * cam.width + px
            radiance = wp.vec3(0.0)
            normal_sum = wp.vec3(0.0)
            hits = int(0)
            depth = float(RAY_FAR)
            for s in range(spp):
                offset = wp.vec2(0.5, 0.5)
                if wp.static(f.supersampling):
                    offset = multi_jittered_sample(s, grid_m, grid_n, pixel_seed)
                d = camera_ray_direction(cam, float(px) + offset[0], float(py) + offset[1])
                origin = cam.eye
                hits_before = hits
                face, u, v = primary_hit(scene, vbuffer, py, px * spp + s, origin, d)
                for _ in range(MAX_PASS_THROUGH):
                    if face < 0:
                        break
                    h = surface_hit(scene, face, u, v, d)
                    mat = scene.materials[h.material]
                    uv = hit_uv(scene, h)
                    if wp.static(f.pass_through):
                        if is_culled(scene, h, mat, uv):
                            origin = offset_ray_origin(h.p, h.p_error, h.ng, d)
                            q = wp.mesh_query_ray(scene.mesh, origin, d, RAY_FAR)
                            face = wp.where(q.result, q.face, -1)
                            u = q.u
                            v = q.v
                            continue
                    n = wp.vec3(0.0)
                    if wp.static(shaded or f.aovs):
                        n = shading_normal(scene, h, mat, uv)
                    radiance = radiance + shade(scene, maps, buffers, env, dfg, h, mat, uv, -d, n, pixel_seed, s)
                    hits = hits + 1
                    if wp.static(f.aovs):
                        normal_sum = normal_sum + n
                        depth = wp.min(depth, wp.length(h.p - cam.eye))
                    break
                if wp.static(f.environment_background):
                    if hits == hits_before:
                        radiance = radiance + environment_radiance(env, d)
            inv_spp = 1.0 / float(spp)
            alpha = float(hits) * inv_spp
            seen_behind = background * (1.0 - alpha)
            if wp.static(f.environment_background):
                seen_behind = wp.vec3(0.0)
            out_rgb[py, px] = clamp_to_float32_max(radiance * inv_spp + seen_behind)
            out_alpha[py, px] = alpha
            if wp.static(f.aovs):
                if hits > 0:
                    out_depth[py, px] = depth
                    out_normal[py, px] = safe_normalize(normal_sum, wp.vec3(0.0))
                else:
                    out_depth[py, px] = wp.inf
                    out_normal[py, px] = wp.vec3(0.0)

    return render_tile
