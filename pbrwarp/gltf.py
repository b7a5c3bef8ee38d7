"""glTF 2.0 loading: trimesh for geometry and the scene graph, the file itself for the rest.

trimesh (5.2) reads triangles, node transforms and instancing well, but drops what a PBR
renderer needs: TANGENT, normalTexture.scale, occlusionTexture.strength, texCoord indices,
samplers, texture transforms, material extensions, lights and all cameras but the first. This
module reads those from the glTF JSON and binary buffers with a small accessor reader, and
matches each trimesh geometry to its glTF (mesh, primitive) so per-vertex data lines up.

Supported: .glb and .gltf (buffers and images embedded, as ``data:`` URIs or as files next to
the .gltf); accessors of every component type, normalized or not, interleaved (byteStride) and
sparse; triangle lists and strips; PNG/JPEG (any format Pillow decodes) textures; samplers' wrap
modes; KHR_texture_transform, KHR_materials_specular (specularFactor),
KHR_materials_emissive_strength, KHR_lights_punctual; perspective cameras.

Not supported: TEXCOORD_1 (textures that ask for it are sampled with TEXCOORD_0, with a
warning), sampler filters (pbrwarp picks its own), specular colour and specular/other extension
textures, light ``range``, orthographic cameras (skipped with a warning), skins, morph targets,
animations, points, lines and triangle fans, and any extension listed in ``extensionsRequired``
other than the ones above (an error, as glTF asks).
"""

from __future__ import annotations

import base64
import io
import json
import math
import os
import struct
import urllib.parse
import warnings
from dataclasses import dataclass, field

import numpy as np

from .camera import Camera
from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError, PbrwarpError
from .lights import DirectionalLight, PointLight, SpotLight
from .materials import Material
from .primitive import Primitive, primitive_from_trimesh, transform_primitive
from .tangents import generate_tangents
from .textures import Texture

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942
_COMPONENT_TYPES = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_INDEX_TYPES = (5121, 5123, 5125)
_TYPE_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_WRAP_MODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_TRIANGLES, _TRIANGLE_STRIP = 4, 5
_TRIMESH_MODES = (0, 1, 4, 5)  # primitive modes trimesh turns into geometry (and names)
_MODES = range(7)  # POINTS .. TRIANGLE_FAN
# An accessor without a bufferView is zeros (plus sparse edits) and costs no bytes in the file, so
# its count is the one size a small file can make arbitrarily large: capped, not allocated blindly.
_MAX_ZERO_FILLED_ELEMENTS = 1 << 26
_SUPPORTED_EXTENSIONS = frozenset({
    "KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_specular", "KHR_materials_emissive_strength",
})
# glTF's default material (spec 3.9.6): everything 1, single-sided.
_DEFAULT_MATERIAL = dict(base_color=(1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=1.0, double_sided=False)


@dataclass
class GltfContent:
    """Everything :func:`load_gltf` read: world-space primitives, lights and cameras."""

    primitives: list[Primitive] = field(default_factory=list)
    lights: list = field(default_factory=list)
    cameras: list[Camera] = field(default_factory=list)


def load_gltf(path) -> GltfContent:
    """Read a .glb or .gltf file into world-space primitives, punctual lights and cameras.

    Raises ``AssetNotFoundError`` when the file (or a buffer or image it references) is missing
    and ``AssetFormatError`` naming the file and the problem when it is corrupt or inconsistent.
    Warns (``warnings.warn``) about features it has to ignore.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise AssetNotFoundError(f"glTF file not found: {path}")
    try:
        content = _load(path)
    except PbrwarpError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        # A safety net for malformed JSON values (a string where a number belongs, ...) that
        # the specific checks do not anticipate.
        raise AssetFormatError(f"cannot load {path}: malformed glTF ({type(err).__name__}: {err})") from None
    if not content.primitives:
        raise AssetFormatError(f"cannot load {path}: its scene contains no triangle meshes")
    return content


def _load(path: str) -> GltfContent:
    import trimesh

    doc = _Document(path)
    # Read and check every accessor and node before trimesh sees the file, so that problems are
    # reported in glTF's terms rather than as trimesh's internal errors.
    data = _read_primitives(doc)
    nodes = list(_scene_nodes(doc))
    try:
        scene = trimesh.load(path, force="scene")
    except Exception as err:  # trimesh raises many types for files it cannot read
        raise doc.error(f"trimesh could not read it: {type(err).__name__}: {err}") from None
    content = GltfContent(primitives=_Builder(doc, data, _trimesh_geometry_names(doc)).primitives(scene))
    for node, world in nodes:
        content.lights.extend(_node_light(doc, node, world))
        content.cameras.extend(_node_camera(doc, node, world))
    return content


# ---------------------------------------------------------------------------- file and accessors
class _Document:
    """The glTF JSON plus lazily loaded buffers and images, with range-checked access."""

    def __init__(self, path: str):
        self.path = path
        self.base_dir = os.path.dirname(os.path.abspath(path))
        with open(path, "rb") as f:
            raw = f.read()
        if raw[:4] == _GLB_MAGIC:
            json_bytes, self.glb_bin = self._split_glb(raw)
        elif path.lower().endswith(".glb"):
            raise self.error(f"not a binary glTF: the file starts with {raw[:4]!r}, not b'glTF'")
        else:
            json_bytes, self.glb_bin = raw, None
        try:
            self.json = json.loads(json_bytes.decode("utf-8-sig"))
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise self.error(f"invalid JSON: {err}") from None
        except RecursionError:  # json's decoder recurses once per nesting level
            raise self.error("invalid JSON: nested too deeply") from None
        if not isinstance(self.json, dict):
            raise self.error("the JSON is not an object")
        self._check_header()
        self._buffers: dict[int, bytes] = {}
        self._images: dict[int, object] = {}

    def error(self, message: str) -> AssetFormatError:
        return AssetFormatError(f"cannot load {self.path}: {message}")

    def _split_glb(self, raw: bytes) -> tuple[bytes, bytes | None]:
        """(JSON chunk, BIN chunk or None) of a GLB, checking its header and chunk sizes."""
        if len(raw) < 20:
            raise self.error(f"truncated GLB: {len(raw)} bytes is shorter than a GLB header")
        _, version, length = struct.unpack_from("<4sII", raw, 0)
        if version != 2:
            raise self.error(f"GLB version {version}; only glTF 2.0 is supported")
        if length > len(raw):
            raise self.error(f"truncated GLB: the header says {length} bytes but the file has {len(raw)}")
        chunks, offset = [], 12
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, offset)
            if offset + 8 + size > length:
                raise self.error(f"truncated GLB: a chunk of {size} bytes at offset {offset} runs past the end")
            chunks.append((kind, raw[offset + 8: offset + 8 + size]))
            offset += 8 + size
        if not chunks or chunks[0][0] != _CHUNK_JSON:
            raise self.error("malformed GLB: the first chunk is not JSON")
        binary = next((data for kind, data in chunks[1:] if kind == _CHUNK_BIN), None)
        return chunks[0][1], binary

    def _check_header(self):
        version = str(self.json.get("asset", {}).get("version", ""))
        if not version.startswith("2"):
            raise self.error(f"asset.version is {version!r}; only glTF 2.0 is supported")
        missing = sorted(set(self.json.get("extensionsRequired", [])) - _SUPPORTED_EXTENSIONS)
        if missing:
            raise self.error(f"it requires extensions pbrwarp does not support: {', '.join(missing)}")

    def element(self, kind: str, index, what: str) -> dict:
        """``json[kind][index]``, an error naming ``what`` if the index is not valid."""
        items = self.json.get(kind, [])
        if not isinstance(items, list):
            raise self.error(f"{kind!r} must be an array, got {type(items).__name__}")
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise self.error(f"{what} refers to {kind}[{index!r}], but the file has {len(items)} {kind}")
        item = items[index]
        if not isinstance(item, dict):
            raise self.error(f"{kind}[{index}] is not an object")
        return item

    # -- bytes
    def buffer(self, index: int) -> bytes:
        if index not in self._buffers:
            spec = self.element("buffers", index, "a bufferView")
            if "uri" in spec:
                data = self._uri_bytes(spec["uri"], f"buffer {index}")
            elif self.glb_bin is not None:
                data = self.glb_bin
            else:
                raise self.error(f"buffer {index} has no uri and the file has no GLB binary chunk")
            if len(data) < spec["byteLength"]:
                raise self.error(f"buffer {index} has {len(data)} bytes but its byteLength is {spec['byteLength']}")
            self._buffers[index] = data
        return self._buffers[index]

    def _uri_bytes(self, uri: str, what: str) -> bytes:
        if uri.startswith("data:"):
            header, _, payload = uri.partition(",")
            try:
                if header.endswith(";base64"):
                    return base64.b64decode(payload, validate=True)
                return urllib.parse.unquote_to_bytes(payload)
            except ValueError as err:
                raise self.error(f"{what} has a malformed data: URI ({err})") from None
        if urllib.parse.urlparse(uri).scheme:
            raise self.error(f"{what} refers to {uri!r}; only relative file paths and data: URIs are supported")
        file = os.path.join(self.base_dir, urllib.parse.unquote(uri))
        if not os.path.isfile(file):
            raise AssetNotFoundError(f"cannot load {self.path}: {what} file not found: {file}")
        with open(file, "rb") as f:
            return f.read()

    def view_array(self, view_index, byte_offset, dtype, count, width, what, strided=True) -> np.ndarray:
        """``count`` x ``width`` values of ``dtype`` from a bufferView, every byte range checked."""
        view = self.element("bufferViews", view_index, what)
        buf = self.buffer(view["buffer"])
        start, length = view.get("byteOffset", 0), view["byteLength"]
        if start < 0 or length < 0 or start + length > len(buf):
            raise self.error(f"bufferView {view_index} spans bytes {start}..{start + length} of buffer "
                             f"{view['buffer']}, which has {len(buf)}")
        element = dtype.itemsize * width
        stride = (view.get("byteStride") if strided else None) or element
        if stride < element:
            raise self.error(f"bufferView {view_index} has byteStride {stride}, "
                             f"less than the {element}-byte elements of {what}")
        end = byte_offset + stride * (count - 1) + element if count else byte_offset
        if byte_offset < 0 or end > length:
            raise self.error(f"{what} reads bytes {byte_offset}..{end} of bufferView {view_index}, which has {length}")
        return np.ndarray((count, width), dtype, buffer=buf, offset=start + byte_offset,
                          strides=(stride, dtype.itemsize)).copy()

    def accessor(self, index, what, widths=(1, 2, 3, 4)) -> np.ndarray:
        """Accessor ``index`` as a (count, width) array: float64 if float or normalized, else
        the stored integer type. Sparse substitution is applied."""
        acc = self.element("accessors", index, what)
        what = f"accessor {index} ({what})"
        ctype, kind, count = acc.get("componentType"), acc.get("type"), acc.get("count")
        if ctype not in _COMPONENT_TYPES:
            raise self.error(f"{what} has unknown componentType {ctype!r}")
        width = _TYPE_WIDTHS.get(kind)
        if width not in widths:
            expected = " or ".join(k for k, w in _TYPE_WIDTHS.items() if w in widths)
            raise self.error(f"{what} has type {kind!r}; expected {expected}")
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise self.error(f"{what} has invalid count {count!r}")
        dtype = np.dtype(_COMPONENT_TYPES[ctype])
        if "bufferView" in acc:
            data = self.view_array(acc["bufferView"], acc.get("byteOffset", 0), dtype, count, width, what)
        elif count > _MAX_ZERO_FILLED_ELEMENTS:
            raise self.error(f"{what} has no bufferView and count {count}: more than the "
                             f"{_MAX_ZERO_FILLED_ELEMENTS} zero-filled elements pbrwarp allocates")
        else:
            data = np.zeros((count, width), dtype)
        if "sparse" in acc:
            self._apply_sparse(acc["sparse"], data, dtype, what)
        if acc.get("normalized", False) and dtype.kind in "iu":
            scale = float(np.iinfo(dtype).max)
            return np.maximum(data.astype(np.float64) / scale, -1.0)
        return data.astype(np.float64) if dtype.kind == "f" else data

    def _apply_sparse(self, sparse, data, dtype, what):
        count = sparse["count"]
        idx_spec, val_spec = sparse["indices"], sparse["values"]
        if idx_spec.get("componentType") not in _INDEX_TYPES:
            raise self.error(f"{what} has sparse indices of componentType {idx_spec.get('componentType')!r}")
        idx_dtype = np.dtype(_COMPONENT_TYPES[idx_spec["componentType"]])
        rows = self.view_array(idx_spec["bufferView"], idx_spec.get("byteOffset", 0), idx_dtype, count, 1,
                               f"sparse indices of {what}", strided=False).ravel()
        values = self.view_array(val_spec["bufferView"], val_spec.get("byteOffset", 0), dtype, count,
                                 data.shape[1], f"sparse values of {what}", strided=False)
        if count and int(rows.max()) >= len(data):
            raise self.error(f"{what} has sparse index {int(rows.max())}, but only {len(data)} elements")
        data[rows.astype(np.int64)] = values

    # -- images
    def image(self, index: int):
        """Decoded Pillow image ``index`` (cached: shared by every texture that uses it)."""
        if index not in self._images:
            from PIL import Image

            spec = self.element("images", index, "a texture")
            if "bufferView" in spec:
                view = self.element("bufferViews", spec["bufferView"], f"image {index}")
                raw = self.view_array(spec["bufferView"], 0, np.dtype("u1"), view["byteLength"], 1,
                                      f"image {index}", strided=False).tobytes()
            elif "uri" in spec:
                raw = self._uri_bytes(spec["uri"], f"image {index}")
            else:
                raise self.error(f"image {index} has neither a bufferView nor a uri")
            try:
                img = Image.open(io.BytesIO(raw))
                img.load()
            except Exception as err:  # Pillow raises several types for bad image data
                raise self.error(f"image {index} cannot be decoded: {type(err).__name__}: {err}") from None
            self._images[index] = img
        return self._images[index]


# ---------------------------------------------------------------------------- mesh primitives
@dataclass
class _PrimitiveData:
    """One glTF triangle primitive as read from the file (local space)."""

    key: tuple[int, int]
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    tangents: np.ndarray | None
    colors: np.ndarray | None
    material: int | None


def _read_primitives(doc: _Document) -> dict[tuple[int, int], _PrimitiveData]:
    """Every triangle primitive of every mesh, read and checked before trimesh sees the file."""
    out = {}
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            mode = prim.get("mode", _TRIANGLES)
            if isinstance(mode, bool) or not isinstance(mode, int) or mode not in _MODES:
                raise doc.error(f"mesh {mi} primitive {pi} has invalid mode {mode!r} (glTF modes are 0..6)")
            if mode in (_TRIANGLES, _TRIANGLE_STRIP):
                out[mi, pi] = _read_primitive(doc, (mi, pi), prim)
    return out


def _read_primitive(doc: _Document, key, prim) -> _PrimitiveData:
    where = f"mesh {key[0]} primitive {key[1]}"
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs:
        raise doc.error(f"{where} has no POSITION attribute")
    positions = doc.accessor(attrs["POSITION"], f"POSITION of {where}", (3,)).astype(np.float64)
    n = len(positions)
    bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
    if len(bad):
        raise doc.error(f"POSITION of {where} has NaN or Inf coordinates ({len(bad)} vertices, "
                        f"first {bad[:3].tolist()})")

    def attribute(name, widths):
        if name not in attrs:
            return None
        arr = doc.accessor(attrs[name], f"{name} of {where}", widths).astype(np.float64)
        if len(arr) != n:
            raise doc.error(f"{where} has {n} positions but {len(arr)} {name} values")
        return arr

    material = prim.get("material")
    if material is not None:
        doc.element("materials", material, where)
    colors = attribute("COLOR_0", (3, 4))
    if colors is not None and colors.shape[1] == 3:
        colors = np.column_stack([colors, np.ones(n)])
    return _PrimitiveData(
        key=key, positions=positions, faces=_primitive_faces(doc, prim, n, where),
        normals=attribute("NORMAL", (3,)), uvs=attribute("TEXCOORD_0", (2,)),
        tangents=attribute("TANGENT", (4,)), colors=colors, material=material,
    )


def _primitive_faces(doc: _Document, prim, n: int, where: str) -> np.ndarray:
    """(F, 3) vertex indices of a triangle list or strip, every index checked against ``n``."""
    if "indices" in prim:
        acc = doc.element("accessors", prim["indices"], f"indices of {where}")
        if acc.get("componentType") not in _INDEX_TYPES or acc.get("normalized", False):
            raise doc.error(f"indices of {where} must be unsigned integers, "
                            f"got componentType {acc.get('componentType')!r}")
        idx = doc.accessor(prim["indices"], f"indices of {where}", (1,)).astype(np.int64).ravel()
        if len(idx) and int(idx.max()) >= n:
            raise doc.error(f"{where} has vertex index {int(idx.max())}, but only {n} vertices")
    else:
        idx = np.arange(n, dtype=np.int64)
    if prim.get("mode", _TRIANGLES) == _TRIANGLE_STRIP:
        if len(idx) < 3:
            raise doc.error(f"triangle strip {where} has fewer than 3 indices")
        i = np.arange(len(idx) - 2)
        odd = i % 2  # glTF 3.7.2.1: triangle i is (i, i + 1 + odd, i + 2 - odd)
        return np.column_stack([idx[i], idx[i + 1 + odd], idx[i + 2 - odd]])
    if len(idx) % 3:
        raise doc.error(f"{where} has {len(idx)} indices, not a multiple of 3")
    return idx.reshape(-1, 3)


def _trimesh_geometry_names(doc: _Document) -> dict[str, tuple[int, int]]:
    """trimesh's geometry name for each (mesh, primitive), replicating its naming
    (``unique_name(mesh name or "GLTF")`` in mesh/primitive order; trimesh/exchange/gltf
    ``_read_buffers``). Only a guess: :meth:`_Builder._match` verifies it."""
    from trimesh.util import unique_name

    names, counts = {}, {}
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            name = unique_name(mesh.get("name", "GLTF"), names, counts=counts)
            if prim.get("mode", _TRIANGLES) in _TRIMESH_MODES:
                names[name] = (mi, pi)
    return names


def _same_triangles(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two face arrays list the same triangles in the same order and winding (each
    row may be rotated: trimesh writes the odd triangles of a strip as (i+2, i+1, i))."""
    if a.shape != b.shape:
        return False
    same = np.zeros(len(a), dtype=bool)
    for turn in range(3):
        same |= np.all(a == np.roll(b, turn, axis=1), axis=1)
    return bool(np.all(same))


class _Builder:
    """Turns trimesh's scene-graph instances into world-space Primitives with glTF data."""

    def __init__(self, doc: _Document, data: dict, names: dict):
        self.doc = doc
        self.data = data
        self.names = names
        self.materials = _Materials(doc)
        self._local: dict[str, Primitive] = {}

    def primitives(self, scene) -> list[Primitive]:
        import trimesh

        out, skipped, unplaced = [], 0, []
        for node in scene.graph.nodes_geometry:
            try:
                matrix, geometry_name = scene.graph[node]
            except ValueError:  # trimesh 5.2 leaves nodes below the first camera unconnected
                unplaced.append(str(node))
                continue
            geom = scene.geometry[geometry_name]
            if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
                skipped += 1
                continue
            local = self._local_primitive(geometry_name, geom)
            try:
                world = transform_primitive(local, matrix)
            except InputError as err:
                raise self.doc.error(f"node {node!r}: {err}") from None
            world.name = str(node)
            out.append(world)
        if skipped:
            warnings.warn(f"{self.doc.path}: {skipped} point or line primitive(s) ignored (pbrwarp renders triangles)")
        if unplaced:
            warnings.warn(f"{self.doc.path}: mesh node(s) {', '.join(unplaced)} left out: trimesh's scene graph has "
                          "no path to them (trimesh drops the first camera's node, and with it its children)")
        return out

    def _local_primitive(self, geometry_name: str, geom) -> Primitive:
        """The Primitive for one trimesh geometry in its mesh's space, shared by its instances."""
        if geometry_name not in self._local:
            data = self._match(geometry_name, geom)
            if data is None:
                warnings.warn(f"{self.doc.path}: geometry {geometry_name!r} matches no glTF primitive; "
                              "using trimesh's data without tangents, samplers or texture settings")
                self._local[geometry_name] = primitive_from_trimesh(geom, name=geometry_name)
            else:
                self._local[geometry_name] = self._from_data(data, geom, geometry_name)
        return self._local[geometry_name]

    def _match(self, geometry_name: str, geom) -> _PrimitiveData | None:
        """The glTF primitive trimesh built ``geom`` from: by name, verified by positions and
        faces; else the first primitive whose positions and faces are equal."""

        def same(data):
            return (data.positions.shape == geom.vertices.shape and np.array_equal(data.positions, geom.vertices)
                    and _same_triangles(data.faces, geom.faces))

        key = self.names.get(geometry_name)
        if key in self.data and same(self.data[key]):
            return self.data[key]
        return next((d for d in self.data.values() if same(d)), None)

    def _from_data(self, data: _PrimitiveData, geom, name: str) -> Primitive:
        if data.material is None:
            material = Material(**_DEFAULT_MATERIAL)
        else:
            material = self.materials.get(data.material, f"mesh {data.key[0]} primitive {data.key[1]}")
        normals = data.normals if data.normals is not None else np.zeros_like(data.positions)
        tangents = data.tangents
        if tangents is None and material.normal_texture is not None and data.uvs is not None:
            tangents = generate_tangents(data.positions, normals, data.uvs, geom.faces)
        try:
            return Primitive(data.positions, np.asarray(geom.faces), material, normals, data.uvs, tangents,
                             data.colors, name)
        except (InputError, InputTypeError) as err:
            raise self.doc.error(f"mesh {data.key[0]} primitive {data.key[1]}: {err}") from None


# ---------------------------------------------------------------------------- materials
class _Materials:
    """glTF materials as pbrwarp Materials, built on first use; textures shared where equal."""

    _SLOTS = (  # (glTF texture-info location, Material attribute)
        (("pbrMetallicRoughness", "baseColorTexture"), "base_color_texture"),
        (("pbrMetallicRoughness", "metallicRoughnessTexture"), "metallic_roughness_texture"),
        (("normalTexture",), "normal_texture"),
        (("occlusionTexture",), "occlusion_texture"),
        (("emissiveTexture",), "emissive_texture"),
    )

    def __init__(self, doc: _Document):
        self.doc = doc
        self._materials: dict[int, Material] = {}
        self._textures: dict[tuple, Texture] = {}

    def get(self, index, user: str) -> Material:
        if index not in self._materials:
            spec = self.doc.element("materials", index, user)
            label = f"material {index}" + (f" ({spec['name']!r})" if spec.get("name") else "")
            try:
                self._materials[index] = self._build(spec, label)
            except (InputError, InputTypeError) as err:
                raise self.doc.error(f"{label}: {err}") from None
        return self._materials[index]

    def _build(self, spec: dict, label: str) -> Material:
        pbr = spec.get("pbrMetallicRoughness", {})
        ext = spec.get("extensions", {})
        emissive_strength = ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        textures = {}
        for location, slot in self._SLOTS:
            info = spec
            for key in location:
                info = info.get(key, {})
            textures[slot] = self._texture(info, f"{label} {location[-1]}") if info else None
        return Material(
            base_color=tuple(pbr.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0))),
            metallic=pbr.get("metallicFactor", 1.0),
            roughness=pbr.get("roughnessFactor", 1.0),
            specular=ext.get("KHR_materials_specular", {}).get("specularFactor", 1.0),
            emissive=tuple(float(c) * emissive_strength for c in spec.get("emissiveFactor", (0.0, 0.0, 0.0))),
            normal_scale=spec.get("normalTexture", {}).get("scale", 1.0),
            occlusion_strength=spec.get("occlusionTexture", {}).get("strength", 1.0),
            double_sided=_boolean(spec.get("doubleSided", False), "doubleSided"),
            alpha_mode=spec.get("alphaMode", "OPAQUE"),
            alpha_cutoff=spec.get("alphaCutoff", 0.5),
            name=spec.get("name", ""),
            **textures,
        )

    def _texture(self, info: dict, label: str) -> Texture:
        """The Texture a textureInfo describes: image, sampler wrap modes, texture transform."""
        doc = self.doc
        tex = doc.element("textures", info.get("index"), label)
        transform = info.get("extensions", {}).get("KHR_texture_transform", {})
        tex_coord = transform.get("texCoord", info.get("texCoord", 0))
        if tex_coord != 0:
            warnings.warn(f"{doc.path}: {label} uses TEXCOORD_{tex_coord}; pbrwarp samples TEXCOORD_0 only")
        if "source" not in tex:
            raise doc.error(f"{label}: texture {info['index']} has no image source pbrwarp can decode")
        sampler = doc.element("samplers", tex["sampler"], label) if "sampler" in tex else {}
        wrap = []
        for key in ("wrapS", "wrapT"):
            code = sampler.get(key, 10497)
            if code not in _WRAP_MODES:
                raise doc.error(f"{label}: sampler {tex['sampler']} has invalid {key} {code!r}")
            wrap.append(_WRAP_MODES[code])
        offset = tuple(float(x) for x in transform.get("offset", (0.0, 0.0)))
        scale = tuple(float(x) for x in transform.get("scale", (1.0, 1.0)))
        rotation = float(transform.get("rotation", 0.0))
        key = (tex["source"], *wrap, offset, rotation, scale)
        if key not in self._textures:
            self._textures[key] = Texture(doc.image(tex["source"]), wrap_s=wrap[0], wrap_t=wrap[1],
                                          offset=offset, rotation=rotation, scale=scale)
        return self._textures[key]


def _boolean(value, what: str) -> bool:
    if not isinstance(value, bool):
        raise InputTypeError(f"{what} must be true or false, got {value!r}")
    return value


# ---------------------------------------------------------------------------- nodes, lights, cameras
def _scene_nodes(doc: _Document):
    """(node index, world matrix) for every node of the default scene, parents first."""
    scenes = doc.json.get("scenes", [])
    if not scenes:
        return
    scene = doc.element("scenes", doc.json.get("scene", 0), "the default scene")
    stack = [(root, np.eye(4), ()) for root in reversed(scene.get("nodes", []))]
    while stack:
        index, parent, ancestors = stack.pop()
        node = doc.element("nodes", index, f"scene graph (under nodes {list(ancestors)})")
        if index in ancestors:
            raise doc.error(f"node {index} is its own ancestor (a cycle in the node hierarchy)")
        if "mesh" in node:
            doc.element("meshes", node["mesh"], f"node {index}")
        world = parent @ _local_matrix(doc, node, index)
        yield index, world
        stack.extend((child, world, ancestors + (index,)) for child in reversed(node.get("children", [])))


def _local_matrix(doc: _Document, node: dict, index: int) -> np.ndarray:
    """A node's local 4x4 matrix: ``matrix`` (column-major) or translation * rotation * scale."""
    if "matrix" in node:
        m = _numbers(doc, node["matrix"], 16, f"node {index} matrix").reshape(4, 4).T
        return m
    t = _numbers(doc, node.get("translation", (0.0, 0.0, 0.0)), 3, f"node {index} translation")
    q = _numbers(doc, node.get("rotation", (0.0, 0.0, 0.0, 1.0)), 4, f"node {index} rotation")
    s = _numbers(doc, node.get("scale", (1.0, 1.0, 1.0)), 3, f"node {index} scale")
    largest = float(np.max(np.abs(q)))
    norm = largest * float(np.linalg.norm(q / largest)) if largest > 0.0 else 0.0  # no overflow in squares
    # glTF rotations are unit quaternions; slightly off ones are normalized, but trimesh (which places
    # the meshes) turns lengths below ~1e-8 or above ~1e154 into the identity, so those are refused
    # rather than leaving meshes unrotated while lights and cameras turn.
    if not 1e-6 <= norm <= 1e6:
        raise doc.error(f"node {index} rotation {q.tolist()} has length {norm:.3g}; glTF rotations are unit quaternions")
    x, y, z, w = (float(c) for c in q / norm)
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    m = np.eye(4)
    m[:3, :3] = rotation * s[None, :]
    m[:3, 3] = t
    return m


def _numbers(doc: _Document, value, count: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise doc.error(f"{what} must be {count} numbers, got {value!r}") from None
    if arr.shape != (count,) or not np.all(np.isfinite(arr)):
        raise doc.error(f"{what} must be {count} finite numbers, got {value!r}")
    return arr


def _node_light(doc: _Document, index: int, world: np.ndarray) -> list:
    """The KHR_lights_punctual light on node ``index``, placed by its world matrix (lights shine
    down the node's -Z). Light ``range`` is ignored: pbrwarp lights follow the inverse square law."""
    ref = doc.element("nodes", index, "scene").get("extensions", {}).get("KHR_lights_punctual")
    if ref is None:
        return []
    lights = doc.json.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    light_index = ref.get("light")
    if isinstance(light_index, bool) or not isinstance(light_index, int) or not 0 <= light_index < len(lights):
        raise doc.error(f"node {index} refers to light {light_index!r}, but the file defines {len(lights)} lights")
    spec = lights[light_index]
    color = tuple(spec.get("color", (1.0, 1.0, 1.0)))
    intensity = spec.get("intensity", 1.0)
    position = tuple(world[:3, 3])
    direction = tuple(-world[:3, 2])
    kind = spec.get("type")
    try:
        if kind == "point":
            return [PointLight(position=position, color=color, intensity=intensity)]
        if kind == "directional":
            return [DirectionalLight(direction=direction, color=color, intensity=intensity)]
        if kind == "spot":
            cone = spec.get("spot", {})
            return [SpotLight(position=position, direction=direction, color=color, intensity=intensity,
                              inner_cone=cone.get("innerConeAngle", 0.0),
                              outer_cone=cone.get("outerConeAngle", math.pi / 4.0))]
    except (InputError, InputTypeError) as err:
        raise doc.error(f"light {light_index} (on node {index}): {err}") from None
    raise doc.error(f"light {light_index} has unknown type {kind!r} (expected point, spot or directional)")


def _node_camera(doc: _Document, index: int, world: np.ndarray) -> list[Camera]:
    """The perspective camera on node ``index`` (looking down its -Z), if any."""
    node = doc.element("nodes", index, "scene")
    if "camera" not in node:
        return []
    spec = doc.element("cameras", node["camera"], f"node {index}")
    if spec.get("type") != "perspective":
        warnings.warn(f"{doc.path}: camera {node['camera']} is {spec.get('type')!r}; only perspective cameras are read")
        return []
    yfov = spec.get("perspective", {}).get("yfov")
    try:
        return [Camera.from_matrix(world, math.degrees(float(yfov)))]
    except (InputError, InputTypeError, TypeError, ValueError) as err:
        raise doc.error(f"camera {node['camera']} (on node {index}): {err}") from None
