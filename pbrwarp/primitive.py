"""Primitives: one triangle mesh in world space with one material, and the conversions into one
(a ``trimesh.Trimesh`` and its visual, a 4x4 transform). The scene layer and the file loaders
both build on this module."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError, InputTypeError
from .materials import Material
from .textures import srgb_to_linear

_CREASE_ANGLE = math.radians(30.0)


def _float_array(value, shape_tail, what, dtype=np.float64):
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} must be a numeric array") from None
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != tuple(shape_tail):
        raise InputError(f"{what} must have shape (N, {', '.join(map(str, shape_tail))}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr).all(axis=tuple(range(1, arr.ndim))))[:3].ravel().tolist()
        raise InputError(f"{what} contains NaN or Inf (first bad rows: {bad})")
    return arr


def _mesh_name(prim) -> str:
    return f"mesh {prim.name!r}" if prim.name else "mesh"


def _positions(prim, value) -> np.ndarray:
    what = _mesh_name(prim)
    positions = _float_array(value, (3,), f"{what} vertices")
    with np.errstate(over="ignore"):
        overflow = ~np.isfinite(positions.astype(np.float32)).all(axis=1)
    if overflow.any():
        rows = np.flatnonzero(overflow)[:3].tolist()
        raise InputError(f"{what} vertices exceed the float32 range (|x| < 3.4e38) the renderer computes in "
                         f"(first bad rows: {rows})")
    if len(positions) >= 2**31 - 1:
        raise InputError(f"{what} has {len(positions)} vertices; at most 2^31 - 2 are supported")
    return positions


def _faces(prim, value) -> np.ndarray:
    what = _mesh_name(prim)
    try:
        faces = np.asarray(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} faces must be an integer array") from None
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{what} faces must have shape (F, 3) (triangles only), got {faces.shape}")
    if len(faces) == 0:
        raise InputError(f"{what} has no faces: nothing to render")
    if not np.issubdtype(faces.dtype, np.integer):
        if not np.all(np.isfinite(faces)) or np.any(faces != np.round(faces)):
            raise InputTypeError(f"{what} faces must hold whole vertex indices")
    return faces.astype(np.int64)


def _material(prim, value) -> Material:
    if not isinstance(value, Material):
        raise InputTypeError(f"{_mesh_name(prim)} material must be a pbrwarp.Material, got {type(value).__name__}")
    return value


def _vertex_attribute(attr: str, width: int):
    def check(prim, value):
        return None if value is None else _float_array(value, (width,), f"{_mesh_name(prim)} {attr}")
    return check


VERTEX_ATTRIBUTES = (("normals", 3), ("uvs", 2), ("tangents", 4), ("colors", 4), ("uvs1", 2))


@dataclass(eq=False)
class Primitive(validate.Checked):
    """One triangle mesh in world space with one material.

    ``positions`` (N, 3) are world units within float32's range; ``faces`` (F, 3), F >= 1, index
    them (whole numbers in 0..N-1); ``material`` is a :class:`Material`. Optional per-vertex
    attributes (default None), finite, one row per vertex: ``normals`` (N, 3), whose rows of
    zero length mean "no normal here" (those triangles are shaded flat) and which need not be
    unit; ``uvs`` (N, 2) in glTF's convention ((0, 0) = top-left of the image); ``tangents``
    (N, 4), glTF's (xyz, handedness w), generated from UVs when absent and a normal texture needs
    them; ``colors`` (N, 4), linear RGBA multiplying the base colour; ``uvs1`` (N, 2), a second
    uv set (glTF TEXCOORD_1) for textures whose ``texcoord`` is 1. ``name`` is for messages.
    Every field is checked whenever it is set, by the constructor or later (InputError for a bad
    shape or value, InputTypeError for a bad type), so a mesh with another vertex count is a new
    Primitive. Replace an array rather than change it in place: renders see assignments only.
    """

    positions: np.ndarray
    faces: np.ndarray
    material: Material
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    tangents: np.ndarray | None = None
    colors: np.ndarray | None = None
    name: str = ""
    uvs1: np.ndarray | None = None

    _checks = {"positions": _positions, "faces": _faces, "material": _material,
               **{attr: _vertex_attribute(attr, width) for attr, width in VERTEX_ATTRIBUTES}}

    def _check_together(self):
        what = _mesh_name(self)
        n = len(self.positions)
        lo, hi = int(self.faces.min()), int(self.faces.max())
        if lo < 0 or hi >= n:
            raise InputError(f"{what} faces index vertices {lo}..{hi}, but the mesh has {n} vertices "
                             f"(valid: 0..{n - 1})")
        for attr, _ in VERTEX_ATTRIBUTES:
            value = getattr(self, attr)
            if value is not None and len(value) != n:
                raise InputError(f"{what} has {n} vertices but {len(value)} {attr}")

    def bounds(self):
        return self.positions.min(axis=0), self.positions.max(axis=0)


def transform_primitive(prim: Primitive, matrix) -> Primitive:
    """``prim`` moved by the 4x4 ``matrix``; a mirroring matrix also reverses the winding, and
    flips the tangents' handedness, so that front faces and bitangents stay consistent."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise InputError(f"transform must be a finite 4x4 matrix, got shape {m.shape}")
    linear = m[:3, :3]
    det = np.linalg.det(linear)
    if det == 0.0:
        raise InputError("transform is singular (zero scale): the mesh would collapse to a plane")
    positions = prim.positions @ linear.T + m[:3, 3]
    normals = None if prim.normals is None else unit_rows(prim.normals @ np.linalg.inv(linear))
    tangents = None
    if prim.tangents is not None:
        xyz = unit_rows(prim.tangents[:, :3] @ linear.T)
        tangents = np.concatenate([xyz, prim.tangents[:, 3:] * np.sign(det)], axis=1)
    faces = prim.faces[:, ::-1] if det < 0 else prim.faces
    return Primitive(positions, faces, prim.material, normals, prim.uvs, tangents, prim.colors, prim.name, prim.uvs1)


def unit_rows(v):
    """Unit rows; zero rows stay zero (they mark missing normals)."""
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)


# ---------------------------------------------------------------------- trimesh conversion
def _has_supplied_normals(mesh) -> bool:
    cache = getattr(getattr(mesh, "_cache", None), "cache", {})
    return "vertex_normals" in cache


def primitive_from_trimesh(mesh, material: Material | None = None, name: str = "") -> Primitive:
    """Convert a ``trimesh.Trimesh``: its normals if it has them (else smooth normals split at
    creases sharper than 30 degrees), UVs flipped to glTF's convention, and a material from its
    visual (PBR material, simple material colour or vertex colours) unless one is given."""
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise InputTypeError(f"add_mesh takes a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise InputError(f"mesh {name or mesh.metadata.get('name', '')!r} has no faces: nothing to render")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError(f"mesh {name!r} has NaN or Inf vertices")
    visual = mesh.visual
    uv = getattr(visual, "uv", None) if visual is not None and visual.kind == "texture" else None
    colors = _vertex_colors(mesh)
    if material is None:
        material = material_from_trimesh(visual)
    # Crease splitting duplicates vertices; per-vertex UVs and colours would not follow, so
    # meshes that carry them keep plain smooth normals.
    if not _has_supplied_normals(mesh) and uv is None and colors is None:
        mesh = trimesh.graph.smooth_shade(mesh, angle=_CREASE_ANGLE)
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
    uvs = None
    if uv is not None and len(uv) == len(mesh.vertices):
        uvs = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])
    return Primitive(mesh.vertices, mesh.faces, material, normals, uvs, None, colors, name)


def _vertex_colors(mesh):
    visual = mesh.visual
    if visual is None:
        return None
    if visual.kind == "vertex":
        rgba = np.asarray(visual.vertex_colors, dtype=np.float64) / 255.0
    elif visual.kind == "texture" and "color" in getattr(visual, "vertex_attributes", {}):
        rgba = np.asarray(visual.vertex_attributes["color"], dtype=np.float64)
        if rgba.max(initial=0.0) > 1.0:
            rgba = rgba / 255.0
        if rgba.shape[1] == 3:
            rgba = np.column_stack([rgba, np.ones(len(rgba))])
        return rgba  # glTF COLOR_0 is linear already
    else:
        return None
    if np.all(rgba == rgba[:1]):
        return None  # uniform colour: the material's base colour carries it
    rgba[:, :3] = srgb_to_linear(rgba[:, :3])  # 8-bit vertex colours are sRGB-encoded
    return rgba


def material_from_trimesh(visual) -> Material:
    """A Material from a trimesh visual: PBR materials map slot by slot, simple materials
    and uniform vertex/face colours become the base colour (decoded from sRGB)."""
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    if visual is None:
        return Material()
    if visual.kind == "vertex" or visual.kind == "face":
        colors = visual.vertex_colors if visual.kind == "vertex" else visual.face_colors
        first = np.asarray(colors[0], dtype=np.float64) / 255.0
        if np.all(colors == colors[:1]):
            return Material(base_color=tuple(srgb_to_linear(first[:3])))
        return Material(base_color=(1.0, 1.0, 1.0))  # vertex colours multiply it
    mat = getattr(visual, "material", None)
    if isinstance(mat, PBRMaterial):
        def factor(value, default):
            return default if value is None else value

        # trimesh keeps baseColorFactor as uint8 RGBA
        base = np.asarray(factor(mat.baseColorFactor, (255, 255, 255, 255)), dtype=np.float64) / 255.0
        return Material(
            base_color=tuple(base),
            metallic=float(np.clip(factor(mat.metallicFactor, 1.0), 0, 1)),
            roughness=float(np.clip(factor(mat.roughnessFactor, 1.0), 0, 1)),
            emissive=tuple(factor(mat.emissiveFactor, (0.0, 0.0, 0.0))),
            base_color_texture=mat.baseColorTexture,
            metallic_roughness_texture=mat.metallicRoughnessTexture,
            normal_texture=mat.normalTexture,
            occlusion_texture=mat.occlusionTexture,
            emissive_texture=mat.emissiveTexture,
            double_sided=bool(mat.doubleSided),
            name=mat.name or "",
        )
    if isinstance(mat, SimpleMaterial):
        diffuse = np.asarray(mat.diffuse, dtype=np.float64)[:3] / 255.0
        image = getattr(mat, "image", None)
        return Material(base_color=tuple(srgb_to_linear(diffuse)) if image is None else (1.0, 1.0, 1.0),
                        base_color_texture=image)
    return Material()
