"""Which effects a render needs: one immutable, hashable Features value per (scene, options).

The render kernel is compiled per Features value (kernels/render.py): an effect a scene does not
call for is absent from the generated code, not skipped at run time. Only *which* effects exist
is in the key; camera, light positions and colours, and material factors are kernel arguments,
so changing them never recompiles.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .brdf import BRDF
from .ibl import IBL
from . import light_buffers, raster
from .emitters import emissive_materials
from .errors import InputError, InputTypeError
from .shadow_maps import shadow_mode
from .lights import DIRECTIONAL, POINT, RECT, SPHERE, SPOT, AreaLighting


@dataclass(frozen=True)
class Features:
    """The effects one render kernel holds: a frozen, hashable value, one compiled kernel per
    value (kernels/render.py render_kernel). Each field is whether an effect is compiled in (True
    or False), or which variant: the shadow technique, the primary visibility path, the IBL rungs
    (an :class:`IBL`, or False without an environment) and the :class:`BRDF`. Renders derive it
    from the scene and options (:func:`scene_features`; :func:`pbrwarp.explain` prints why);
    the defaults, and :meth:`everything`, compile every effect in."""

    base_color_texture: bool = True
    metallic_roughness_texture: bool = True
    emissive_texture: bool = True
    # KHR_materials_specular's textures: strength (alpha channel) and colour
    specular_texture: bool = True
    specular_color_texture: bool = True
    # KHR_materials_transmission: camera rays pass through transmissive surfaces; its texture
    transmission: bool = True
    transmission_texture: bool = True
    # KHR_materials_volume: rays refract into closed meshes and are absorbed inside
    volume: bool = True
    # rough transmission: "prefiltered" (the environment seen through is blurred; the cheap rung),
    # "sampled" (the GGX transmission lobe sampled per camera sample; the exact rung) or False
    rough_transmission: object = "prefiltered"
    # shadow rays pass transmissive surfaces, tinted
    transmissive_shadows: bool = True
    normal_mapping: bool = True
    vertex_colors: bool = True
    emission: bool = True
    # KHR_materials_unlit: materials whose radiance is their base colour
    unlit: bool = True
    # KHR_materials_anisotropy: highlights stretched along a tangent direction
    anisotropy: bool = True
    anisotropy_texture: bool = True
    # KHR_materials_iridescence: a thin film's interference colours in the Fresnel terms
    iridescence: bool = True
    iridescence_texture: bool = True
    # KHR_materials_clearcoat: a coat layer, and its textures (intensity, roughness, normal map)
    clearcoat: bool = True
    clearcoat_textures: bool = True
    # KHR_materials_sheen: a Charlie sheen layer, and its colour and roughness textures
    sheen: bool = True
    sheen_textures: bool = True
    diffuse: bool = True
    specular: bool = True
    point_lights: bool = True
    directional_lights: bool = True
    spot_lights: bool = True
    # area lights: spheres and rectangles (pbrwarp.SphereLight, pbrwarp.RectLight)
    sphere_lights: bool = True
    rect_lights: bool = True
    # how area lights are integrated: a pbrwarp.AreaLighting, or False without area lights
    area_lighting: object = AreaLighting()
    # area lights trace shadow rays through the BVH (shadow maps and light buffers serve
    # punctual lights only)
    area_shadows: bool = True
    # "rays" (a shadow ray per light and hit), "map" (shadow-map lookups) or False
    shadows: object = "rays"
    supersampling: bool = True
    # camera rays may pass through surfaces: single-sided back faces, alpha masks
    pass_through: bool = True
    # camera rays composite alpha-blended surfaces' coverage front to back (glTF alphaMode BLEND)
    alpha_blend: bool = True
    # occlusion rays (shadow rays, shadowed environment directions) pass alpha cut-outs
    masked_occlusion: bool = True
    # depth, normal and albedo outputs
    aovs: bool = True
    # primary visibility: "raycast" (a BVH query per camera sample) or "raster" (a visibility buffer)
    visibility: str = "raycast"
    # environment lighting: the IBL rungs (pbrwarp.IBL), or False without an environment
    environment: object = IBL()
    occlusion_texture: bool = True
    # misses show the environment rather than a constant background
    environment_background: bool = True
    # the model of each BRDF term
    brdf: BRDF = BRDF()
    # how textures are filtered: "trilinear" (mip-mapped over each pixel's footprint), "bilinear"
    # (the full-resolution image only), or False where no texture is read
    texture_filter: object = "trilinear"
    # textures read with a second uv set (glTF TEXCOORD_1)
    second_uv_set: bool = True
    # the light transport: "direct" (kernels/render.py) or "path" (kernels/path.py)
    integrator: str = "direct"

    @property
    def textures(self) -> bool:
        return any(getattr(self, name) for name in TEXTURE_FLAGS)

    @classmethod
    def everything(cls, spp: int = 1, aovs: bool = True, brdf: BRDF = BRDF(), shadows="rays", ibl: IBL = IBL(),
                   environment_background: bool = True, texture_filter: str = "trilinear",
                   area_lighting: AreaLighting = AreaLighting()) -> "Features":
        """Every effect compiled in and primary rays ray cast: the unspecialized kernel, the
        reference for specialization. Sampling, outputs, BRDF, the shadow technique, the IBL and
        area-light rungs, what misses show and the texture filter follow the options."""
        technique = shadow_mode(shadows)[0]
        return cls(supersampling=spp > 1, aovs=aovs, brdf=brdf, shadows=technique, environment=ibl,
                   area_lighting=area_lighting, area_shadows=bool(technique),
                   environment_background=environment_background, texture_filter=_texture_filter(texture_filter),
                   rough_transmission="sampled" if ibl.method == "monte_carlo" else "prefiltered")


# The Features flags that read textures (each a material slot, or the normal map's).
TEXTURE_FLAGS = ("base_color_texture", "metallic_roughness_texture", "emissive_texture", "normal_mapping",
                 "specular_texture", "specular_color_texture", "occlusion_texture", "anisotropy_texture",
                 "iridescence_texture", "clearcoat_textures", "sheen_textures", "transmission_texture")
# Material texture slots whose Features flag has another name.
_SLOT_FLAGS = {"normal_texture": "normal_mapping", "iridescence_thickness_texture": "iridescence_texture",
               "clearcoat_texture": "clearcoat_textures", "clearcoat_roughness_texture": "clearcoat_textures",
               "clearcoat_normal_texture": "clearcoat_textures", "sheen_color_texture": "sheen_textures",
               "sheen_roughness_texture": "sheen_textures"}
TEXTURE_FILTERS = ("trilinear", "bilinear")


def _texture_filter(mode) -> str:
    if not isinstance(mode, str) or mode not in TEXTURE_FILTERS:
        raise InputError(f"texture_filter must be one of {', '.join(map(repr, TEXTURE_FILTERS))}, got {mode!r}")
    return mode


@dataclass(frozen=True)
class Decision:
    name: str
    present: object
    why: str


def _is_convex(scene, prim) -> bool:
    """Whether ``prim``, one of ``scene``'s, is one closed convex surface (kept in the scene cache:
    the hull is costly for big meshes)."""
    def convex(prim):
        import trimesh

        mesh = trimesh.Trimesh(prim.positions, prim.faces, process=False)
        return bool(mesh.is_watertight and mesh.is_convex)

    return scene.cache.fact("convex", prim, convex)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "es" if noun.endswith("sh") else "s")


INTEGRATORS = ("direct", "path")
# Path tracing's default bounces: paths of up to 8 segments, as Mitsuba's path integrator's
# max_depth=8 (the Cornell-box speed target of issue 31 counts segments).
DEFAULT_MAX_BOUNCES = 7
# The most bounces a render may ask for.
MAX_BOUNCES = 1024
VISIBILITY_MODES = ("auto", "raycast", "raster")
# visibility="auto" ray-casts rather than hold a visibility buffer (8 bytes a sample, plus the
# sample positions' 8) larger than this: 1920 x 1080 at 16 spp needs 506 MiB, 3840 x 2160 at
# 16 spp would need 2 GiB.
BYTES_PER_SAMPLE = 16
MAX_AUTO_VISIBILITY_BUFFER_BYTES = 2**30
def estimated_visibility_seconds(triangles: int, samples: int) -> tuple[float, float]:
    """(raster, ray cast) seconds of primary visibility on every core, by the cost models
    bench/visibility.py fitted (pbrwarp/raster.py keeps the constants)."""
    raster_s = raster.RASTER_SECONDS_PER_TRIANGLE * triangles + raster.RASTER_SECONDS_PER_SAMPLE * samples
    raycast_s = raster.RAYCAST_SECONDS_PER_SAMPLE_LOG2_TRIANGLE * samples * math.log2(max(triangles, 2))
    return raster_s, raycast_s


def _visibility(mode: str, triangles: int, samples: int) -> tuple[str, str]:
    """(path, why) for primary visibility."""
    if mode not in VISIBILITY_MODES:
        raise InputError(f"visibility must be one of {', '.join(VISIBILITY_MODES)}, got {mode!r}")
    raster_s, raycast_s = estimated_visibility_seconds(triangles, samples)
    estimate = f"{triangles:,} triangles, {samples:,} samples: about {1e3 * raster_s:.1f} ms rasterized, {1e3 * raycast_s:.1f} ms ray cast"
    if mode != "auto":
        path = mode
        return path, f"primary visibility {_path_words(path)} (visibility={mode!r}; {estimate})"
    if samples * BYTES_PER_SAMPLE > MAX_AUTO_VISIBILITY_BUFFER_BYTES:
        return "raycast", (f"primary visibility ray cast: a visibility buffer of {samples:,} samples would take "
                           f"{samples * BYTES_PER_SAMPLE / 2**20:,.0f} MiB ({estimate})")
    path = "raster" if raster_s < raycast_s else "raycast"
    return path, f"primary visibility {_path_words(path)}, the cheaper ({estimate})"


def _path_words(path: str) -> str:
    if path == "raster":
        return (f"rasterized (clusters of {raster.CLUSTER_SIZE} triangles skipped where off screen, facing away "
                "from the eye if single-sided or closed, or hidden)")
    return "ray cast"


def decide(scene, gpu, *, shadows, spp: int, aovs: bool = True, brdf: BRDF = BRDF(), visibility: str = "auto",
           samples: int = 480_000, ibl: IBL = IBL(), background_given: bool = False,
           texture_filter: str = "trilinear", area_lighting: AreaLighting = AreaLighting(), integrator: str = "direct",
           max_bounces: int = DEFAULT_MAX_BOUNCES) -> list[Decision]:
    """Every effect with whether the render simulates it and why, in the order explain prints.
    ``integrator`` "path" (with ``max_bounces``) decides for the path tracer (path_decisions)."""
    texture_filter = _texture_filter(texture_filter)
    tracing_paths = check_integrator(integrator) == "path"
    prims = scene.primitives
    rows = gpu.material_rows
    mats = [p.material for p in prims]
    count = {k: sum(1 for light in scene.lights if light.kind == k) for k in (POINT, DIRECTIONAL, SPOT, SPHERE, RECT)}
    punctual = count[POINT] + count[DIRECTIONAL] + count[SPOT]
    areas = count[SPHERE] + count[RECT]

    def slot(attr, label):
        users = sum(1 for r in rows if getattr(r, attr) >= 0)
        return (users > 0, f"{label}: {users} of {len(rows)} meshes" if users else f"no {label}s")

    decisions = []

    def add(name, present, why):
        decisions.append(Decision(name, bool(present), why))

    path, why = _visibility(visibility, scene.triangle_count, samples)
    decisions.append(Decision("visibility", path, why))

    decisions.append(Decision("brdf", brdf, f"BRDF: {brdf.describe()}"))

    for name, kind, label in (("point_lights", POINT, "point light"), ("directional_lights", DIRECTIONAL, "directional light"),
                              ("spot_lights", SPOT, "spot light")):
        add(name, count[kind], _count(count[kind], label) if count[kind] else f"no {label}s")
    for name, kind, label in (("sphere_lights", SPHERE, "sphere light"), ("rect_lights", RECT, "rectangle light")):
        add(name, count[kind], _count(count[kind], label) if count[kind] else f"no {label}s")
    if areas:
        decisions.append(Decision("area_lighting", area_lighting, f"area lights: {area_lighting.describe()}"))
    else:
        add("area_lighting", False, "no area lights")
    lit_mats = [m for m in mats if not m.unlit]
    if not scene.lights and scene.environment is None and not (tracing_paths and emissive_materials(scene)):
        add("diffuse", False, "no lights: only emission and the background")
        add("specular", False, "no lights: no reflection")
    elif not lit_mats:
        add("diffuse", False, "no diffuse: every material is unlit")
        add("specular", False, "no specular lobe: every material is unlit")
    else:
        diffuse = any(m.metallic < 1.0 or m.metallic_roughness_texture is not None for m in lit_mats)
        add("diffuse", diffuse, f"{brdf.diffuse} diffuse" if diffuse else "no diffuse: every material is fully metallic")
        specular = any(m.specular > 0.0 or m.metallic > 0.0 for m in lit_mats)
        lobe = (f"Cook-Torrance specular: {brdf.distribution} distribution, {brdf.geometry} geometry, {brdf.fresnel} "
                f"Fresnel" if brdf.model == "microfacet" else f"legacy normalized {brdf.model} specular lobe")
        add("specular", specular, lobe if specular else "no specular lobe: every material has specular = 0 and metallic = 0")
    shadows, _ = shadow_mode(shadows)
    convex = (bool(shadows) and bool(scene.lights) and len(prims) == 1 and not prims[0].material.see_through
              and _is_convex(scene, prims[0]))
    if not shadows:
        add("shadows", False, "no shadow rays: shadows=False")
    elif not punctual:
        add("shadows", False, "no shadow rays: no lights" if not areas else "no shadow rays for punctual lights: none")
    elif convex:
        add("shadows", False, "no shadow rays: one convex mesh cannot shadow itself beyond what n.l does")
    elif shadows == "map":
        decisions.append(Decision("shadows", "map", f"shadow maps: {punctual} lookups per hit, "
                                  f"maps rasterized from each light ({scene.triangle_count:,} triangles)"))
    else:
        side = light_buffers.scene_resolution(scene)
        finer = (f", finer than the {light_buffers.RESOLUTION}² of scenes up to "
                 f"~{light_buffers.RESOLUTION_TRIANGLES:,} triangles" if side > light_buffers.RESOLUTION else "")
        decisions.append(Decision("shadows", "rays", f"shadow rays: {punctual} per hit, against "
                                  f"{scene.triangle_count:,} triangles, through each light's light buffer "
                                  f"(the triangles seen in each of {side}² directions per view{finer}; rays leaving "
                                  "a triangle, or its interior, marked clear of the light skip it)"))
    if not areas:
        add("area_shadows", False, "no area-light shadows: no area lights")
    elif not shadows:
        add("area_shadows", False, "no area-light shadow rays: shadows=False")
    elif convex:
        add("area_shadows", False, "no area-light shadow rays: one convex mesh cannot shadow itself beyond what "
            "the horizon does")
    else:
        how = (f"{area_lighting.samples} per area light and hit (soft shadows)" if area_lighting.method == "monte_carlo"
               else "one per area light and hit, to its centre (hard shadows)")
        add("area_shadows", True, f"area-light shadow rays: {how}, through the BVH"
            + ("; shadow maps serve punctual lights only" if shadows == "map" else
               "; light buffers serve punctual lights only (area-light rays start from points across the light)"))
    environment = scene.environment
    if environment is None:
        add("environment", False, "no environment lighting: scene.environment is None")
        add("occlusion_texture", False, "no occlusion textures read: they scale environment light only")
        add("environment_background", False, "misses show the background colour")
    else:
        decisions.append(Decision("environment", ibl, f"environment lighting ({environment!r}): {ibl.describe()}"))
        present, why = slot("occlusion_texture", "occlusion texture")
        if ibl.shadowed:
            present, why = False, "no occlusion textures: the scene itself occludes the traced environment directions"
        add("occlusion_texture", present, why)
        add("environment_background", not background_given,
            "misses show the background colour given" if background_given else "misses show the environment")
    present, why = slot("base_color_texture", "base colour texture")
    add("base_color_texture", present, why)
    present, why = slot("metallic_roughness_texture", "metallic-roughness texture")
    add("metallic_roughness_texture", present, why)
    present, why = slot("emissive_texture", "emissive texture")
    add("emissive_texture", present, why)
    specular_lobe = next(d.present for d in decisions if d.name == "specular")
    for name, label in (("specular_texture", "specular texture"), ("specular_color_texture", "specular colour texture")):
        present, why = slot(name, label)
        if present and not specular_lobe:
            present, why = False, f"no {label}s read: no specular lobe"
        add(name, present, why)
    stretched = [m for m in lit_mats if m.anisotropy_strength > 0.0] if specular_lobe else []
    add("anisotropy", stretched, f"anisotropic highlights (KHR_materials_anisotropy): "
        f"{_count(len(stretched), 'material')}, anisotropic GGX with height-correlated Smith masking"
        if stretched else "no anisotropy: every lit material has anisotropy_strength 0" if specular_lobe
        else "no anisotropy: no specular lobe")
    present, why = slot("anisotropy_texture", "anisotropy texture")
    if present and not stretched:
        present, why = False, "no anisotropy textures read: no anisotropic material"
    add("anisotropy_texture", present, why)
    filmed = [m for m in lit_mats if m.iridescence > 0.0] if specular_lobe else []
    add("iridescence", filmed, f"thin-film iridescence (KHR_materials_iridescence): {_count(len(filmed), 'material')}, "
        "Belcour & Barla 2017's Fresnel of the film" if filmed
        else "no iridescence: every lit material has iridescence 0" if specular_lobe
        else "no iridescence: no specular lobe")
    users = sum(1 for r in rows if r.iridescence_texture >= 0 or r.iridescence_thickness_texture >= 0)
    present, why = users > 0, (f"iridescence textures: {users} of {len(rows)} meshes" if users
                               else "no iridescence textures")
    if present and not filmed:
        present, why = False, "no iridescence textures read: no iridescent material"
    add("iridescence_texture", present, why)
    present, why = slot("normal_texture", "normal map")
    add("normal_mapping", present, why + ("" if present else ": no tangent frames"))
    coated = sum(1 for m in lit_mats if m.clearcoat > 0.0)
    add("clearcoat", coated, f"clear coat (KHR_materials_clearcoat): {_count(coated, 'material')}" if coated
        else "no clear coat: every clearcoat factor is 0")
    sheened = sum(1 for m in lit_mats if max(m.sheen_color) > 0.0)
    if sheened and not (scene.lights or environment or (tracing_paths and emissive_materials(scene))):
        add("sheen", False, "no sheen: no lights")
    else:
        add("sheen", sheened, f"sheen (KHR_materials_sheen): {_count(sheened, 'material')}" if sheened
            else "no sheen: every sheen colour is black")
    for name, layer, slots in (("clearcoat_textures", "clearcoat", ("clearcoat_texture", "clearcoat_roughness_texture",
                                                                     "clearcoat_normal_texture")),
                               ("sheen_textures", "sheen", ("sheen_color_texture", "sheen_roughness_texture"))):
        users = sum(1 for r in rows if any(getattr(r, s) >= 0 for s in slots))
        label = name.replace("_", " ")
        if users and not next(d.present for d in decisions if d.name == layer):
            add(name, False, f"no {label} read: no {layer} layer")
        else:
            add(name, users, f"{label}: {users} of {len(rows)} meshes" if users else f"no {label}")
    unlit = sum(1 for m in mats if m.unlit)
    add("unlit", unlit, f"unlit (KHR_materials_unlit): {_count(unlit, 'material')} show their base colour"
        if unlit else "no unlit materials")
    emitters = sum(1 for m in mats if max(m.emissive) > 0.0)
    add("emission", emitters, f"emission: {_count(emitters, 'material')}" if emitters else "no emission: every emissive factor is 0")
    coloured = sum(1 for p in prims if p.colors is not None and not np.all(p.colors == 1.0))
    add("vertex_colors", coloured, f"vertex colours: {_count(coloured, 'mesh')}" if coloured else "no vertex colours")
    add("supersampling", spp > 1, f"{spp} stratified samples per pixel" if spp > 1 else "one ray through each pixel centre (spp = 1)")
    masked = sum(1 for m in mats if m.alpha_mode == "MASK")
    traced = any((d.name == "shadows" and d.present == "rays") or (d.name == "area_shadows" and d.present)
                 or (d.name == "environment" and d.present and d.present.shadowed) for d in decisions)
    if not traced:
        add("masked_occlusion", False, "no cut-outs in occlusion rays: no shadow rays nor shadowed environment rays")
    else:
        add("masked_occlusion", masked, f"occlusion rays pass alpha cut-outs ({_count(masked, 'material')})" if masked
            else "no cut-outs in occlusion rays: no alpha-masked material")
    transmissive = [m for m in mats if m.transmissive and not m.unlit]
    add("transmission", transmissive, f"camera rays pass through smooth transmissive surfaces "
        f"(KHR_materials_transmission: {_count(len(transmissive), 'material')})"
        if transmissive else "no transmission: no transmissive material")
    present, why = slot("transmission_texture", "transmission texture")
    if present and not transmissive:
        present, why = False, "no transmission textures read: no transmissive material"
    add("transmission_texture", present, why)
    volumes = sum(1 for m in transmissive if m.thickness > 0.0)
    add("volume", volumes, f"rays refract into and out of closed volumes, absorbed inside (KHR_materials_volume: "
        f"{_count(volumes, 'material')})" if volumes else "no volumes: every transmissive surface is thin-walled"
        if transmissive else "no volumes: no transmissive material")
    traced_shadows = (next(d.present for d in decisions if d.name == "shadows") == "rays"
                      or next(d.present for d in decisions if d.name == "area_shadows"))
    if transmissive and traced_shadows:
        add("transmissive_shadows", True, "shadow rays pass transmissive surfaces, tinted by what they transmit "
            "(straight, without refraction)")
    else:
        add("transmissive_shadows", False, "no tinted shadows: " + (
            "no shadow rays" if transmissive else "no transmissive material")
            + ("" if traced_shadows or not transmissive else " (shadow maps and environment rays treat glass as opaque)"))
    rough = sum(1 for m in transmissive if m.roughness > 0.0)
    environment_shown = next(d.present for d in decisions if d.name == "environment_background")
    lighting = next(d.present for d in decisions if d.name == "environment")
    if rough and lighting and lighting.method == "monte_carlo":
        decisions.append(Decision("rough_transmission", "sampled", "rough transmission samples the GGX transmission "
                                  f"lobe per camera sample ({_count(rough, 'material')}; the exact rung, with Monte "
                                  "Carlo environment lighting: what lies behind is blurred, with noise)"))
    elif rough and environment_shown:
        decisions.append(Decision("rough_transmission", "prefiltered", "the environment seen through rough "
                                  f"transmissive surfaces is blurred: prefiltered at their roughness "
                                  f"({_count(rough, 'material')}; cheap rung: objects behind stay sharp)"))
    else:
        add("rough_transmission", False, "no transmission blur: " + (
            "misses show the background colour" if rough else "no rough transmissive material"))
    blended = sum(1 for m in mats if m.alpha_mode == "BLEND")
    add("alpha_blend", blended, f"camera rays composite alpha-blended coverage front to back "
        f"({_count(blended, 'material')}; opaque to shadow and environment rays)" if blended
        else "no alpha blending: no alphaMode BLEND material")
    decisions += _texture_decisions(prims, decisions, texture_filter)  # after every texture slot's decision
    single = sum(1 for m in mats if not m.double_sided or m.alpha_mode == "MASK")
    add("pass_through", single, f"camera rays pass single-sided back faces and alpha cut-outs ({_count(single, 'material')})"
        if single else "no pass-through: every material is double-sided and opaque")
    add("aovs", aovs, "depth, normal and albedo outputs" if aovs else "no depth, normal or albedo outputs: aovs=False")
    if tracing_paths:
        return path_decisions(decisions, scene, spp, max_bounces)
    return [Decision("integrator", "direct", "direct lighting (integrator='direct'): the light of the lights and "
                     "the environment reflected once towards the eye; light bouncing between surfaces is not "
                     "simulated (integrator='path' does)")] + decisions


def _listed(items: list[str]) -> str:
    """"a", "a and b", "a, b and c"."""
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def path_decisions(decisions: list[Decision], scene, spp: int, max_bounces: int) -> list[Decision]:
    """``decisions`` (the direct integrator's) turned into the path tracer's: what it traces
    instead of the direct kernel's shadow and visibility techniques."""
    lights, areas, emitting = len(scene.punctual_lights), len(scene.area_lights), emissive_materials(scene)
    masked = sum(1 for p in scene.primitives if p.material.alpha_mode == "MASK")
    sources = []
    if areas:
        sources.append(_count(areas, "area light"))
    if emitting:
        sources.append(f"the triangles of {_count(emitting, 'emissive mesh')}")
    if scene.environment is not None and any(d.name == "environment" and d.present for d in decisions):
        sources.append("the environment")
    shadow_rays = []
    if lights:
        shadow_rays.append(f"one shadow ray per punctual light ({_count(lights, 'punctual light')}: delta lights, by "
                           "light sampling alone)")
    if sources:
        shadow_rays.append(f"a shadow ray towards one light chosen by power from {_listed(sources)}, weighted against "
                           "BSDF sampling by the power heuristic (BSDF-sampled rays see area lights, camera rays do "
                           "not)")
    changed = {
        "visibility": ("raycast", "primary visibility ray cast: each camera ray starts a path"),
        "supersampling": (True, f"{_count(spp, 'path')} per pixel through random points of it (counter-based "
                                "random numbers: the image does not depend on threads)"),
        "occlusion_texture": (False, "no occlusion textures read: the path tracer traces the occlusion they stand "
                                     "for"),
        "shadows": ("rays", "next-event estimation at every path vertex: " + "; ".join(shadow_rays))
        if shadow_rays else (False, "no shadow rays: no lights and no emissive meshes to sample"),
        "masked_occlusion": (bool(masked), f"shadow rays pass alpha cut-outs ({_count(masked, 'material')})" if masked
                             else "no cut-outs in shadow rays: no alpha-masked material"),
    }
    if areas:
        changed["area_lighting"] = (False, "no area-light rung: the path tracer samples area lights by next-event "
                                           "estimation (area_lighting= applies to integrator='direct')")
        changed["area_shadows"] = (False, "no separate area-light shadow rays: next-event estimation's serve them")
    transmissive = [p.material for p in scene.primitives if p.material.transmissive and not p.material.unlit]
    if transmissive:
        changed["transmission"] = (True, "paths and shadow rays pass straight through smooth thin transmissive walls, "
                                         "paths with the probability of the share transmitted (KHR_materials_"
                                         f"transmission: {_count(len(transmissive), 'material')})")
        changed["transmissive_shadows"] = (False, "no separate tinted shadows: shadow rays pass smooth thin walls "
                                                  "tinted, and stop at volumes and rough walls (the light through "
                                                  "them arrives by sampling their transmission lobes)")
    volumes = sum(1 for m in transmissive if m.thickness > 0.0)
    if volumes:
        changed["volume"] = (True, "paths refract into and out of volumes (Snell's law, or Walter et al.'s rough "
                                   "interface; Fresnel reflection and total internal reflection included), absorbed "
                                   f"inside by Beer-Lambert (KHR_materials_volume: {_count(volumes, 'material')}; "
                                   "one volume at a time, not nested)")
    rough = sum(1 for m in transmissive if m.thickness <= 0.0 and m.roughness > 0.0 and m.ior != 1.0)
    if rough and not next(d.present for d in decisions if d.name == "specular"):
        changed["specular"] = (True, "specular lobe: rough thin walls transmit along its mirror image")
    changed["rough_transmission"] = (
        ("sampled", "paths pass rough thin walls along the GGX transmission lobe (the specular lobe mirrored "
                    "through the wall), sampled, and next-event estimation lights it from behind them "
                    f"({_count(rough, 'material')})") if rough else
        (False, "no rough transmission lobe: " + ("no rough thin-walled transmissive material" if transmissive
                                                  else "no transmissive material")))
    if scene.environment is not None:
        changed["environment"] = (IBL(), f"environment ({scene.environment!r}): the radiance of rays that escape "
                                         "the scene, a light importance-sampled by luminance for next-event estimation and weighted "
                                         "against BSDF sampling by the power heuristic")
    out = [Decision("integrator", "path", f"path tracing (integrator='path'): light bouncing up to {max_bounces} "
                    f"times between surfaces (paths of up to {max_bounces + 1} segments), the BRDF's lobes sampled "
                    "by a mixture of cosine and GGX visible normals, Russian roulette after three bounces; "
                    "emissive materials are lights")]
    for d in decisions:
        if d.name in changed:
            present, why = changed[d.name]
            out.append(Decision(d.name, present, why))
        else:
            out.append(d)
    return out


def path_features(f: Features) -> Features:
    """``f`` with what the path tracer ignores set to one value, so that renders differing only
    there share a kernel: visibility is ray cast, every pixel supersampled, shadows traced, the
    environment's IBL rungs unused, occlusion textures dropped (its paths find what occludes)."""
    return dataclasses.replace(
        f, integrator="path", visibility="raycast", supersampling=True, shadows="rays", occlusion_texture=False,
        environment=IBL() if f.environment else False, rough_transmission="sampled" if f.rough_transmission else False,
        transmissive_shadows=False, area_lighting=False, area_shadows=False)


def check_integrator(integrator) -> str:
    """``integrator`` if it names one of INTEGRATORS; InputTypeError or InputError otherwise."""
    if not isinstance(integrator, str):
        raise InputTypeError(f"integrator must be 'direct' or 'path', got {integrator!r}")
    if integrator not in INTEGRATORS:
        raise InputError(f"integrator must be one of {', '.join(map(repr, INTEGRATORS))}, got {integrator!r}")
    return integrator


def _texture_decisions(prims, decisions, texture_filter: str) -> list[Decision]:
    """How the textures read (the slots ``decisions`` keep) are filtered, and whether any of them
    reads TEXCOORD_1."""
    read = {d.name for d in decisions if d.name in TEXTURE_FLAGS and d.present}
    if not read:
        return [Decision("texture_filter", False, "no texture filtering: no textures read"),
                Decision("second_uv_set", False, "no second uv set: no textures read")]
    if texture_filter == "trilinear":
        why = ("textures filtered trilinearly: the mip level of each sample's footprint, from ray differentials "
               "(isotropic: the footprint's longer side)")
    else:
        why = ("textures filtered bilinearly at full resolution (texture_filter='bilinear'): textures finer than "
               "the pixels alias")
    second = sorted({slot for p in prims if p.uvs is not None for slot, tex, _ in p.material.textures()
                     if tex.texcoord == 1 and _SLOT_FLAGS.get(slot, slot) in read})
    return [Decision("texture_filter", texture_filter, why),
            Decision("second_uv_set", bool(second), f"second uv set (TEXCOORD_1) read by {', '.join(second)}"
                     if second else "no second uv set: every texture read uses TEXCOORD_0")]


def scene_features(scene, gpu, **options) -> Features:
    """The Features a scene needs under the given render options (decide's keywords)."""
    return Features(**{d.name: d.present for d in decide(scene, gpu, **options)})


def describe(decisions: list[Decision], load_warnings=()) -> str:
    """The text of pw.explain: what is simulated, then what was dropped and why, then what the
    scene's file asks for that pbrwarp does not honour (``Scene.load_warnings``), if anything."""
    on = [d.why for d in decisions if d.present is not False]
    off = [d.why for d in decisions if d.present is False]
    lines = ["simulated:"] + [f"  + {w}" for w in on] + ["not simulated:"] + [f"  - {w}" for w in dict.fromkeys(off)]
    if load_warnings:
        lines += ["not honoured from the file (warned at load):"] + [f"  ! {w}" for w in load_warnings]
    return "\n".join(lines)

