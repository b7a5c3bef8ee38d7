"""The render kernel: camera rays, closest hit, surface attributes, direct lighting with shadow
rays, accumulated over stratified sub-pixel samples. Built per feature set, so the compiled
code holds only what a scene needs."""

import dataclasses
import functools

import warp as wp

from .ambient import ambient_for
from .aovs import denoiser_albedo
from .area_lights import (AREA_LIGHT_STREAM, AREA_RECT, AreaLightData, area_light_kinds, rect_irradiance,
                          rect_representative_point, representative_point_normalization, robust_length,
                          sphere_irradiance, sphere_representative_point)
from .brdf import albedo_coupled_brdf_for, brdf_for, fresnel_dielectric, max_channel
from .ibl import EnvironmentData, environment_radiance, prefiltered_radiance
from .camera import CameraData, camera_ray_direction, sample_footprint_side
from .clearcoat import Coat, clearcoat_for
from .light_buffer import LightBuffers
from .light_buffer_query import (OCCLUDED, SHADOW_CACHE_LIGHTS, UNDECIDED, ShadowCache, light_buffer_occlusion,
                                 ray_leaves_clear, segment_meets_triangle)
from .lights import LightSample, light_sampler
from .material_inputs import material_lookups
from .microfacet import PI, alpha_from_roughness
from .ray_triangle import ray_triangle_intersection
from .robust import RAY_FAR, SHADOW_RAY_SHORTENING, clamp_to_float32_max, offset_ray_origin, safe_normalize
from .sampling import multi_jittered_sample
from .scene_data import NO_TEXTURE, MaterialData, SceneData, triangle_corners
from .shadow_map import ShadowMaps, shadow_map_visibility
from .sheen import Sheen, sheen_for
from .transmission import (TRANSMISSION_STREAM, beer_lambert, blurred_roughness, refract_through,
                           sample_rough_interface, sample_thin_lobe, transmission_blur, transmission_roughness,
                           transmitted_share)
from .work_queue import read_counter, take_next_item_from
from .surface import (MAX_PASS_THROUGH, NEGLIGIBLE_THROUGHPUT, SurfaceHit, shadow_segment, surface_hit,
                      surface_tests)
from .texture_coords import SurfaceUV, texture_lookups
from .visibility_buffer import visible_triangle

wp.set_module_options({"enable_backward": False})

# Slots of render_tile's int32 ``rows`` array: the counter rows are taken from, and a flag that
# stops every launch at its next pixel once set (by an interrupt of the caller).
ROWS_TAKEN = wp.constant(0)
STOP = wp.constant(1)
WORK_SLOTS = 2


@functools.cache
def render_kernel(features):
    """The tile kernel for a ``features`` value (hashable; see pbrwarp.features.Features).

    Each flag is a compile-time constant: code for an absent effect is not generated at all.
    """
    f = features
    textured = f.textures
    layers = dict(anisotropic=f.anisotropy, iridescent=f.iridescence)
    brdf = brdf_for(f.diffuse, f.specular, **dataclasses.asdict(f.brdf), **layers)
    coupled = albedo_coupled_brdf_for(f.diffuse, f.specular, **dataclasses.asdict(f.brdf), **layers)
    brdf_scaled, diffuse_share_scale = coupled or (None, None)
    # the albedo coupling's normalization depends on the material's inputs alone: where no texture
    # or vertex colour varies them (transmission's scales the base colour) it is computed once per
    # material met, not per light and pixel
    scale_per_material = bool(coupled) and not (f.base_color_texture or f.metallic_roughness_texture
                                                or f.vertex_colors or f.specular_texture
                                                or f.specular_color_texture or f.transmission_texture)
    sample_light = light_sampler(f.point_lights, f.directional_lights, f.spot_lights)
    # area lights, and their rung: "representative_point" or "monte_carlo" (pbrwarp.AreaLighting)
    area = (f.sphere_lights or f.rect_lights) and bool(f.area_lighting)
    area_rung = f.area_lighting.method if area else None
    # (direction, distance, solid-angle pdf) of a point of an area light, by its kind
    sample_area_light = area_light_kinds(f.sphere_lights, f.rect_lights)[0]
    if area_rung == "representative_point" and f.specular:
        # the specular lobe alone, shaded from the representative point
        specular_brdf = brdf_for(False, True, **dataclasses.asdict(f.brdf), **layers)
    area_samples = f.area_lighting.samples if area_rung == "monte_carlo" else 1
    # the samples' stratification grid, m x n = area_samples with m the largest divisor <= sqrt
    area_grid_m = max(d for d in range(1, int(area_samples ** 0.5) + 1) if area_samples % d == 0)
    area_grid_n = area_samples // area_grid_m
    lit = f.point_lights or f.directional_lights or f.spot_lights or area
    ibl = f.environment
    shaded = lit or bool(ibl)
    hit_uv, alpha_at, is_cut_out, _, occluded = surface_tests(textured, f.base_color_texture,
                                                              f.masked_occlusion, f.second_uv_set)
    # the pixel footprint (ray differentials) is computed only for trilinear filtering
    footprint = textured and f.texture_filter == "trilinear"
    hit_texcoords, texture = texture_lookups(textured, footprint, f.second_uv_set)
    inputs = material_lookups(f, texture)
    base_color_at, surface_inputs, roughness_at = inputs.base_color_at, inputs.surface_inputs, inputs.roughness_at
    transmission_at, anisotropy_at, thin_film_at = inputs.transmission_at, inputs.anisotropy_at, inputs.thin_film_at
    oriented_normal, shading_normal, emission_at = inputs.oriented_normal, inputs.shading_normal, inputs.emission_at
    coat_at, _, clearcoat_brdf, clearcoat_environment = clearcoat_for(
        f.brdf.distribution, f.brdf.geometry, f.brdf.fresnel, texture if f.clearcoat_textures else None)
    if f.sheen:  # (its albedo table is integrated on first use)
        sheen_at, _, sheen_brdf, sheen_scaling, sheen_environment, _ = sheen_for(
            texture if f.sheen_textures else None)

    @wp.func
    def is_culled(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: wp.vec2) -> bool:
        if h.back_face == 1 and mat.double_sided == 0:
            return True
        return is_cut_out(scene, h, mat, uv)

    if ibl:
        ambient = ambient_for(ibl.method, ibl.fresnel, ibl.samples, ibl.shadowed, f.brdf.energy == "multiscatter",
                              f.brdf.coupling != "none" and f.diffuse and f.specular, brdf, occluded,
                              f.brdf.metallic_mix == "gltf", f.anisotropy, f.iridescence, ibl.environment_sampling)

    @wp.func
    def transmitted(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: SurfaceUV, n: wp.vec3, v: wp.vec3,
                    t: float) -> wp.vec3:
        """The share of the light behind the surface that passes through it towards v."""
        metallic, roughness, specular, f0_dielectric = surface_inputs(scene, mat, uv)
        return transmitted_share(base_color_at(scene, h, mat, uv), metallic, t, specular, f0_dielectric,
                                 wp.max(wp.dot(n, v), 0.0))

    @wp.func
    def layered_reflectance(n: wp.vec3, view: wp.vec3, l: wp.vec3, base: wp.vec3, metallic: float, roughness: float,
                            specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, scale: wp.vec3,
                            aniso_t: wp.vec3, anisotropy: float, thin_film: wp.vec3) -> wp.vec3:
        """The BRDF towards l, below the sheen and the clear coat (``scale``, the albedo
        coupling's normalization, is read only where the BRDF couples its lobes so)."""
        if wp.static(bool(coupled)):
            return brdf_scaled(n, view, l, base, metallic, roughness, specular, eta, kappa, f0_dielectric, scale,
                               aniso_t, anisotropy, thin_film)
        return brdf(n, view, l, base, metallic, roughness, specular, eta, kappa, f0_dielectric, aniso_t, anisotropy,
                    thin_film)

    @wp.func
    def reflectance(n: wp.vec3, view: wp.vec3, l: wp.vec3, base: wp.vec3, metallic: float, roughness: float,
                    specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, scale: wp.vec3,
                    aniso_t: wp.vec3, anisotropy: float, thin_film: wp.vec3, sheen: Sheen) -> wp.vec3:
        """The BRDF towards l with the sheen layer's albedo scaling and lobe: what punctual and
        area lights reflect alike."""
        fr = layered_reflectance(n, view, l, base, metallic, roughness, specular, eta, kappa, f0_dielectric, scale,
                                 aniso_t, anisotropy, thin_film)
        if wp.static(f.sheen):  # KHR_materials_sheen's albedo scaling
            fr = fr * sheen_scaling(sheen, l) + sheen_brdf(sheen, view, l)
        return fr

    @wp.func
    def area_light_visibility(scene: SceneData, h: SurfaceHit, direction: wp.vec3, distance: float) -> wp.vec3:
        """The share of an area light's radiance that reaches the hit from ``distance`` along
        ``direction``: 1, 0 where a surface blocks it, or what transmissive blockers pass. Traced
        through the BVH: light buffers and shadow maps hold punctual lights only."""
        if wp.static(not f.area_shadows):
            return wp.vec3(1.0)
        origin = offset_ray_origin(h.p, h.p_error, h.ng, direction)
        reach = distance * (1.0 - SHADOW_RAY_SHORTENING)
        if not occluded(scene, origin, direction, reach):
            return wp.vec3(1.0)
        if wp.static(f.transmissive_shadows):
            return light_passed(scene, origin, direction, reach)
        return wp.vec3(0.0)

    @wp.func
    def sphere_shape(light: AreaLightData, p: wp.vec3, n: wp.vec3, r: wp.vec3, centre_distance: float):
        """area_light_shape of a sphere light: its size is its radius, and a shadow
        ray towards its centre ends at its surface."""
        mean, projected, facing = sphere_irradiance(light, p, n)
        return (mean, projected, facing, sphere_representative_point(light, p, r), light.radius,
                centre_distance - light.radius)

    @wp.func
    def rect_shape(light: AreaLightData, p: wp.vec3, n: wp.vec3, r: wp.vec3, centre_distance: float):
        """area_light_shape of a rectangle light: its size is the radius of the disc
        of its area."""
        mean, projected, facing = rect_irradiance(light, p, n)
        return (mean, projected, facing, rect_representative_point(light, p, r), wp.sqrt(light.area / PI),
                centre_distance)

    @wp.func
    def area_light_shape(light: AreaLightData, p: wp.vec3, n: wp.vec3, r: wp.vec3, centre_distance: float):
        """(mean direction, projected solid angle, facing projected solid angle, the
        representative point relative to p, the light's size for Karis's normalization, the
        distance a shadow ray to the centre must reach) of a light, by its kind."""
        if wp.static(f.sphere_lights and f.rect_lights):
            if light.kind == AREA_RECT:
                return rect_shape(light, p, n, r, centre_distance)
            return sphere_shape(light, p, n, r, centre_distance)
        elif wp.static(f.sphere_lights):
            return sphere_shape(light, p, n, r, centre_distance)
        else:
            return rect_shape(light, p, n, r, centre_distance)

    @wp.func
    def area_light_sampled(scene: SceneData, light: AreaLightData, h: SurfaceHit, n: wp.vec3, view: wp.vec3,
                           base: wp.vec3, metallic: float, roughness: float, specular: float, eta: wp.vec3,
                           kappa: wp.vec3, f0_dielectric: wp.vec3, scale: wp.vec3, aniso_t: wp.vec3,
                           anisotropy: float, thin_film: wp.vec3, sheen: Sheen, coat: Coat, light_seed: int):
        """(reflected, reflected by the clear coat) per unit of the light's radiance, the exact
        rung: the Monte Carlo estimate of the integral of f cos over the light, from area_samples
        points drawn by solid angle (multi-jittered), each checked by a shadow ray."""
        total = wp.vec3(0.0)
        coat_total = wp.vec3(0.0)
        for k in range(area_samples):
            u = multi_jittered_sample(k, area_grid_m, area_grid_n, light_seed)
            direction, distance, pdf = sample_area_light(light, h.p, u)
            if pdf <= 0.0:
                continue
            # light below the geometric surface: shading normals must not leak it through
            if wp.dot(h.ng, direction) <= 0.0:
                continue
            n_dot_l = wp.dot(n, direction)
            if n_dot_l <= 0.0:
                continue
            passed = area_light_visibility(scene, h, direction, distance)
            if max_channel(passed) <= 0.0:
                continue
            fr = reflectance(n, view, direction, base, metallic, roughness, specular, eta, kappa, f0_dielectric,
                             scale, aniso_t, anisotropy, thin_film, sheen)
            total = total + wp.cw_mul(fr, passed) * (n_dot_l / pdf)
            if wp.static(f.clearcoat):
                coat_total = coat_total + passed * (clearcoat_brdf(coat, view, direction)
                                                    * wp.dot(coat.normal, direction) / pdf)
        inv = 1.0 / float(area_samples)
        return total * inv, coat_total * inv

    @wp.func
    def area_light_representative(scene: SceneData, light: AreaLightData, h: SurfaceHit, n: wp.vec3,
                                  view: wp.vec3, base: wp.vec3, metallic: float, roughness: float, specular: float,
                                  eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, scale: wp.vec3,
                                  aniso_t: wp.vec3, anisotropy: float, thin_film: wp.vec3, sheen: Sheen,
                                  coat: Coat):
        """(reflected, reflected by the clear coat) per unit of the light's radiance, the cheap rung
        (Karis 2013): the diffuse lobe lit by the light's exact unoccluded irradiance from its mean
        direction, the specular lobe by the light as a point where the reflection ray passes
        closest to it, with the irradiance of a surface facing the light and the lobe's energy
        normalization for the light's angular size; the sheen and the clear coat from the mean
        direction. Shadowed as a whole by one ray to the light's centre."""
        r = 2.0 * wp.dot(n, view) * n - view  # the mirror direction
        to_centre = light.position - h.p
        centre_distance = robust_length(to_centre)
        mean, projected, facing, to_point, size, reach = area_light_shape(light, h.p, n, r, centre_distance)
        # nothing where the light is all below the geometric surface (shading normals must not
        # leak it through): its bounding sphere (the rectangle's half diagonal) under the plane
        extent = light.radius + 0.5 * wp.length(light.edge_u + light.edge_v)
        if facing <= 0.0 or wp.dot(h.ng, to_centre) + extent <= 0.0:
            return wp.vec3(0.0), wp.vec3(0.0)
        passed = area_light_visibility(scene, h, to_centre / centre_distance, reach)
        if max_channel(passed) <= 0.0:
            return wp.vec3(0.0), wp.vec3(0.0)
        fr = layered_reflectance(n, view, mean, base, metallic, roughness, specular, eta, kappa, f0_dielectric, scale,
                                 aniso_t, anisotropy, thin_film)
        reflected = fr * projected
        if wp.static(f.specular):
            # the specular lobe moves from the mean direction to the representative point
            glossy = specular_brdf(n, view, mean, base, metallic, roughness, specular, eta, kappa, f0_dielectric,
                                   aniso_t, anisotropy, thin_film)
            reflected = wp.max(fr - glossy, wp.vec3(0.0)) * projected
            point_distance = robust_length(to_point)
            if point_distance > 0.0:
                l = to_point / point_distance
                if wp.dot(h.ng, l) > 0.0:
                    normalization = representative_point_normalization(alpha_from_roughness(roughness), size,
                                                                       centre_distance)
                    reflected = reflected + specular_brdf(n, view, l, base, metallic, roughness, specular, eta, kappa,
                                              f0_dielectric, aniso_t, anisotropy, thin_film) * (
                        facing * wp.max(wp.dot(n, l), 0.0) * normalization)
        if wp.static(f.sheen):
            reflected = reflected * sheen_scaling(sheen, mean) + sheen_brdf(sheen, view, mean) * projected
        coat_reflected = wp.vec3(0.0)
        if wp.static(f.clearcoat):
            coat_reflected = passed * (clearcoat_brdf(coat, view, mean) * wp.max(wp.dot(coat.normal, mean), 0.0)
                                       * facing)
        return wp.cw_mul(reflected, passed), coat_reflected

    @wp.func
    def shade(scene: SceneData, maps: ShadowMaps, buffers: LightBuffers, env: EnvironmentData,
              dfg: wp.array2d(dtype=wp.vec2), h: SurfaceHit, mat: MaterialData, uv: SurfaceUV, view: wp.vec3,
              n: wp.vec3, seed: int, stream: int, cache: ShadowCache, scale: wp.vec3, scale_material: int):
        """(radiance leaving the hit towards the view, the shadow cache, the albedo coupling's
        normalization ``scale`` (diffuse_share_scale) and the material it was computed for,
        ``scale_material``, -1 for none: kept from pixel to pixel where it depends on the material
        alone)."""
        if wp.static(f.unlit):
            if mat.unlit != 0:  # KHR_materials_unlit: the base colour, in nits, and nothing else
                return base_color_at(scene, h, mat, uv), cache, scale, scale_material
        radiance = wp.vec3(0.0)
        coat = Coat()
        coat_radiance = wp.vec3(0.0)  # reflected by the clear coat, over the rest (with emission)
        if wp.static(f.clearcoat):
            coat_normal_map = NO_TEXTURE
            if wp.static(f.clearcoat_textures):
                coat_normal_map = mat.clearcoat_normal_texture
            coat = coat_at(scene, mat, uv, oriented_normal(scene, h, uv, coat_normal_map, mat.clearcoat_normal_scale),
                           view)
        if wp.static(f.emission):
            radiance = emission_at(scene, mat, uv)
        if wp.static(shaded):
            base = base_color_at(scene, h, mat, uv)
            metallic, roughness, specular, f0_dielectric = surface_inputs(scene, mat, uv)
            if wp.static(f.transmission):
                # the diffuse lobe keeps what transmission leaves (KHR_materials_transmission)
                base = base * (1.0 - transmission_at(scene, mat, uv))
            aniso_t = wp.vec3(0.0)
            anisotropy = float(0.0)
            if wp.static(f.anisotropy):
                aniso_t, anisotropy = anisotropy_at(scene, h, mat, uv, n)
            thin_film = wp.vec3(0.0)
            if wp.static(f.iridescence):
                thin_film = thin_film_at(scene, mat, uv)
            sheen = Sheen()
            if wp.static(f.sheen):
                sheen = sheen_at(scene, mat, uv, n, view)
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
                irradiance = ls.irradiance
                if wp.static(f.shadows == "rays"):
                    cached = int(-1)
                    if i < SHADOW_CACHE_LIGHTS:
                        cached = cache[i]
                    blocked, blocker = shadow_ray_occluded(scene, buffers, i, h, ls, cached)
                    if i < SHADOW_CACHE_LIGHTS:
                        cache[i] = blocker
                    if blocked:
                        if wp.static(f.transmissive_shadows):
                            # a transmissive blocker tints the light rather than stopping it
                            origin, direction, reach = shadow_segment(scene, i, h, ls)
                            passed = light_passed(scene, origin, direction, reach)
                            if max_channel(passed) <= 0.0:
                                continue
                            irradiance = wp.cw_mul(irradiance, passed)
                        else:
                            continue
                if wp.static(f.shadows == "map"):
                    unshadowed = shadow_map_visibility(maps, i, scene.lights[i].position, h.p, h.ng)
                    if unshadowed == 0.0:
                        continue
                if wp.static(bool(coupled)):
                    if scale_material != h.material:
                        scale = diffuse_share_scale(base, metallic, roughness, specular, f0_dielectric)
                        scale_material = h.material
                fr = reflectance(n, view, ls.to_light, base, metallic, roughness, specular, mat.ior_eta, mat.ior_kappa,
                                 f0_dielectric, scale, aniso_t, anisotropy, thin_film, sheen)
                radiance = radiance + wp.cw_mul(fr, irradiance) * (n_dot_l * unshadowed)
                if wp.static(f.clearcoat):
                    coat_radiance = coat_radiance + irradiance * (clearcoat_brdf(coat, view, ls.to_light)
                                                                     * wp.dot(coat.normal, ls.to_light) * unshadowed)
            if wp.static(area):
                if wp.static(bool(coupled)):
                    if scene.num_area_lights > 0 and scale_material != h.material:
                        scale = diffuse_share_scale(base, metallic, roughness, specular, f0_dielectric)
                        scale_material = h.material
                # one random stream per camera sample, a seed per light drawn from it
                area_state = wp.rand_init(seed, AREA_LIGHT_STREAM + stream)
                for i in range(scene.num_area_lights):
                    light = scene.area_lights[i]
                    reflected = wp.vec3(0.0)
                    coat_reflected = wp.vec3(0.0)
                    if wp.static(area_rung == "monte_carlo"):
                        reflected, coat_reflected = area_light_sampled(
                            scene, light, h, n, view, base, metallic, roughness, specular, mat.ior_eta, mat.ior_kappa,
                            f0_dielectric, scale, aniso_t, anisotropy, thin_film, sheen, coat, wp.randi(area_state))
                    else:
                        reflected, coat_reflected = area_light_representative(
                            scene, light, h, n, view, base, metallic, roughness, specular, mat.ior_eta, mat.ior_kappa,
                            f0_dielectric, scale, aniso_t, anisotropy, thin_film, sheen, coat)
                    radiance = radiance + wp.cw_mul(reflected, light.radiance)
                    if wp.static(f.clearcoat):
                        coat_radiance = coat_radiance + wp.cw_mul(coat_reflected, light.radiance)
            if wp.static(bool(ibl)):
                from_environment = ambient(scene, env, dfg, h.p, h.p_error, h.ng, n, view, base, metallic,
                                           roughness, specular, mat.ior_eta, mat.ior_kappa, f0_dielectric, seed,
                                           stream, aniso_t, anisotropy, thin_film)
                if wp.static(f.sheen):
                    from_environment = sheen_environment(env, sheen, from_environment)
                coat_from_environment = wp.vec3(0.0)
                if wp.static(f.clearcoat):
                    coat_from_environment = clearcoat_environment(env, dfg, coat, view)
                if wp.static(f.occlusion_texture):
                    if mat.occlusion_texture != NO_TEXTURE:
                        occlusion = texture(scene, mat.occlusion_texture, uv)[0]
                        visible = 1.0 + mat.occlusion_strength * (occlusion - 1.0)
                        from_environment = from_environment * visible
                        coat_from_environment = coat_from_environment * visible
                radiance = radiance + from_environment
                coat_radiance = coat_radiance + coat_from_environment
        if wp.static(f.clearcoat):
            radiance = radiance * (1.0 - coat.weight) + coat_radiance  # KHR_materials_clearcoat's fresnel_coat
        if wp.static(not scale_per_material):
            scale_material = -1  # the next hit's inputs may differ
        return radiance, cache, scale, scale_material

    @wp.func
    def light_passed(scene: SceneData, start: wp.vec3, direction: wp.vec3, length: float) -> wp.vec3:
        """The share of a light's radiance that passes the transmissive surfaces on the shadow ray
        from ``start`` along ``direction`` up to ``length``, 0 if an opaque one blocks it:
        straight through, each surface passing its transmitted share at the ray's incidence (base
        colour, 1 - F), volumes absorbing by Beer-Lambert along the chord and passing 1 - F of
        the exact Fresnel where the ray leaves them. Without refraction the light's path is the
        straight one: exact through smooth thin walls, an approximation through volumes (no
        caustics). After MAX_PASS_THROUGH surfaces the next one counts as opaque."""
        origin = wp.vec3(start)
        reach = float(length)
        passed = wp.vec3(1.0)
        sigma = wp.vec3(0.0)
        for _ in range(MAX_PASS_THROUGH):
            q = wp.mesh_query_ray(scene.mesh, origin, direction, reach)
            if not q.result:
                return passed
            blocker = surface_hit(scene, q.face, q.u, q.v, direction)
            mat = scene.materials[blocker.material]
            uv0 = hit_uv(scene, blocker)
            # a shadow ray has no footprint: its differentials are itself, textures read at level 0
            uv = hit_texcoords(scene, blocker, uv0, origin, direction, direction)
            if wp.static(f.volume):
                if max_channel(sigma) > 0.0:
                    passed = wp.cw_mul(passed, beer_lambert(sigma, q.t))
            if not is_cut_out(scene, blocker, mat, uv0):
                t = transmission_at(scene, mat, uv)
                if t <= 0.0:
                    return wp.vec3(0.0)
                cos_i = wp.dot(blocker.ng, -direction)  # ng is turned towards the ray
                leaves_volume = False
                if wp.static(f.volume):
                    leaves_volume = blocker.back_face == 1 and mat.thickness > 0.0
                if leaves_volume:
                    passed = passed * (1.0 - fresnel_dielectric(cos_i, 1.0 / mat.ior))
                    sigma = wp.vec3(0.0)
                else:
                    passed = wp.cw_mul(passed, transmitted(scene, blocker, mat, uv, blocker.ng, -direction, t))
                    if wp.static(f.volume):
                        if mat.thickness > 0.0:
                            sigma = mat.attenuation
                if max_channel(passed) <= NEGLIGIBLE_THROUGHPUT:
                    return wp.vec3(0.0)
            origin = offset_ray_origin(blocker.p, blocker.p_error, blocker.ng, direction)
            reach = reach - q.t
        return wp.vec3(0.0)

    # inlined: a call would copy the scene's and the light buffers' structs (~1 KB) per shadow ray
    @wp.func(inline=True)
    def shadow_ray_occluded(scene: SceneData, buffers: LightBuffers, light: int, h: SurfaceHit, ls: LightSample,
                            cached: int):
        """(whether a surface blocks the segment from the hit to light ``light``, the triangle
        found blocking it or -1): aimed from the offset origin at the light's position, so that
        the light buffer's cell holds it, or along a directional light. The ``cached`` blocker (of
        the shadow cache) is tested first, then the light buffer; the BVH answers where the light
        buffer cannot."""
        if ray_leaves_clear(buffers, light, h.face, h.b0, h.b1, h.b2):
            return False, -1
        origin, direction, max_t = shadow_segment(scene, light, h, ls)
        position = scene.lights[light].position
        verdict = UNDECIDED
        blocker = int(-1)
        if cached >= 0:
            if segment_meets_triangle(scene.positions, scene.indices, cached, origin, direction, max_t):
                verdict = OCCLUDED
                blocker = cached
        if verdict == UNDECIDED:
            verdict, blocker = light_buffer_occlusion(buffers, light, position, scene.positions, scene.indices, origin,
                                                      direction, max_t, h.face)
        if verdict == UNDECIDED:
            return occluded(scene, origin, direction, max_t), -1
        if wp.static(f.masked_occlusion):
            # the blocker found may be cut out there
            if verdict == OCCLUDED and scene.materials[scene.face_material[blocker]].alpha_mask == 1:
                return occluded(scene, origin, direction, max_t), -1
        return verdict == OCCLUDED, blocker

    @wp.func
    def primary_hit(scene: SceneData, seen: int, origin: wp.vec3, d: wp.vec3):
        """(face, u, v) of the nearest surface along a camera ray, face -1 for none: the triangle
        ``seen`` in the visibility buffer with the hit recomputed by the ray caster's own
        ray-triangle test, or a BVH query."""
        if wp.static(f.visibility == "raster"):
            if seen < 0:
                return -1, 0.0, 0.0
            c = triangle_corners(scene.indices, seen)
            p0 = scene.positions[c[0]]
            p1 = scene.positions[c[1]]
            p2 = scene.positions[c[2]]
            # barycentrics of the ray's crossing of the triangle's plane even where the raster's
            # and the ray test's verdicts on an edge sample differ
            hit, t, u, v = ray_triangle_intersection(origin, d, p0, p1, p2)
            return seen, u, v
        q = wp.mesh_query_ray(scene.mesh, origin, d, RAY_FAR)
        if not q.result:
            return -1, 0.0, 0.0
        return q.face, q.u, q.v

    @wp.func
    def next_hit(scene: SceneData, origin: wp.vec3, d: wp.vec3):
        """(face, u, v) of the nearest surface along a ray leaving a surface, face -1 for none."""
        q = wp.mesh_query_ray(scene.mesh, origin, d, RAY_FAR)
        return wp.where(q.result, q.face, -1), q.u, q.v

    @wp.func
    def render_row(
        scene: SceneData,
        cam: CameraData,
        spp: int,
        grid_m: int,
        grid_n: int,
        seed: int,
        py: int,
        background: wp.vec3,
        out_rgb: wp.array2d(dtype=wp.vec3),
        out_alpha: wp.array2d(dtype=float),
        out_depth: wp.array2d(dtype=float),
        out_normal: wp.array2d(dtype=wp.vec3),
        out_albedo: wp.array2d(dtype=wp.vec3),
        vbuffer: wp.array2d(dtype=wp.uint64),
        maps: ShadowMaps,
        buffers: LightBuffers,
        env: EnvironmentData,
        dfg: wp.array2d(dtype=wp.vec2),
        rows: wp.array(dtype=wp.int32),
    ):
        """Row py of the image, sample by sample, unless rows[STOP] is set: then the row is left
        at the next pixel (which takes spp samples at most)."""
        cache = ShadowCache(-1)
        scale = wp.vec3(1.0)
        scale_material = int(-1)
        step = sample_footprint_side(spp)
        for px in range(cam.width):
            if read_counter(rows, STOP) != 0:
                return
            pixel_seed = seed + py * cam.width + px
            radiance = wp.vec3(0.0)
            normal_sum = wp.vec3(0.0)
            albedo_sum = wp.vec3(0.0)
            hits = int(0)
            covered = float(0.0)
            depth = float(RAY_FAR)
            samples = spp
            if wp.static(not f.supersampling):
                # spp is 1: a constant count lets the compiler drop the loop, which it would
                # otherwise leave only after hoisting the camera ray (the same for every sample)
                # above the empty-sample test
                samples = 1
            for s in range(samples):
                seen = int(-1)
                if wp.static(f.visibility == "raster"):
                    seen = visible_triangle(vbuffer[py, px * spp + s])
                    if wp.static(not f.environment_background):
                        if seen < 0:
                            continue  # the background's colour needs no camera ray
                offset = wp.vec2(0.5, 0.5)
                if wp.static(f.supersampling):
                    offset = multi_jittered_sample(s, grid_m, grid_n, pixel_seed)
                d = camera_ray_direction(cam, float(px) + offset[0], float(py) + offset[1])
                dir_dx = d
                dir_dy = d
                if wp.static(footprint):
                    # the rays one step right and one step down: a pixel apart, or with
                    # supersampling a stratum apart, the footprint of one of spp samples
                    dir_dx = camera_ray_direction(cam, float(px) + offset[0] + step, float(py) + offset[1])
                    dir_dy = camera_ray_direction(cam, float(px) + offset[0], float(py) + offset[1] + step)
                origin = cam.eye
                camera_d = d
                travelled = float(0.0)
                # the weight of what lies further along the ray, and the part of the sample no
                # surface covers (alpha-blended surfaces cover part of it)
                throughput = wp.vec3(1.0)
                uncovered = float(1.0)
                # the attenuation coefficient of the volume the ray travels in (0: none)
                sigma = wp.vec3(0.0)
                # the squared GGX width rough transmissive surfaces blur the environment by
                blur = float(0.0)
                lobe_state = wp.rand_init(pixel_seed, TRANSMISSION_STREAM + s)
                hits_before = hits
                face, u, v = primary_hit(scene, seen, origin, d)
                for _ in range(MAX_PASS_THROUGH):
                    if face < 0:
                        break
                    h = surface_hit(scene, face, u, v, d)
                    mat = scene.materials[h.material]
                    uv0 = hit_uv(scene, h)
                    # the footprint of the camera ray's differentials, also for surfaces seen through
                    # refracting ones: the pencil keeps its spread about the refracted ray over the
                    # whole distance travelled (a refraction's magnification is ignored)
                    travelled = travelled + wp.length(h.p - origin)
                    uv = hit_texcoords(scene, h, uv0, h.p - d * travelled, d + (dir_dx - camera_d),
                                       d + (dir_dy - camera_d))
                    if wp.static(f.volume):
                        if max_channel(sigma) > 0.0:  # absorbed on the way from inside a volume
                            throughput = wp.cw_mul(throughput, beer_lambert(sigma, wp.length(h.p - origin)))
                        if h.back_face == 1 and mat.thickness > 0.0:
                            if transmission_at(scene, mat, uv) > 0.0 and not is_cut_out(scene, h, mat, uv0):
                                # leaving a volume (whatever double_sided says): a bare interface, as
                                # lights outside do not shade it; its partial reflection is dropped
                                eta = 1.0 / mat.ior
                                n_exit = shading_normal(scene, h, mat, uv)
                                refracts, d_next, bent_by = refract_through(d, n_exit, h.ng, eta)
                                if wp.static(f.rough_transmission == "sampled"):
                                    rough = roughness_at(scene, mat, uv)
                                    if rough > 0.0:
                                        u2 = wp.vec2(wp.randf(lobe_state), wp.randf(lobe_state))
                                        refracts, d_next, lobe_weight = sample_rough_interface(d, n_exit, h.ng, eta,
                                                                                               rough, u2)
                                        throughput = throughput * lobe_weight
                                        bent_by = n_exit
                                if refracts:
                                    fresnel = fresnel_dielectric(wp.dot(bent_by, -d), eta)
                                    throughput = throughput * (1.0 - fresnel)
                                    sigma = wp.vec3(0.0)
                                    if wp.static(f.rough_transmission == "prefiltered"):
                                        blur = blur + transmission_blur(roughness_at(scene, mat, uv), mat.ior)
                                d = d_next
                                origin = offset_ray_origin(h.p, h.p_error, h.ng, d)
                                face, u, v = next_hit(scene, origin, d)
                                continue
                    if wp.static(f.pass_through):
                        if is_culled(scene, h, mat, uv0):
                            origin = offset_ray_origin(h.p, h.p_error, h.ng, d)
                            face, u, v = next_hit(scene, origin, d)
                            continue
                    n = wp.vec3(0.0)
                    if wp.static(shaded or f.aovs or f.transmission):
                        n = shading_normal(scene, h, mat, uv)
                    shaded_radiance, cache, scale, scale_material = shade(scene, maps, buffers, env, dfg, h, mat, uv,
                                                                          -d, n, pixel_seed, s, cache, scale,
                                                                          scale_material)
                    if wp.static(f.aovs):
                        if hits == hits_before:  # the first surface the sample shows
                            hits = hits + 1
                            normal_sum = normal_sum + n
                            albedo_sum = albedo_sum + denoiser_albedo(base_color_at(scene, h, mat, uv))
                            depth = wp.min(depth, wp.length(h.p - cam.eye))
                    t = float(0.0)
                    if wp.static(f.transmission):
                        t = transmission_at(scene, mat, uv)
                    if wp.static(f.alpha_blend):
                        if mat.alpha_blend == 1:
                            # glTF alphaMode BLEND: alpha is the surface's coverage, composited
                            # front to back ("over", Porter & Duff 1984); a transmissive blended
                            # surface passes its share on as a thin wall
                            alpha = wp.clamp(alpha_at(scene, h, mat, uv0), 0.0, 1.0)
                            radiance = radiance + wp.cw_mul(throughput, shaded_radiance) * alpha
                            passed = wp.vec3(1.0 - alpha)
                            if wp.static(f.transmission):
                                if t > 0.0:
                                    passed = passed + transmitted(scene, h, mat, uv, n, -d, t) * alpha
                            throughput = wp.cw_mul(throughput, passed)
                            uncovered = uncovered * (1.0 - alpha)
                            if wp.max(max_channel(throughput), uncovered) <= NEGLIGIBLE_THROUGHPUT:
                                throughput = wp.vec3(0.0)
                                uncovered = 0.0
                                break
                            origin = offset_ray_origin(h.p, h.p_error, h.ng, d)
                            face, u, v = next_hit(scene, origin, d)
                            continue
                    if wp.static(f.transmission):
                        if t > 0.0:
                            # KHR_materials_transmission: the surface's own radiance, then the share
                            # of what lies behind it; straight on through a thin wall, refracted into
                            # a volume (KHR_materials_volume)
                            radiance = radiance + wp.cw_mul(throughput, shaded_radiance)
                            throughput = wp.cw_mul(throughput, transmitted(scene, h, mat, uv, n, -d, t))
                            uncovered = 0.0
                            if wp.static(f.rough_transmission == "prefiltered"):
                                blur = blur + transmission_blur(roughness_at(scene, mat, uv), mat.ior)
                            if max_channel(throughput) <= NEGLIGIBLE_THROUGHPUT:
                                throughput = wp.vec3(0.0)
                                break
                            thick = False
                            bent = False  # whether d_next replaces d
                            d_next = d
                            if wp.static(f.volume):
                                thick = mat.thickness > 0.0
                                if thick:
                                    refracts, d_next, bent_by = refract_through(d, n, h.ng, mat.ior)
                                    sigma = mat.attenuation
                                    bent = True
                            if wp.static(f.rough_transmission == "sampled"):
                                rough = roughness_at(scene, mat, uv)
                                if rough > 0.0:
                                    # the exact rung: a draw of the GGX transmission lobe, refracted
                                    # into a volume (Walter et al. 2007) or through a thin wall (the
                                    # specular lobe seen through it, as the extension defines)
                                    u1 = wp.vec2(wp.randf(lobe_state), wp.randf(lobe_state))
                                    lobe_weight = float(1.0)
                                    if thick:
                                        inward, d_next, lobe_weight = sample_rough_interface(d, n, h.ng, mat.ior, rough,
                                                                                             u1)
                                    else:
                                        d_next, lobe_weight = sample_thin_lobe(d, n, h.ng,
                                                                               transmission_roughness(rough, mat.ior), u1)
                                    throughput = throughput * lobe_weight
                                    bent = True
                            if bent:
                                d = d_next
                            origin = offset_ray_origin(h.p, h.p_error, h.ng, d)
                            face, u, v = next_hit(scene, origin, d)
                            continue
                    radiance = radiance + wp.cw_mul(throughput, shaded_radiance)
                    throughput = wp.vec3(0.0)
                    uncovered = 0.0
                    break
                covered = covered + (1.0 - uncovered)
                if wp.static(f.transmission and not f.environment_background):
                    # what transmissive surfaces let through of the background is in the pixel's
                    # radiance (they cover the pixel); the uncovered rest is blended by alpha
                    radiance = radiance + wp.cw_mul(throughput - wp.vec3(uncovered), background)
                if wp.static(f.environment_background):
                    if throughput[0] + throughput[1] + throughput[2] > 0.0:  # no weight is negative
                        seen_along = wp.vec3(0.0)
                        if wp.static(f.rough_transmission == "prefiltered"):
                            # the cheap rung of rough transmission: the environment prefiltered
                            # at the roughness of the surfaces passed (as the glTF Sample Viewer
                            # blurs its framebuffer); objects seen through them stay sharp
                            if blur > 0.0:
                                seen_along = prefiltered_radiance(env, d, blurred_roughness(blur))
                            else:
                                seen_along = environment_radiance(env, d)
                        else:
                            seen_along = environment_radiance(env, d)
                        radiance = radiance + wp.cw_mul(throughput, seen_along)
            inv_spp = 1.0 / float(spp)
            alpha = covered * inv_spp
            seen_behind = background * (1.0 - alpha)
            if wp.static(f.environment_background):
                seen_behind = wp.vec3(0.0)
            out_rgb[py, px] = clamp_to_float32_max(radiance * inv_spp + seen_behind)
            out_alpha[py, px] = alpha
            if wp.static(f.aovs):
                out_albedo[py, px] = albedo_sum * inv_spp  # a miss adds 0
                if hits > 0:
                    out_depth[py, px] = depth
                    if hits == 1:
                        out_normal[py, px] = normal_sum  # one unit normal: exactly it
                    else:
                        out_normal[py, px] = safe_normalize(normal_sum, wp.vec3(0.0))
                else:
                    out_depth[py, px] = wp.inf
                    out_normal[py, px] = wp.vec3(0.0)


    @wp.kernel(enable_backward=False, module="unique")
    def render_tile(
        scene: SceneData,
        cam: CameraData,
        spp: int,
        grid_m: int,
        grid_n: int,
        seed: int,
        rows: wp.array(dtype=wp.int32),
        rows_per_take: int,
        background: wp.vec3,
        out_rgb: wp.array2d(dtype=wp.vec3),
        out_alpha: wp.array2d(dtype=float),
        out_depth: wp.array2d(dtype=float),
        out_normal: wp.array2d(dtype=wp.vec3),
        out_albedo: wp.array2d(dtype=wp.vec3),
        vbuffer: wp.array2d(dtype=wp.uint64),
        maps: ShadowMaps,
        buffers: LightBuffers,
        env: EnvironmentData,
        dfg: wp.array2d(dtype=wp.vec2),
    ):
        # Launched once per thread: takes rows_per_take rows at a time from the counter
        # rows[ROWS_TAKEN], shared by every launch, until none are left (or rows[STOP] is set), so
        # that the threads finish together. (Not a thread index per pixel or row: Warp's CPU code
        # copies the kernel's arguments, structs of arrays of about a kilobyte, for every index.)
        first_row = take_next_item_from(rows, ROWS_TAKEN) * rows_per_take
        while first_row < cam.height and read_counter(rows, STOP) == 0:
            for py in range(first_row, wp.min(first_row + rows_per_take, cam.height)):
                render_row(scene, cam, spp, grid_m, grid_n, seed, py, background, out_rgb, out_alpha, out_depth,
                           out_normal, out_albedo, vbuffer, maps, buffers, env, dfg, rows)
            first_row = take_next_item_from(rows, ROWS_TAKEN) * rows_per_take

    return render_tile
