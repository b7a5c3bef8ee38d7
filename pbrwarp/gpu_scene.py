"""Turning a Scene into the flat Warp arrays the kernels read (kernels/scene_data.py).

Geometry (with its BVH) and texels are kept in the scene's cache (pbrwarp/scene_cache.py) and
rebuilt only when its meshes or textures change; materials and lights are small and re-uploaded on every render, so editing a
light or a material factor between renders takes effect without rebuilding anything.

The primitives' triangles and vertices are merged into one mesh and stored in locality order
(pbrwarp/locality.py), so a triangle or vertex index in the kernels is not its index in the
primitive: face_material says which primitive a triangle came from.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import validate
from .errors import InputError
from .lights import SPHERE, SPOT
from .locality import inverse_permutation, locality_order
from .materials import Material
from .raster import Clusters, triangle_clusters
from .scene import unit_rows
from .tangents import frame_uv_set, generate_tangents
from .textures import UNORM8_DECODE, WRAP_MODES, Texture, mip_levels, mip_texel_count
from pbrwarp.kernels.area_lights import AREA_RECT, AREA_SPHERE, AreaLightData
from pbrwarp.kernels.lights import LightData
from pbrwarp.kernels.scene_data import INFINITE_IOR, MaterialData, SceneData
from pbrwarp.kernels.textures import TEXELS_FLOAT, TEXELS_SRGB8, TEXELS_UNORM8, Texels, TextureData, texel_store

# Largest triangle and vertex counts the int32 indices of the kernels address.
MAX_ELEMENTS = 2**31 - 1
# glTF's smallest spot cone difference, which keeps cone_scale finite for inner == outer.
MIN_CONE_COS_DIFFERENCE = 0.001
# Triangles per leaf of the ray-casting BVH (Warp builds 4 by default). Two keep the boxes of
# large triangles apart, as in a room whose every wall's box contains the rays' origins:
# bench/results/traversal.md measures the ray rates.
BVH_LEAF_SIZE = 2


@dataclass(eq=False)
class _Geometry:
    mesh: wp.Mesh
    positions: wp.array
    indices: wp.array
    normals: wp.array
    uvs: wp.array
    # TEXCOORD_1 (a mesh without it repeats its uvs), None when no mesh has a second set
    uvs1: wp.array | None
    tangents: wp.array
    colors: wp.array
    face_primitive: wp.array
    # bounds of runs of triangles, for the rasterizer's occlusion culling
    clusters: Clusters


@dataclass(eq=False)
class _Texels:
    key: tuple
    slots: dict  # (id(texture), srgb) -> row in the texture table
    table: wp.array
    texels: Texels


@dataclass
class GpuScene:
    data: SceneData
    # one row per primitive, as uploaded (texture slots are -1 where a mesh has no UVs)
    material_rows: list
    # kept alive while ``data`` refers to them; the first is the uploaded geometry
    _keep: tuple
    # the lights whose rows data.lights and data.area_lights hold, in their order
    punctual_lights: tuple = ()
    area_lights: tuple = ()

    @property
    def geometry(self) -> _Geometry:
        """The uploaded geometry, which the scene cache's slots derived from it are keyed by."""
        return self._keep[0]

    @property
    def clusters(self) -> Clusters:
        """The rasterizer's clusters of data.positions and data.indices (pbrwarp.raster.triangle_clusters)."""
        return self._keep[0].clusters


def _tangent_uv_set(prim) -> int | None:
    """The uv set from which ``prim``'s tangent frame is generated (tangents.frame_uv_set), None
    where it has its own tangents. The material decides, so the geometry cache is keyed by it too."""
    return None if prim.tangents is not None else frame_uv_set(prim.material, prim.uvs, prim.uvs1)


def _primitive_tangents(prim):
    if prim.tangents is not None:
        return prim.tangents
    uv_set = _tangent_uv_set(prim)
    if uv_set is None:
        return np.zeros((len(prim.positions), 4))
    normals = prim.normals if prim.normals is not None else np.zeros_like(prim.positions)
    return generate_tangents(prim.positions, normals, prim.uvs1 if uv_set == 1 else prim.uvs, prim.faces)


def _build_geometry(prims) -> _Geometry:
    counts = [len(p.positions) for p in prims]
    total_vertices = sum(counts)
    total_faces = sum(len(p.faces) for p in prims)
    if total_vertices > MAX_ELEMENTS or total_faces * 3 > MAX_ELEMENTS:
        raise InputError(f"scene too large: {total_vertices} vertices, {total_faces} triangles")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    positions = np.concatenate([p.positions for p in prims]).astype(np.float32)
    indices = np.concatenate([p.faces + s for p, s in zip(prims, starts)]).astype(np.int32).reshape(-1)
    # Validated here a last time: an out-of-range index reaching Warp would crash the process.
    if indices.min() < 0 or indices.max() >= total_vertices:
        raise InputError("internal error: triangle index out of range after merging meshes")
    if not np.all(np.isfinite(positions)):
        raise InputError("a vertex position overflows float32 (|x| > 3.4e38)")

    def column(values, width, default):
        """Per-primitive attribute arrays stacked in float64; ``default`` where one is missing."""
        return np.concatenate([np.full((len(p.positions), width), default, np.float64) if v is None else v
                               for p, v in zip(prims, values)])

    # unit length in float64 here: float32 squares of 1e-20 or 1e20 long normals would
    # under- or overflow in the kernels; zero rows (flat shading) stay zero
    normals = unit_rows(column([p.normals for p in prims], 3, 0.0)).astype(np.float32)
    uvs = column([p.uvs for p in prims], 2, 0.0).astype(np.float32)
    uvs1 = None
    if any(p.uvs1 is not None for p in prims):
        uvs1 = column([p.uvs if p.uvs1 is None else p.uvs1 for p in prims], 2, 0.0).astype(np.float32)
    tangents = column([_primitive_tangents(p) for p in prims], 4, 0.0).astype(np.float32)
    colors = column([p.colors for p in prims], 4, 1.0).astype(np.float32)
    face_primitive = np.concatenate([np.full(len(p.faces), i, np.int32) for i, p in enumerate(prims)])
    # stored in an order that keeps neighbours near in memory (pbrwarp/locality.py)
    face_order, vertex_order = locality_order(wp.array(positions, dtype=wp.vec3, device="cpu"),
                                              wp.array(indices, dtype=wp.int32, device="cpu"))
    indices = inverse_permutation(vertex_order)[indices.reshape(-1, 3)[face_order]].astype(np.int32).reshape(-1)
    wp_positions = wp.array(positions[vertex_order], dtype=wp.vec3, device="cpu")
    wp_indices = wp.array(indices, dtype=wp.int32, device="cpu")
    mesh = wp.Mesh(points=wp_positions, indices=wp_indices, bvh_leaf_size=BVH_LEAF_SIZE)
    return _Geometry(
        mesh=mesh,
        positions=wp_positions,
        indices=wp_indices,
        normals=wp.array(normals[vertex_order], dtype=wp.vec3, device="cpu"),
        uvs=wp.array(uvs[vertex_order], dtype=wp.vec2, device="cpu"),
        uvs1=None if uvs1 is None else wp.array(uvs1[vertex_order], dtype=wp.vec2, device="cpu"),
        tangents=wp.array(tangents[vertex_order], dtype=wp.vec4, device="cpu"),
        colors=wp.array(colors[vertex_order], dtype=wp.vec4, device="cpu"),
        face_primitive=wp.array(face_primitive[face_order], dtype=wp.int32, device="cpu"),
        clusters=triangle_clusters(wp_positions, wp_indices),
    )


def _texture_slots(prims) -> dict:
    """(id(texture), srgb) -> (texture, srgb) of every texture the primitives with UVs sample."""
    slots = {}
    for prim in prims:
        if prim.uvs is not None:
            for _, tex, srgb in prim.material.textures():
                slots.setdefault((id(tex), srgb), (tex, srgb))
    return slots


def _build_texels(prims, key) -> _Texels:
    """The texture table and texels of the textured primitives' materials: each (texture, srgb)
    slot's mip chain (pbrwarp.textures.mip_levels). 8-bit images stay 8-bit, level 0 stored once
    however many slots read it (sRGB-decoded or not, in the kernel), the levels past it per slot
    (averaged in linear space, then re-encoded as the slot decodes them); others are stored as
    linear float32 texels per slot. The texel counts, levels included, are checked against the
    kernels' int32 offsets before any level is made."""
    slots = _texture_slots(prims)
    texels, counted = {False: 0, True: 0}, set()  # texels of float and 8-bit images; 8-bit ones counted
    for tex, _ in slots.values():
        eight_bit = tex.rgba8 is not None
        _, with_levels = mip_texel_count(*tex.shape)
        shared = eight_bit and id(tex) in counted  # its level 0 is counted already
        texels[eight_bit] += with_levels - (tex.shape[0] * tex.shape[1] if shared else 0)
        counted.add(id(tex))
    if max(texels.values()) > MAX_ELEMENTS:
        raise InputError(f"textures too large: {max(texels.values()):,} texels of one kind with their mip levels, "
                         "more than the 2^31 - 1 one scene may hold")
    rows, stored = [], {TEXELS_FLOAT: [], TEXELS_UNORM8: []}  # texel chunks, in order
    count = {TEXELS_FLOAT: 0, TEXELS_UNORM8: 0}
    level0 = {}  # id(texture) -> first texel of an 8-bit image's level 0

    def store(kind, chunk) -> int:
        stored[kind].append(chunk.reshape(-1, 4))
        count[kind] += len(stored[kind][-1])
        return count[kind] - len(stored[kind][-1])

    for tex, srgb in slots.values():
        h, w = tex.shape
        row = TextureData()
        if tex.rgba8 is not None:
            kind = TEXELS_UNORM8
            if id(tex) not in level0:
                level0[id(tex)] = store(kind, tex.rgba8)
            row.offset, row.texel_format = level0[id(tex)], TEXELS_SRGB8 if srgb else TEXELS_UNORM8
        else:
            kind = TEXELS_FLOAT
            row.offset, row.texel_format = store(kind, tex.texels(srgb)), TEXELS_FLOAT
        levels = mip_levels(tex, srgb)
        row.mip_offset = count[kind]
        for level in levels:
            store(kind, level)
        m = tex.uv_matrix()
        row.width, row.height, row.levels = w, h, 1 + len(levels)
        row.wrap_s, row.wrap_t = WRAP_MODES[tex.wrap_s], WRAP_MODES[tex.wrap_t]
        row.uv_set = tex.texcoord
        row.uv_row0, row.uv_row1 = wp.vec3(*m[0]), wp.vec3(*m[1])
        rows.append(row)
    return _Texels(
        key=key,
        slots={slot: i for i, slot in enumerate(slots)},
        table=wp.array(rows if rows else [TextureData()], dtype=TextureData, device="cpu"),
        texels=texel_store(stored[TEXELS_FLOAT], stored[TEXELS_UNORM8], UNORM8_DECODE),
    )


def _material_row(mat: Material, texture_slots: dict, has_uvs: bool) -> MaterialData:
    row = MaterialData()
    row.base_color = wp.vec4(*mat.base_color)
    row.emissive = _float32_vector(mat.emissive, "Material.emissive")
    row.metallic, row.roughness, row.specular = mat.metallic, mat.roughness, mat.specular
    row.f0_dielectric = _float32_vector(mat.f0_dielectric, "Material.specular_color")
    row.normal_scale, row.alpha_cutoff = mat.normal_scale, mat.alpha_cutoff
    row.double_sided = int(mat.double_sided)
    if mat.complex_ior is not None:
        row.ior_eta = _float32_vector(mat.complex_ior[0], "Material.complex_ior n")
        row.ior_kappa = _float32_vector(mat.complex_ior[1], "Material.complex_ior k")
    row.alpha_mask = int(mat.alpha_mode == "MASK")
    row.alpha_blend = int(mat.alpha_mode == "BLEND")
    row.unlit = int(mat.unlit)
    row.anisotropy_strength = mat.anisotropy_strength
    row.anisotropy_rotation = wp.vec2(math.cos(mat.anisotropy_rotation), math.sin(mat.anisotropy_rotation))
    row.iridescence, row.iridescence_ior = mat.iridescence, mat.iridescence_ior
    row.iridescence_thickness = wp.vec2(mat.iridescence_thickness_min, mat.iridescence_thickness_max)
    row.clearcoat, row.clearcoat_roughness = mat.clearcoat, mat.clearcoat_roughness
    row.clearcoat_normal_scale = mat.clearcoat_normal_scale
    row.sheen_color = _float32_vector(mat.sheen_color, "Material.sheen_color")
    row.sheen_roughness = mat.sheen_roughness
    row.transmission, row.thickness = mat.transmission, mat.thickness
    row.attenuation = _float32_vector([min(sigma, _FLOAT32_MAX) for sigma in mat.attenuation_coefficient],
                                      "Material.attenuation_color")
    row.ior = mat.ior if mat.ior > 0.0 else INFINITE_IOR
    slot_index = {slot: texture_slots[(id(tex), srgb)] if has_uvs else -1 for slot, tex, srgb in mat.textures()}
    row.base_color_texture = slot_index.get("base_color_texture", -1)
    row.metallic_roughness_texture = slot_index.get("metallic_roughness_texture", -1)
    row.normal_texture = slot_index.get("normal_texture", -1)
    row.emissive_texture = slot_index.get("emissive_texture", -1)
    row.occlusion_texture = slot_index.get("occlusion_texture", -1)
    row.specular_texture = slot_index.get("specular_texture", -1)
    row.specular_color_texture = slot_index.get("specular_color_texture", -1)
    row.anisotropy_texture = slot_index.get("anisotropy_texture", -1)
    row.iridescence_texture = slot_index.get("iridescence_texture", -1)
    row.iridescence_thickness_texture = slot_index.get("iridescence_thickness_texture", -1)
    row.clearcoat_texture = slot_index.get("clearcoat_texture", -1)
    row.clearcoat_roughness_texture = slot_index.get("clearcoat_roughness_texture", -1)
    row.clearcoat_normal_texture = slot_index.get("clearcoat_normal_texture", -1)
    row.sheen_color_texture = slot_index.get("sheen_color_texture", -1)
    row.sheen_roughness_texture = slot_index.get("sheen_roughness_texture", -1)
    row.transmission_texture = slot_index.get("transmission_texture", -1)
    row.occlusion_strength = mat.occlusion_strength
    return row


_FLOAT32_MAX = float(np.finfo(np.float32).max)


def _float32_vector(values, what: str):
    """``values`` as a float32 vec3, rejecting what float32 cannot hold (e.g. 1e39)."""
    with np.errstate(over="ignore"):
        v = np.asarray(values, dtype=np.float64).astype(np.float32)
    if not np.all(np.isfinite(v)):
        raise InputError(f"{what} {tuple(values)} exceeds the float32 range (|x| < 3.4e38) the kernels compute in")
    return wp.vec3(*v)


def _light_row(light) -> LightData:
    row = LightData()
    row.kind = light.kind
    row.intensity = _float32_vector(np.asarray(light.color) * light.intensity, f"{type(light).__name__} color * intensity")
    row.position = wp.vec3(*getattr(light, "position", (0.0, 0.0, 0.0)))
    row.direction = wp.vec3(*getattr(light, "direction", (0.0, -1.0, 0.0)))
    row.cone_scale, row.cone_offset = 0.0, 1.0
    reach = getattr(light, "range", None)
    # 1 / range^4 in float64, then float32: ranges below ~1e-10 would overflow it, and those
    # lights reach nothing that float32 positions can tell apart from the light itself
    row.inv_range4 = 0.0 if reach is None else float(min(reach ** -4.0, 3.0e38))
    if light.kind == SPOT:
        cos_outer = math.cos(light.outer_cone)
        # KHR_lights_punctual's recommended falloff
        row.cone_scale = 1.0 / max(MIN_CONE_COS_DIFFERENCE, math.cos(light.inner_cone) - cos_outer)
        row.cone_offset = -cos_outer * row.cone_scale
    return row


def _area_light_row(light) -> AreaLightData:
    row = AreaLightData()
    row.kind = AREA_SPHERE if light.kind == SPHERE else AREA_RECT
    row.radiance = _float32_vector(np.asarray(light.color) * light.intensity,
                                   f"{type(light).__name__} color * intensity")
    row.position = wp.vec3(*light.position)
    row.radius = getattr(light, "radius", 0.0)
    row.edge_u = wp.vec3(*getattr(light, "edge_u", (0.0, 0.0, 0.0)))
    row.edge_v = wp.vec3(*getattr(light, "edge_v", (0.0, 0.0, 0.0)))
    row.normal = wp.vec3(*getattr(light, "normal", (0.0, 0.0, 1.0)))
    row.area = light.area
    return row


def upload(scene) -> GpuScene:
    """The scene as a SceneData struct, reusing cached geometry and texels when unchanged, and the
    whole upload while no material or light changed either."""
    prims = list(scene.primitives)
    if not prims:
        raise InputError("the scene has no meshes: add one with scene.add_mesh(...) or load a file")
    cache = scene.cache
    # primitives and textures compare by identity and revision (a field set anew rebuilds what
    # depends on it), and the keys keep them alive
    geo_key = tuple((validate.revision(p), _tangent_uv_set(p)) for p in prims)
    geometry = cache.get("geometry", geo_key, lambda: _build_geometry(prims))
    tex_key = tuple((validate.revision(tex), srgb) for p in prims if p.uvs is not None
                    for _, tex, srgb in p.material.textures())
    texels = cache.get("texels", tex_key, lambda: _build_texels(prims, tex_key))
    for prim in prims:
        if prim.uvs is None and any(True for _ in prim.material.textures()):
            warnings.warn(f"mesh {prim.name!r} has textures but no UVs: its textures are ignored", stacklevel=3)

    # the rows as last uploaded while no material or light changed: building Warp structs field
    # by field is slow enough to matter in a small render
    rows_key = (geometry, texels, tuple((_content_key(p.material), p.uvs is not None) for p in prims),
                tuple((type(light), _content_key(light)) for light in scene.lights))
    return cache.get("rows", rows_key, lambda: _upload_rows(scene, prims, geometry, texels))


def _upload_rows(scene, prims, geometry: _Geometry, texels: _Texels) -> GpuScene:
    materials = [_material_row(p.material, texels.slots, p.uvs is not None) for p in prims]
    lights = [_light_row(light) for light in scene.punctual_lights]
    area_lights = [_area_light_row(light) for light in scene.area_lights]
    data = SceneData()
    data.mesh = geometry.mesh.id
    data.positions, data.indices = geometry.positions, geometry.indices
    data.normals, data.uvs, data.tangents, data.colors = geometry.normals, geometry.uvs, geometry.tangents, geometry.colors
    data.uvs1 = geometry.uvs if geometry.uvs1 is None else geometry.uvs1
    data.face_material = geometry.face_primitive
    data.materials = wp.array(materials, dtype=MaterialData, device="cpu")
    data.textures, data.texels = texels.table, texels.texels
    data.lights = wp.array(lights if lights else [LightData()], dtype=LightData, device="cpu")
    data.num_lights = len(lights)
    data.area_lights = wp.array(area_lights if area_lights else [AreaLightData()], dtype=AreaLightData, device="cpu")
    data.num_area_lights = len(area_lights)
    return GpuScene(data=data, material_rows=materials,
                    _keep=(geometry, texels, data.materials, data.lights, data.area_lights),
                    punctual_lights=tuple(scene.punctual_lights), area_lights=tuple(scene.area_lights))


def _content_key(value):
    """A hashable stand-in for a material's or light's current contents (its fields, nested
    sequences and arrays by value, textures by identity, as the texel cache keys them)."""
    if isinstance(value, Texture):
        return id(value), value._revision
    if hasattr(value, "__dataclass_fields__"):  # a Material, a light
        return tuple(_content_key(v) for v in vars(value).values())
    if isinstance(value, (tuple, list)):
        return tuple(_content_key(v) for v in value)
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if value is None or isinstance(value, (bool, int, float, str, np.generic)):
        return value
    return id(value)


def _is_closed_volume(prim) -> bool:
    """Whether a primitive bounds a volume with its faces turned outwards: every directed edge
    appears once and its reverse once (watertight and consistently wound; vertices are not
    merged, so a mesh split at UV seams counts as open) and the signed volume is positive. The
    edge sort is costly on large meshes: callers keep the answer in the scene cache."""
    faces = np.asarray(prim.faces, dtype=np.int64)
    closed = len(faces) > 0 and not np.any((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                                             | (faces[:, 2] == faces[:, 0]))
    if closed:
        tail, head = faces.reshape(-1), np.roll(faces, -1, axis=1).reshape(-1)
        edges = np.sort(tail * len(prim.positions) + head)
        reversed_edges = np.sort(head * len(prim.positions) + tail)
        closed = bool(np.all(edges[1:] != edges[:-1]) and np.array_equal(edges, reversed_edges))
    if closed:
        p = prim.positions[faces]
        closed = float(np.einsum("ij,ij->", p[:, 0], np.cross(p[:, 1], p[:, 2]))) > 0.0
    return closed


def closed_seen_from(scene, prim, point=None) -> bool:
    """Whether ``prim`` is an opaque closed volume and ``point`` (None: infinitely far away) lies
    outside its bounding box, so outside the volume: a ray from there enters it through a front
    face first, and a segment from anywhere to there that meets it leaves it through a front face
    turned towards the point. ``prim`` is one of ``scene``'s, whose cache keeps its facts."""
    if prim.material.see_through:
        return False
    if point is not None:
        lo, hi = scene.cache.fact("bounds", prim, lambda p: p.bounds())
        if not (np.any(point < lo) or np.any(point > hi)):
            return False
    return scene.cache.fact("closed volume", prim, _is_closed_volume)


def back_faces_unseen(scene, prim, point=None) -> bool:
    """Whether no surface a ray from ``point`` (None: from infinitely far away) shows is a back
    face of ``prim`` (one of ``scene``'s): its material is single-sided (the render kernel passes
    through its back faces), or closed_seen_from(scene, prim, point)."""
    return not prim.material.double_sided or closed_seen_from(scene, prim, point)


# Sets of per-triangle flags of each kind kept in the scene cache (face_flags).
KEPT_FACE_FLAGS = 8


def face_flags(scene, gpu: GpuScene, kind: str, per_primitive: list[bool]) -> wp.array:
    """Per-primitive flags spread over the triangles of ``gpu`` (``scene`` uploaded; a uint8
    wp.array, one entry per triangle), kept in the scene cache while the geometry stays: the same
    array for the same flags (lights that agree share one), the last KEPT_FACE_FLAGS sets of each
    ``kind`` ("culling", "front only", "closed")."""
    geometry = gpu.geometry
    flags = tuple(bool(f) for f in per_primitive)

    def spread():
        per_mesh = np.array(flags, dtype=np.uint8)
        return wp.array(per_mesh[geometry.face_primitive.numpy()], dtype=wp.uint8, device="cpu")

    return scene.cache.get(("face flags", kind, flags), geometry, spread, keep=KEPT_FACE_FLAGS)


def back_face_culling(scene, gpu: GpuScene, eye) -> tuple[wp.array | None, int]:
    """(per-triangle uint8 flags for raster.visibility_buffer's ``cull_back_faces``, or None,
    and how many meshes are culled): a mesh's back faces need not be drawn where the eye sees
    none of them (back_faces_unseen)."""
    eye = np.asarray(eye, dtype=np.float64)
    flags = [back_faces_unseen(scene, prim, eye) for prim in scene.primitives]
    if not any(flags):
        return None, 0
    return face_flags(scene, gpu, "culling", flags), sum(flags)
