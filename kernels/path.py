"""The path tracer: unidirectional path tracing with next-event estimation and multiple importance
sampling (Veach 1997), on the same surfaces, materials and BRDF as the direct render kernel.

Per camera sample, a path leaves the eye through a random point of the pixel. At every surface it
reaches it adds
- the surface's emission, weighted by the power heuristic against light sampling when a BSDF-
  sampled ray found it (full weight for the camera ray);
- next-event estimation: every punctual light (a delta light, sampled only this way, no MIS: a
  shadow ray each, as in the direct kernel), and one light chosen from the light table
  (kernels/emitters.py) by its estimated power: an emissive triangle gets a point uniform on its
  area, a sphere or rectangle light a direction uniform in the solid angle it subtends
  (kernels/area_lights.py), the environment a direction by its luminance
  (kernels/environment_sampling.py), each weighted against BSDF sampling;
then continues along a direction drawn from the BRDF's lobe mixture (kernels/bsdf_sampling.py),
its throughput multiplied by f cos / pdf. That ray adds the radiance of every sphere and
rectangle light it meets before the surface it reaches (area lights are not in the mesh and, as
in the direct kernel, block no light: the path goes on through them), and a ray that escapes
adds the environment's, each weighted by the power heuristic against light sampling (camera
rays do not see area lights, as in the direct kernel, and see the environment at full weight).
Smooth thin transmissive walls are passed as null events,
with the probability of the share they transmit (find_surface), and shadow rays pass them tinted
by that share (transmittance); volumes and rough thin walls scatter paths through them, and stop
shadow rays (kernels/path_transmission.py). After three bounces, Russian roulette continues a path with
probability q = min(max throughput channel, 0.95), dividing its throughput by q. Every random
number is a hash of (seed, pixel, sample, dimension) (kernels/random.py).

Built per feature set like the direct kernel, with only the lights, textures and material inputs
a scene needs; which of the direct kernel's effects the path tracer ignores is pbrwarp.features'
business (path_features).
"""

import dataclasses
import functools

import warp as wp

from .aovs import denoiser_albedo
from .area_lights import area_light_kinds
from .bsdf_sampling import (pdf_brdf_direction, pdf_coated_direction, power_heuristic, sample_brdf_direction,
                            sample_coated_direction, specular_lobe_probability)
from .brdf import brdf_for, max_channel
from .camera import CameraData, camera_ray_direction, sample_footprint_side
from .clearcoat import Coat, clearcoat_for
from .emitters import LightTable, area_to_solid_angle, choose_light_or_environment, sample_triangle, triangle_area
from .environment_sampling import pdf_environment, sample_environment
from .ibl import EnvironmentData, environment_radiance
from .lights import light_sampler
from .material_inputs import material_lookups
from .microfacet import alpha_from_roughness
from .path_transmission import (MAX_PASSED, MIRRORED, NOT_LIGHT_SAMPLED, SCATTERED, medium_after, thin_lobe_frame,
                                transmission_lobes)
from .random import sample_key, uniform, uniform2
from .render import ROWS_TAKEN, STOP
from .robust import FLOAT32_MAX, RAY_FAR, SHADOW_RAY_SHORTENING, clamp_to_float32_max, offset_ray_origin, safe_normalize
from .scene_data import NO_TEXTURE, MaterialData, SceneData, triangle_corners
from .sheen import Sheen, sheen_for
from .surface import MAX_PASS_THROUGH, SurfaceHit, segment_to_point, shadow_segment, surface_hit, surface_tests
from .texture_coords import SurfaceUV, texture_lookups
from .transmission import beer_lambert, transmitted_share
from .work_queue import read_counter, take_next_item_from

wp.set_module_options({"enable_backward": False})

# The random dimensions of a sample: the pixel position, then a block per bounce (the light's
# choice, the point on it, the lobe's choice, the direction, Russian roulette), then the draws of
# alpha-blended coverage and of passing transmissive walls (two per surface met per bounce), far
# past any bounce's.
PIXEL_DIMENSION = wp.constant(0)
FIRST_BOUNCE_DIMENSION = wp.constant(2)
DIMENSIONS_PER_BOUNCE = wp.constant(8)
LIGHT_CHOICE = wp.constant(0)
LIGHT_POINT = wp.constant(1)
LOBE_CHOICE = wp.constant(3)
DIRECTION = wp.constant(4)
ROULETTE = wp.constant(6)
TRANSMISSION_CHOICE = wp.constant(7)
COVERAGE_DIMENSION = wp.constant(1 << 24)
# Russian roulette starts at this bounce (0: the first surface), and keeps at most this share.
ROULETTE_FROM_BOUNCE = wp.constant(3)
MAX_SURVIVAL = wp.constant(0.95)
# With a sheen, the cosine lobe (which samples it) keeps at least this share of the BRDF samples.
MIN_COSINE_LOBE_WITH_SHEEN = wp.constant(0.1)


@wp.struct
class Layers:
    """The layers over a surface's BRDF at a path vertex: its clear coat (weight 0: none) and its
    sheen (colour 0: none), as kernels/clearcoat.py and kernels/sheen.py define them."""

    coat: Coat
    sheen: Sheen


@functools.cache
def path_kernel(features):
    """The path tracer's tile kernel for a ``features`` value (pbrwarp.features.path_features has
    set the flags it ignores), launched as the direct render kernel is: once per thread, taking
    rows from a shared counter (kernels/render.py render_tile)."""
    f = features
    textured = f.textures
    brdf = brdf_for(f.diffuse, f.specular, **dataclasses.asdict(f.brdf), anisotropic=f.anisotropy,
                    iridescent=f.iridescence)
    punctual = f.point_lights or f.directional_lights or f.spot_lights
    area = f.sphere_lights or f.rect_lights
    if area:
        sample_area_light, pdf_area_light, area_light_distance = area_light_kinds(f.sphere_lights, f.rect_lights)
    # the environment is a light where it lights the scene (not where it is only the background)
    environment_lights = bool(f.environment)
    sample_light = light_sampler(f.point_lights, f.directional_lights, f.spot_lights)
    # transmissive surfaces that bend light (volumes, rough thin walls) scatter paths through them
    # (kernels/path_transmission.py), lit or not; without them, smooth thin walls are passed straight only
    lobes = f.transmission and (f.volume or bool(f.rough_transmission))
    scattering = f.diffuse or f.specular or lobes
    hit_uv, alpha_at, is_cut_out, _, occluded = surface_tests(textured, f.base_color_texture, f.masked_occlusion,
                                                              f.second_uv_set)
    # textures are filtered over a sample's footprint where the camera ray meets its first
    # surface, at full resolution after a bounce
    footprint = textured and f.texture_filter == "trilinear"
    hit_texcoords, texture = texture_lookups(textured, footprint, f.second_uv_set)
    inputs = material_lookups(f, texture)
    base_color_at, surface_inputs, emission_at = inputs.base_color_at, inputs.surface_inputs, inputs.emission_at
    anisotropy_at, thin_film_at, shading_normal = inputs.anisotropy_at, inputs.thin_film_at, inputs.shading_normal
    transmission_at = inputs.transmission_at
    if lobes:
        scatters, scatter = transmission_lobes(f.volume, bool(f.rough_transmission))
    oriented_normal = inputs.oriented_normal
    if f.clearcoat:
        coat_at, _, clearcoat_brdf, _ = clearcoat_for(f.brdf.distribution, f.brdf.geometry, f.brdf.fresnel,
                                                      texture if f.clearcoat_textures else None)
    if f.sheen:
        sheen_at, _, sheen_brdf, sheen_scaling, _, _ = sheen_for(texture if f.sheen_textures else None)

    @wp.func
    def layers_at(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: SurfaceUV, n: wp.vec3,
                  v: wp.vec3) -> Layers:
        """The clear coat and sheen of the material at the hit, seen from v (none where the kernel
        has neither)."""
        layers = Layers()
        if wp.static(f.clearcoat):
            coat_normal_map = NO_TEXTURE
            if wp.static(f.clearcoat_textures):
                coat_normal_map = mat.clearcoat_normal_texture
            layers.coat = coat_at(scene, mat, uv, oriented_normal(scene, h, uv, coat_normal_map,
                                                                  mat.clearcoat_normal_scale), v)
        if wp.static(f.sheen):
            layers.sheen = sheen_at(scene, mat, uv, n, v)
        return layers

    @wp.func
    def reflected_cosine(n: wp.vec3, v: wp.vec3, l: wp.vec3, base: wp.vec3, metallic: float, roughness: float,
                         specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, aniso_t: wp.vec3,
                         anisotropy: float, thin_film: wp.vec3, layers: Layers) -> wp.vec3:
        """f(v, l) times the cosine, as the direct kernel combines the layers: the BRDF at n.l
        under the sheen (KHR_materials_sheen's albedo scaling, plus its lobe) and under the clear
        coat (times 1 - its weight), plus the coat's lobe at Nc.l (KHR_materials_clearcoat)."""
        fr = brdf(n, v, l, base, metallic, roughness, specular, eta, kappa, f0_dielectric, aniso_t, anisotropy,
                  thin_film)
        if wp.static(f.sheen):
            fr = fr * sheen_scaling(layers.sheen, l) + sheen_brdf(layers.sheen, v, l)
        fr = fr * wp.max(wp.dot(n, l), 0.0)
        if wp.static(f.clearcoat):
            coat = layers.coat
            fr = fr * (1.0 - coat.weight) + wp.vec3(clearcoat_brdf(coat, v, l) * wp.max(wp.dot(coat.normal, l), 0.0))
        return fr

    @wp.func
    def direction_pdf(n: wp.vec3, v: wp.vec3, l: wp.vec3, alpha: float, p_specular: float, layers: Layers) -> float:
        """The solid-angle pdf with which sample_direction draws l: the coat's lobe (GGX visible
        normals about the coat's normal) with probability its weight, else the BRDF's mixture."""
        if wp.static(f.clearcoat):
            return pdf_coated_direction(n, v, l, alpha, p_specular, layers.coat.normal,
                                        alpha_from_roughness(layers.coat.roughness),
                                        wp.clamp(layers.coat.weight, 0.0, 1.0))
        return pdf_brdf_direction(n, v, l, alpha, p_specular)

    @wp.func
    def sample_direction(n: wp.vec3, v: wp.vec3, alpha: float, p_specular: float, layers: Layers, u_lobe: float,
                         u: wp.vec2) -> wp.vec3:
        """A direction from the lobes direction_pdf gives the density of; ``u_lobe`` chooses the
        coat (below its weight) or, rescaled, the BRDF's lobe."""
        if wp.static(f.clearcoat):
            return sample_coated_direction(n, v, alpha, p_specular, layers.coat.normal,
                                           alpha_from_roughness(layers.coat.roughness),
                                           wp.clamp(layers.coat.weight, 0.0, 1.0), u_lobe, u)
        return sample_brdf_direction(n, v, alpha, p_specular, u_lobe, u)

    @wp.func
    def wall_share(scene: SceneData, h: SurfaceHit, mat: MaterialData, d: wp.vec3) -> wp.vec3:
        """The share of light a smooth thin transmissive wall passes straight through along ``d``,
        per channel, 0 for an opaque surface and for one that scatters light (a volume's, a rough
        wall's): transmitted_share at the geometric normal's cosine (the same both ways),
        textures read at full resolution."""
        if wp.static(lobes):
            if scatters(mat):
                return wp.vec3(0.0)
        uv = hit_texcoords(scene, h, hit_uv(scene, h), h.p, d, d)
        t = transmission_at(scene, mat, uv)
        if t <= 0.0:
            return wp.vec3(0.0)
        metallic, roughness, specular, f0_dielectric = surface_inputs(scene, mat, uv)
        return transmitted_share(base_color_at(scene, h, mat, uv), metallic, t, specular, f0_dielectric,
                                 wp.abs(wp.dot(h.ng, d)))

    @wp.func
    def transmittance(scene: SceneData, origin: wp.vec3, direction: wp.vec3, max_t: float, blended: bool) -> wp.vec3:
        """The share of light that travels the shadow ray's segment: 0 where an opaque surface
        or one that scatters light (wall_share) blocks it, the product of the shares of the
        surfaces it passes otherwise: a smooth thin wall's (straight through, as paths pass
        them), and, where ``blended``, 1 - alpha + alpha times that of an alpha-blended surface
        (what find_surface passes on average; without ``blended`` such a surface passes all:
        the caller has drawn its coverage); after MAX_PASS_THROUGH surfaces, 0."""
        if wp.static(not f.transmission and not f.alpha_blend):
            if occluded(scene, origin, direction, max_t):
                return wp.vec3(0.0)
            return wp.vec3(1.0)
        o = origin
        reach = max_t
        passed = wp.vec3(1.0)
        for _ in range(MAX_PASS_THROUGH):
            q = wp.mesh_query_ray(scene.mesh, o, direction, reach)
            if not q.result:
                return passed
            b = surface_hit(scene, q.face, q.u, q.v, direction)
            mat = scene.materials[b.material]
            if not is_cut_out(scene, b, mat, hit_uv(scene, b)):
                share = wp.vec3(0.0)
                if wp.static(f.transmission):
                    if mat.transmission > 0.0:
                        share = wall_share(scene, b, mat, direction)
                if wp.static(f.alpha_blend):
                    if mat.alpha_blend == 1:
                        alpha = float(0.0)
                        if blended:
                            alpha = wp.clamp(alpha_at(scene, b, mat, hit_uv(scene, b)), 0.0, 1.0)
                        share = share * alpha + wp.vec3(1.0 - alpha)
                if max_channel(share) <= 0.0:
                    return wp.vec3(0.0)
                passed = wp.cw_mul(passed, share)
            o = offset_ray_origin(b.p, b.p_error, b.ng, direction)
            reach = reach - q.t
        return wp.vec3(0.0)

    @wp.func
    def find_surface(scene: SceneData, origin: wp.vec3, d: wp.vec3, camera_ray: bool, key: wp.uint32, bounce: int):
        """(found, hit, weight, met) of the surface the ray from ``origin`` along ``d`` stops at:
        past alpha cut-outs, past single-sided back faces for camera rays (as the direct kernel),
        past an alpha-blended surface with probability 1 - alpha (its coverage, drawn), and past a
        thin transmissive wall with probability p = min(max channel of its share, MAX_PASSED):
        ``weight`` is then multiplied by share / p, or by 1 / (1 - p) where the ray stops at it,
        so that on average it passes its share and reflects the rest. ``met``: whether a
        transmissive wall was met (it covers the pixel). After MAX_PASS_THROUGH surfaces passed,
        a miss."""
        o = origin
        h = SurfaceHit()
        weight = wp.vec3(1.0)
        met = False
        for k in range(MAX_PASS_THROUGH):
            q = wp.mesh_query_ray(scene.mesh, o, d, RAY_FAR)
            if not q.result:
                return False, h, weight, met
            h = surface_hit(scene, q.face, q.u, q.v, d)
            passes = False
            draw = COVERAGE_DIMENSION + 2 * (bounce * MAX_PASS_THROUGH + k)
            if wp.static(f.pass_through or f.alpha_blend or f.transmission):
                mat = scene.materials[h.material]
                if wp.static(f.pass_through):
                    passes = is_cut_out(scene, h, mat, hit_uv(scene, h))
                    if camera_ray and h.back_face == 1 and mat.double_sided == 0:
                        passes = True
                if wp.static(f.alpha_blend):
                    if not passes and mat.alpha_blend == 1:
                        alpha = wp.clamp(alpha_at(scene, h, mat, hit_uv(scene, h)), 0.0, 1.0)
                        passes = uniform(key, draw) >= alpha
                if wp.static(f.transmission):
                    if not passes and mat.transmission > 0.0:
                        share = wall_share(scene, h, mat, d)
                        p = wp.min(max_channel(share), MAX_PASSED)
                        if p > 0.0:
                            met = True
                            if uniform(key, draw + 1) < p:
                                passes = True
                                weight = wp.cw_mul(weight, share / p)
                            else:
                                weight = weight / (1.0 - p)
            if not passes:
                return True, h, weight, met
            o = offset_ray_origin(h.p, h.p_error, h.ng, d)
        return False, h, weight, met

    @wp.func
    def emitter_pdf(scene: SceneData, lights: LightTable, h: SurfaceHit, from_point: wp.vec3, d: wp.vec3) -> float:
        """The solid-angle pdf with which next-event estimation at ``from_point`` samples the point
        of ``h`` a ray along ``d`` reached: its triangle's probability over its area, per solid angle."""
        c = triangle_corners(scene.indices, h.face)
        area = triangle_area(scene.positions[c[0]], scene.positions[c[1]], scene.positions[c[2]])
        if area <= 0.0:
            return 0.0
        to_hit = h.p - from_point
        pmf = lights.face_pmf[h.face] * (1.0 - lights.environment)
        return area_to_solid_angle(pmf / area, wp.dot(to_hit, to_hit), wp.dot(h.ng, d))

    @wp.func
    def area_lights_met(scene: SceneData, lights: LightTable, p: wp.vec3, origin: wp.vec3, d: wp.vec3, reach: float,
                        met: bool, bsdf_pdf: float) -> wp.vec3:
        """The radiance of the area lights the BSDF-sampled ray from ``origin`` (offset from the
        vertex p it was sampled at) along ``d`` meets before ``reach`` (the surface it reaches),
        each weighted by the power heuristic against next-event estimation's density at p, and
        by the share of thin transmissive walls on the way (transmittance, as shadow rays). Where
        the ray ``met`` such a wall, ``reach`` is unbounded and alpha-blended surfaces pass their
        mean share too; otherwise the ray's own draws decided them."""
        total = wp.vec3(0.0)
        # the table holds every area light, unless none of the scene's lights emits (then it is empty)
        for k in range(wp.min(scene.num_area_lights, lights.area)):
            light = scene.area_lights[k]
            t = area_light_distance(light, origin, d)
            # shortened as next-event estimation's shadow rays are (segment_to_point), so that a
            # surface through the light (a rect light flush with a ceiling) hides it from neither
            shortened = t * (1.0 - SHADOW_RAY_SHORTENING)
            if t > 0.0 and shortened < reach:
                passed = wp.vec3(1.0)
                if wp.static(f.transmission):
                    passed = transmittance(scene, origin, d, shortened, met)
                light_pdf = lights.pmf[k] * (1.0 - lights.environment) * pdf_area_light(light, p, d)
                total = total + wp.cw_mul(light.radiance, passed) * power_heuristic(bsdf_pdf, light_pdf)
        return total

    @wp.func
    def light_sample(scene: SceneData, origin: wp.vec3, direction: wp.vec3, max_t: float, le: wp.vec3, pdf: float,
                     n: wp.vec3, v: wp.vec3, l: wp.vec3, base: wp.vec3, metallic: float, roughness: float,
                     specular: float, eta: wp.vec3, kappa: wp.vec3, f0_dielectric: wp.vec3, aniso_t: wp.vec3,
                     anisotropy: float, thin_film: wp.vec3, alpha: float, p_specular: float, layers: Layers) -> wp.vec3:
        """The radiance reflected towards v of light ``le`` arriving along l, sampled with solid-angle
        ``pdf`` (choice included) by next-event estimation: passed through the shadow ray's
        segment (transmittance), MIS-weighted (power heuristic) against BSDF sampling."""
        passed = transmittance(scene, origin, direction, max_t, True)
        if max_channel(passed) <= 0.0:
            return wp.vec3(0.0)
        reflected = reflected_cosine(n, v, l, base, metallic, roughness, specular, eta, kappa, f0_dielectric, aniso_t,
                                     anisotropy, thin_film, layers)
        weight = power_heuristic(pdf, direction_pdf(n, v, l, alpha, p_specular, layers))
        return wp.cw_mul(wp.cw_mul(reflected, le), passed) * (weight / pdf)

    @wp.func
    def punctual_lights_reflected(scene: SceneData, h: SurfaceHit, n: wp.vec3, v: wp.vec3, base: wp.vec3,
                                  metallic: float, roughness: float, specular: float, eta: wp.vec3, kappa: wp.vec3,
                                  f0_dielectric: wp.vec3, aniso_t: wp.vec3, anisotropy: float, thin_film: wp.vec3,
                                  layers: Layers) -> wp.vec3:
        """Radiance reflected towards v of every punctual light: each a shadow ray, none chosen by
        chance (choosing among them by an estimate of their power adds the most noise where the
        estimate misjudges what reaches the surface, a directional light's above all)."""
        total = wp.vec3(0.0)
        for i in range(scene.num_lights):
            ls = sample_light(scene.lights[i], h.p)
            # light below the geometric surface: shading normals must not leak it through
            if wp.dot(h.ng, ls.to_light) > 0.0 and wp.dot(n, ls.to_light) > 0.0 and max_channel(ls.irradiance) > 0.0:
                origin, direction, max_t = shadow_segment(scene, i, h, ls)
                passed = transmittance(scene, origin, direction, max_t, True)
                if max_channel(passed) > 0.0:
                    reflected = reflected_cosine(n, v, ls.to_light, base, metallic, roughness, specular, eta, kappa,
                                                 f0_dielectric, aniso_t, anisotropy, thin_film, layers)
                    total = total + wp.cw_mul(wp.cw_mul(reflected, ls.irradiance), passed)
        return total

    @wp.func
    def next_event(scene: SceneData, lights: LightTable, env: EnvironmentData, h: SurfaceHit, n: wp.vec3, v: wp.vec3, base: wp.vec3,
                   metallic: float, roughness: float, specular: float, eta: wp.vec3, kappa: wp.vec3,
                   f0_dielectric: wp.vec3, aniso_t: wp.vec3, anisotropy: float, thin_film: wp.vec3, alpha: float,
                   p_specular: float, layers: Layers, key: wp.uint32, dim: int) -> wp.vec3:
        """Radiance reflected towards v of one light chosen from the table or the environment,
        divided by the probability of that choice and by the sample's pdf, MIS-weighted against
        BSDF sampling; 0 where the light is below the surface or blocked."""
        i, pmf = choose_light_or_environment(lights, uniform(key, dim + LIGHT_CHOICE))
        if pmf <= 0.0:
            return wp.vec3(0.0)
        if wp.static(environment_lights):
            if i == -1:
                l, env_pdf = sample_environment(env.sampler, env, uniform2(key, dim + LIGHT_POINT))
                pdf = pmf * env_pdf
                if not (pdf > 0.0) or wp.dot(h.ng, l) <= 0.0 or wp.dot(n, l) <= 0.0:
                    return wp.vec3(0.0)
                le = environment_radiance(env, l)
                if max_channel(le) <= 0.0:
                    return wp.vec3(0.0)
                return light_sample(scene, offset_ray_origin(h.p, h.p_error, h.ng, l), l, RAY_FAR, le, pdf, n, v, l,
                                    base, metallic, roughness, specular, eta, kappa, f0_dielectric, aniso_t,
                                    anisotropy, thin_film, alpha, p_specular, layers)
        if i < 0:
            return wp.vec3(0.0)
        if wp.static(area):
            if i < lights.area:
                light = scene.area_lights[i]
                l, distance, light_pdf = sample_area_light(light, h.p, uniform2(key, dim + LIGHT_POINT))
                pdf = pmf * light_pdf
                if not (pdf > 0.0) or wp.dot(h.ng, l) <= 0.0 or wp.dot(n, l) <= 0.0:
                    return wp.vec3(0.0)
                if max_channel(light.radiance) <= 0.0:
                    return wp.vec3(0.0)
                origin, direction, max_t = segment_to_point(h, h.p + l * distance, l)
                return light_sample(scene, origin, direction, max_t, light.radiance, pdf, n, v, l, base, metallic,
                                    roughness, specular, eta, kappa, f0_dielectric, aniso_t, anisotropy, thin_film,
                                    alpha, p_specular, layers)
        if wp.static(f.emission):
            face = lights.face[i - lights.area]
            if face == h.face:
                return wp.vec3(0.0)  # a flat triangle does not light itself
            b = sample_triangle(uniform2(key, dim + LIGHT_POINT))
            c = triangle_corners(scene.indices, face)
            p0 = scene.positions[c[0]]
            p1 = scene.positions[c[1]]
            p2 = scene.positions[c[2]]
            target = p0 * b[0] + p1 * b[1] + p2 * (1.0 - b[0] - b[1])
            to_target = target - h.p
            distance_sq = wp.dot(to_target, to_target)
            l = safe_normalize(to_target, n)
            if distance_sq <= 0.0 or wp.dot(h.ng, l) <= 0.0 or wp.dot(n, l) <= 0.0:
                return wp.vec3(0.0)
            e = surface_hit(scene, face, b[0], b[1], l)
            mat = scene.materials[e.material]
            if e.back_face == 1 and mat.double_sided == 0:
                return wp.vec3(0.0)  # a single-sided emitter seen from behind
            if wp.static(f.pass_through):
                if is_cut_out(scene, e, mat, hit_uv(scene, e)):
                    return wp.vec3(0.0)
            pdf = area_to_solid_angle(pmf / triangle_area(p0, p1, p2), distance_sq, wp.dot(e.ng, -l))
            if pdf <= 0.0:
                return wp.vec3(0.0)
            # the emitted radiance's texture is read at full resolution
            le = emission_at(scene, mat, hit_texcoords(scene, e, hit_uv(scene, e), target, l, l))
            if wp.static(f.alpha_blend):
                if mat.alpha_blend == 1:  # paths meet it with probability alpha: it emits that share
                    le = le * wp.clamp(alpha_at(scene, e, mat, hit_uv(scene, e)), 0.0, 1.0)
            if max_channel(le) <= 0.0:
                return wp.vec3(0.0)
            origin, direction, max_t = segment_to_point(h, target, l)
            return light_sample(scene, origin, direction, max_t, le, pdf, n, v, l, base, metallic, roughness, specular,
                                eta, kappa, f0_dielectric, aniso_t, anisotropy, thin_film, alpha, p_specular, layers)
        return wp.vec3(0.0)

    @wp.func
    def lobe_probability(base: wp.vec3, metallic: float, specular: float, f0_dielectric: wp.vec3,
                         n_dot_v: float) -> float:
        """The probability of sampling the specular lobe, fixed where the kernel has one lobe only."""
        if wp.static(not f.specular):
            return 0.0
        if wp.static(not f.diffuse):
            return 1.0
        return specular_lobe_probability(base, metallic, specular, f0_dielectric, n_dot_v)

    @wp.func
    def render_row(scene: SceneData, cam: CameraData, spp: int, first_sample: int, seed: int, max_bounces: int,
                   py: int, background: wp.vec3, out_rgb: wp.array2d(dtype=wp.vec3),
                   out_alpha: wp.array2d(dtype=float), out_depth: wp.array2d(dtype=float),
                   out_normal: wp.array2d(dtype=wp.vec3), out_albedo: wp.array2d(dtype=wp.vec3),
                   env: EnvironmentData, lights: LightTable, rows: wp.array(dtype=wp.int32)):
        """Row py of the image, path by path, unless rows[STOP] is set: then the row is left at the
        next pixel."""
        step = sample_footprint_side(spp)
        for px in range(cam.width):
            if read_counter(rows, STOP) != 0:
                return
            pixel = py * cam.width + px
            radiance = wp.vec3(0.0)
            normal_sum = wp.vec3(0.0)
            albedo_sum = wp.vec3(0.0)
            depth = float(RAY_FAR)
            covered = int(0)
            for s in range(spp):
                key = sample_key(seed, pixel, first_sample + s)
                jitter = uniform2(key, PIXEL_DIMENSION)
                x = float(px) + jitter[0]
                y = float(py) + jitter[1]
                d = camera_ray_direction(cam, x, y)
                dir_dx = d
                dir_dy = d
                if wp.static(footprint):
                    dir_dx = camera_ray_direction(cam, x + step, y)
                    dir_dy = camera_ray_direction(cam, x, y + step)
                origin = cam.eye
                throughput = wp.vec3(1.0)
                # the pdf of the BSDF sample that led here (0 for the camera ray: emission seen
                # directly has full weight) and the vertex it left
                previous_pdf = float(0.0)
                previous_p = cam.eye
                # the attenuation coefficient of the volume the path travels in (0: none), and
                # whether the path has only been scattered through transmissive surfaces since the eye
                sigma = wp.vec3(0.0)
                seen_through = bool(True)
                for bounce in range(max_bounces + 1):
                    found, h, passed, met = find_surface(scene, origin, d, bounce == 0, key, bounce)
                    if wp.static(area):
                        if bounce > 0:  # camera rays do not see area lights (as in the direct kernel)
                            # the surface reached bounds the lights seen, unless a transmissive
                            # wall was met: then transmittance weighs them, whatever the path did
                            reach = float(RAY_FAR)
                            if found and not met:
                                reach = wp.dot(h.p - origin, d)
                            radiance = radiance + wp.cw_mul(throughput, area_lights_met(
                                scene, lights, previous_p, origin, d, reach, met, previous_pdf))
                    throughput = wp.cw_mul(throughput, passed)
                    if wp.static(lobes and f.volume):
                        if max_channel(sigma) > 0.0:  # absorbed on the way (Beer-Lambert); escaping: all
                            throughput = wp.cw_mul(throughput, beer_lambert(
                                sigma, wp.where(found, wp.length(h.p - origin), RAY_FAR)))
                    if not found:
                        if bounce == 0:
                            if met:  # transmissive walls cover the pixel
                                covered = covered + 1
                            if wp.static(f.environment_background):
                                radiance = radiance + wp.cw_mul(throughput, environment_radiance(env, d))
                            else:
                                if met:  # the background seen through them
                                    radiance = radiance + wp.cw_mul(throughput, background)
                        else:
                            # the background seen through transmissive surfaces, as through thin walls
                            # (where the environment lights the scene, it is what they show instead)
                            if wp.static(lobes and not f.environment_background and not environment_lights):
                                if seen_through:
                                    radiance = radiance + wp.cw_mul(throughput, background)
                            if wp.static(environment_lights):
                                # weighted against next-event estimation's choice of the environment
                                weight = power_heuristic(previous_pdf,
                                                         lights.environment * pdf_environment(env.sampler, env, d))
                                radiance = radiance + wp.cw_mul(throughput, environment_radiance(env, d)) * weight
                        break
                    mat = scene.materials[h.material]
                    uv = hit_texcoords(scene, h, hit_uv(scene, h), origin, dir_dx, dir_dy)
                    if bounce == 0:
                        covered = covered + 1
                    n = wp.vec3(0.0)
                    if wp.static(scattering or f.aovs):
                        n = shading_normal(scene, h, mat, uv)
                    if wp.static(f.aovs):
                        if bounce == 0:
                            normal_sum = normal_sum + n
                            albedo_sum = albedo_sum + denoiser_albedo(base_color_at(scene, h, mat, uv))
                            depth = wp.min(depth, wp.length(h.p - cam.eye))
                    if wp.static(f.unlit):
                        if mat.unlit != 0:  # KHR_materials_unlit: its base colour, and no bounce
                            radiance = radiance + wp.cw_mul(throughput, base_color_at(scene, h, mat, uv))
                            break
                    layers = Layers()
                    if wp.static(f.clearcoat or f.sheen):
                        layers = layers_at(scene, h, mat, uv, n, -d)
                    if wp.static(f.emission):
                        if h.back_face == 0 or mat.double_sided == 1:
                            le = emission_at(scene, mat, uv)
                            if wp.static(f.clearcoat):  # the coat passes 1 - its weight of the emission
                                le = le * (1.0 - layers.coat.weight)
                            if max_channel(le) > 0.0:
                                weight = float(1.0)
                                if previous_pdf > 0.0:
                                    weight = power_heuristic(previous_pdf,
                                                             emitter_pdf(scene, lights, h, previous_p, d))
                                radiance = radiance + wp.cw_mul(throughput, le) * weight
                    if bounce == max_bounces:
                        break
                    if wp.static(not scattering):
                        break
                    v = -d
                    base = base_color_at(scene, h, mat, uv)
                    metallic, roughness, specular, f0_dielectric = surface_inputs(scene, mat, uv)
                    dim = FIRST_BOUNCE_DIMENSION + bounce * DIMENSIONS_PER_BOUNCE
                    scattered = bool(False)  # along a direction drawn by scatter
                    through = bool(False)  # through a transmissive surface
                    l = wp.vec3(0.0)
                    pdf = float(0.0)
                    if wp.static(f.transmission):
                        t = transmission_at(scene, mat, uv)
                        if wp.static(lobes):
                            if t > 0.0 and scatters(mat):
                                share = transmitted_share(base, metallic, t, specular, f0_dielectric,
                                                          wp.abs(wp.dot(n, v)))
                                event, l, event_weight = scatter(d, n, h.ng, h.back_face, mat, roughness, share,
                                                                 uniform(key, dim + TRANSMISSION_CHOICE),
                                                                 uniform(key, dim + LOBE_CHOICE),
                                                                 uniform2(key, dim + DIRECTION))
                                throughput = wp.cw_mul(throughput, event_weight)
                                if event == SCATTERED:
                                    scattered = True
                                    through = True
                                    pdf = NOT_LIGHT_SAMPLED
                                    sigma = medium_after(sigma, mat, h.back_face, h.ng, l)
                                if event == MIRRORED:
                                    # a rough thin wall's lobe: the reflection of a white metal off
                                    # the frame mirrored through the wall, sampled and lit below
                                    n, v, mirrored_ng, roughness = thin_lobe_frame(n, v, h.ng, roughness, mat.ior)
                                    h.ng = mirrored_ng
                                    layers = Layers()  # the lobe is the wall's bare transmission
                                    base = wp.vec3(1.0)
                                    metallic = 1.0
                                    t = 0.0
                                    through = True
                            if not through:
                                seen_through = False
                        # the diffuse lobe keeps what transmission leaves (KHR_materials_transmission)
                        base = base * (1.0 - t)
                    aniso_t = wp.vec3(0.0)
                    anisotropy = float(0.0)
                    if wp.static(f.anisotropy):
                        aniso_t, anisotropy = anisotropy_at(scene, h, mat, uv, n)
                    thin_film = wp.vec3(0.0)
                    if wp.static(f.iridescence):
                        thin_film = thin_film_at(scene, mat, uv)
                    alpha = alpha_from_roughness(roughness)
                    p_specular = lobe_probability(base, metallic, specular, f0_dielectric, wp.dot(n, v))
                    if wp.static(f.sheen):  # the cosine lobe samples the sheen's
                        if max_channel(layers.sheen.color) > 0.0:
                            p_specular = wp.min(p_specular, 1.0 - MIN_COSINE_LOBE_WITH_SHEEN)
                    if not scattered:  # the reflecting BRDF: next-event estimation, then a direction from it
                        lit = next_event(scene, lights, env, h, n, v, base, metallic, roughness, specular,
                                         mat.ior_eta, mat.ior_kappa, f0_dielectric, aniso_t, anisotropy, thin_film,
                                         alpha, p_specular, layers, key, dim)
                        if wp.static(punctual):
                            lit = lit + punctual_lights_reflected(scene, h, n, v, base, metallic, roughness, specular,
                                                                  mat.ior_eta, mat.ior_kappa, f0_dielectric, aniso_t,
                                                                  anisotropy, thin_film, layers)
                        radiance = radiance + wp.cw_mul(throughput, lit)
                        l = sample_direction(n, v, alpha, p_specular, layers, uniform(key, dim + LOBE_CHOICE),
                                             uniform2(key, dim + DIRECTION))
                        if wp.dot(h.ng, l) <= 0.0 or wp.dot(n, l) <= 0.0:
                            break  # below the surface: the BRDF is 0 there
                        pdf = direction_pdf(n, v, l, alpha, p_specular, layers)
                        if pdf <= 0.0:
                            break
                        reflected = reflected_cosine(n, v, l, base, metallic, roughness, specular, mat.ior_eta,
                                                     mat.ior_kappa, f0_dielectric, aniso_t, anisotropy, thin_film,
                                                     layers)
                        throughput = wp.cw_mul(throughput, reflected) * (1.0 / pdf)
                    strongest = max_channel(throughput)
                    if not (strongest > 0.0 and strongest < FLOAT32_MAX):
                        break  # nothing more to carry (or an overflow: dropped rather than Inf or NaN)
                    if bounce + 1 >= ROULETTE_FROM_BOUNCE:
                        survival = wp.min(strongest, MAX_SURVIVAL)
                        if uniform(key, dim + ROULETTE) >= survival:
                            break
                        throughput = throughput / survival
                    previous_pdf = pdf
                    previous_p = h.p
                    origin = offset_ray_origin(h.p, h.p_error, h.ng, l)
                    d = l
                    dir_dx = d  # after a bounce, textures are read at full resolution
                    dir_dy = d
            inv_spp = 1.0 / float(spp)
            alpha_out = float(covered) * inv_spp
            seen_behind = background * (1.0 - alpha_out)
            if wp.static(f.environment_background):
                seen_behind = wp.vec3(0.0)
            out_rgb[py, px] = clamp_to_float32_max(radiance * inv_spp + seen_behind)
            out_alpha[py, px] = alpha_out
            if wp.static(f.aovs):
                out_albedo[py, px] = albedo_sum * inv_spp  # a miss adds 0
                if covered > 0:
                    out_depth[py, px] = depth
                    out_normal[py, px] = safe_normalize(normal_sum, wp.vec3(0.0))
                else:
                    out_depth[py, px] = wp.inf
                    out_normal[py, px] = wp.vec3(0.0)

    @wp.kernel(enable_backward=False, module="unique")
    def path_tile(
        scene: SceneData,
        cam: CameraData,
        spp: int,
        first_sample: int,
        seed: int,
        max_bounces: int,
        rows: wp.array(dtype=wp.int32),
        rows_per_take: int,
        background: wp.vec3,
        out_rgb: wp.array2d(dtype=wp.vec3),
        out_alpha: wp.array2d(dtype=float),
        out_depth: wp.array2d(dtype=float),
        out_normal: wp.array2d(dtype=wp.vec3),
        out_albedo: wp.array2d(dtype=wp.vec3),
        env: EnvironmentData,
        lights: LightTable,
    ):
        # as kernels/render.py render_tile: rows_per_take rows at a time from the shared counter
        first_row = take_next_item_from(rows, ROWS_TAKEN) * rows_per_take
        while first_row < cam.height and read_counter(rows, STOP) == 0:
            for py in range(first_row, wp.min(first_row + rows_per_take, cam.height)):
                render_row(scene, cam, spp, first_sample, seed, max_bounces, py, background, out_rgb, out_alpha,
                           out_depth, out_normal, out_albedo, env, lights, rows)
            first_row = take_next_item_from(rows, ROWS_TAKEN) * rows_per_take

    return path_tile
