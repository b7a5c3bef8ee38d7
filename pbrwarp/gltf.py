"""glTF 2.0 loading: the file's meshes, materials, node graph, lights and cameras.

pbrwarp reads glTF itself, with a small accessor reader over the JSON and binary buffers,
because what a PBR renderer needs (TANGENT, normalTexture.scale, occlusionTexture.strength,
texCoord indices, samplers, texture transforms, material extensions, lights, every camera) is
what general mesh libraries drop, and because it walks the node graph once, with its own limits,
where a general scene graph does not bound its work (docs/loading.md).

Supported: .glb and .gltf (buffers and images embedded, as ``data:`` URIs or as files inside the
model's folder); accessors of every component type, normalized or not, interleaved (byteStride)
and sparse, with KHR_mesh_quantization's integer attributes; triangle lists, strips and fans;
morph targets at their default weights (POSITION, NORMAL and TANGENT); skins posed by the node
graph's own transforms (the pose a viewer shows before any animation plays);
EXT_mesh_gpu_instancing, whose instances are expanded into copies; KHR_draco_mesh_compression,
decoded by DracoPy (the ``draco`` extra; pbrwarp/gltf_draco.py); PNG and JPEG textures (and
WebP, GIF, BMP, TGA), and KTX2 (KHR_texture_basisu) decoded by opengl-basisu (the ``ktx2`` extra;
pbrwarp/gltf_basisu.py); samplers' wrap modes and LINEAR filtering; metallic-roughness materials
with alphaMode OPAQUE, MASK and BLEND; KHR_texture_transform, KHR_materials_specular,
KHR_materials_ior, KHR_materials_emissive_strength, KHR_materials_unlit, KHR_materials_clearcoat,
KHR_materials_sheen, KHR_materials_anisotropy, KHR_materials_iridescence,
KHR_materials_transmission (but the blur of rough surfaces on what is seen through them),
KHR_materials_volume, KHR_lights_punctual (with ``range``), KHR_node_visibility; perspective
cameras.

Everything else a file asks for is named in a warning at load, once per kind
("KHR_materials_transmission on 3 materials ('glass', ...) ignored: rendered opaque"), saying what is rendered instead,
and kept in ``GltfContent.load_warnings`` (``Scene.load_warnings``, listed by ``pw.explain``): the
extensions ``_EXTENSIONS`` marks IGNORED and unknown ones, TEXCOORD_2 and above (sampled as
TEXCOORD_0), morph targets of TEXCOORD_n and COLOR_n, NEAREST magnification, rough transmissive
materials (by default only the environment seen through them is blurred), animations (the nodes'
stored static pose is shown), points and lines (skipped), cameras other than perspective
(skipped) and scenes other than the default.
pbrwarp/gltf_notes.py makes the notes (the reader adds the ones it can only make where it reads:
TEXCOORD_n, camera types, morph target attributes). An IGNORED extension listed in
``extensionsRequired`` is an error, as glTF asks.
"""

from __future__ import annotations

import base64
import json
import math
import os
import struct
import urllib.parse
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from . import validate
from .camera import Camera
from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError, PbrwarpError
from .gltf_basisu import decode_ktx2, is_ktx2, ktx2_size, texture_source
from .gltf_draco import decode_primitive
from .gltf_notes import _SUPPORTED_EXTENSIONS, _Notes, _ident, _note_unhonoured
from .lights import DirectionalLight, PointLight, SpotLight
from .load_limits import LoadLimits
from .materials import Material
from .primitive import Primitive, transform_primitive, unit_rows
from .tangents import frame_uv_set, generate_tangents
from .textures import Texture, decode_rgba, open_image

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942
_COMPONENT_TYPES = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_INDEX_TYPES = (5121, 5123, 5125)
_TYPE_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}  # the accessor types pbrwarp reads
_TYPE_COMPONENTS = {**_TYPE_WIDTHS, "MAT2": 4, "MAT3": 9, "MAT4": 16}  # every type, e.g. skins' MAT4
_READ_WIDTHS = {**_TYPE_WIDTHS, "MAT4": 16}  # MAT4 for skins' float inverse bind matrices (no padding)
_MORPHED = ("POSITION", "NORMAL", "TANGENT")  # the morph target attributes pbrwarp applies
_INSTANCING = "EXT_mesh_gpu_instancing"
_SKIN_CHUNK = 1 << 16  # vertices skinned at once: bounds the (chunk, 4, 4) blended matrices
_WRAP_MODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_TRIANGLES, _TRIANGLE_STRIP, _TRIANGLE_FAN = 4, 5, 6
_TRIANGLE_MODES = (_TRIANGLES, _TRIANGLE_STRIP, _TRIANGLE_FAN)
_MODES = range(7)  # POINTS .. TRIANGLE_FAN
# glTF's default material (spec 3.9.6): everything 1, single-sided.
_DEFAULT_MATERIAL = dict(base_color=(1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=1.0, double_sided=False)


@dataclass
class GltfContent:
    """Everything :func:`load_gltf` read: world-space primitives, lights and cameras, and
    ``load_warnings``: one message per kind of thing in the file that pbrwarp does not honour
    (the warnings the load issued, in order)."""

    primitives: list[Primitive] = field(default_factory=list)
    lights: list = field(default_factory=list)
    cameras: list[Camera] = field(default_factory=list)
    load_warnings: tuple[str, ...] = ()


def load_gltf(path, *, allowed_roots=None, limits: LoadLimits | None = None) -> GltfContent:
    """Read a .glb or .gltf file into world-space primitives, punctual lights and cameras.

    ``allowed_roots``: folders besides the model's own that its buffer and image URIs may name
    (default: none). Every URI other than ``data:`` must resolve, after percent-decoding and
    following ``..`` and symbolic links, to a file inside the model's folder or one of these;
    anything else is refused before any file is opened. ``limits``: the :class:`LoadLimits` the
    file's images, accessors and node graph are checked against before anything is decoded or
    allocated (default: ``LoadLimits()``). docs/loading.md describes both.

    Raises ``AssetNotFoundError`` when the file (or a buffer or image it references) is missing
    and ``AssetFormatError`` naming the file and the problem when it is corrupt, inconsistent,
    refers outside its folder or exceeds a limit. Warns (``warnings.warn``, a ``UserWarning``)
    once for each kind of thing in the file it does not honour -- an extension it ignores, a
    property it skips, an animation -- naming the file, what is affected and what is rendered
    instead; the messages are kept in ``GltfContent.load_warnings``. docs/loading.md tables what
    is honoured.
    """
    path = os.fspath(path)
    roots = validate.allowed_roots(allowed_roots)
    limits = LoadLimits.of(limits)
    if not os.path.isfile(path):
        raise AssetNotFoundError(f"glTF file not found: {path}")
    try:
        content = _load(path, roots, limits)
    except PbrwarpError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        # A safety net for malformed JSON values (a string where a number belongs, ...) that
        # the specific checks do not anticipate.
        raise AssetFormatError(f"cannot load {path}: malformed glTF ({type(err).__name__}: {err})") from None
    for message in content.load_warnings:
        warnings.warn(message, stacklevel=2)
    if not content.primitives:
        raise AssetFormatError(f"cannot load {path}: its scene contains no triangle meshes")
    return content


def _load(path: str, roots: tuple[str, ...], limits: LoadLimits) -> GltfContent:
    doc = _Document(path, roots, limits)
    # Every size is checked from the JSON before anything is read or allocated: accessor counts
    # against the bytes behind them, the node graph's depth and the instances it places.
    doc.check_accessor_sizes()
    nodes, hidden = _scene_nodes(doc)
    shown = [(node, world) for node, world in nodes if node not in hidden]
    _check_instancing(doc, shown)
    _note_unhonoured(doc, nodes)
    content = GltfContent(primitives=_Builder(doc, _read_primitives(doc)).primitives(shown, dict(nodes)))
    for node, world in nodes:
        if node not in hidden:
            content.lights.extend(_node_light(doc, node, world))
        content.cameras.extend(_node_camera(doc, node, world))  # KHR_node_visibility leaves cameras
    content.load_warnings = doc.notes.messages()
    return content


# ---------------------------------------------------------------------------- file and accessors
class _Document:
    """The glTF JSON plus lazily loaded buffers and images, with range-checked access."""

    def __init__(self, path: str, roots: tuple[str, ...] = (), limits: LoadLimits | None = None):
        self.path = path
        self.base_dir = os.path.dirname(os.path.abspath(path))
        self.roots = roots
        self.limits = LoadLimits.of(limits)
        self._texels = 0  # texels of the images decoded so far
        self._pose_values = 0  # vertex values read to pose meshes so far (charge_pose_read)
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
        self.notes = _Notes(path)  # what the file asks for that pbrwarp does not honour
        self._buffers: dict[int, bytes] = {}
        self._images: dict[int, object] = {}
        # accessor -> its data decoded from a KHR_draco_mesh_compression primitive (gltf_draco)
        self.decoded: dict[int, np.ndarray] = {}

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
            length = spec.get("byteLength")
            if isinstance(length, bool) or not isinstance(length, int) or length < 0:
                raise self.error(f"buffer {index} has invalid byteLength {length!r}")
            if "uri" in spec:
                data = self._uri_bytes(spec["uri"], f"buffer {index}", max_bytes=length)
            elif self.glb_bin is not None:
                data = self.glb_bin
            else:
                raise self.error(f"buffer {index} has no uri and the file has no GLB binary chunk")
            if len(data) < length:
                raise self.error(f"buffer {index} has {len(data)} bytes but its byteLength is {length}")
            self._buffers[index] = data
        return self._buffers[index]

    def _uri_bytes(self, uri: str, what: str, max_bytes: int | None = None) -> bytes:
        """The bytes a buffer's or image's URI names: a data: URI's payload (no larger than the
        JSON that holds it), or a file inside the model's folder (validate.confined_path)."""
        if isinstance(uri, str) and uri[:5].lower() == "data:":
            header, _, payload = uri.partition(",")
            try:
                if header.lower().endswith(";base64"):
                    return base64.b64decode(payload, validate=True)
                return urllib.parse.unquote_to_bytes(payload)
            except ValueError as err:
                raise self.error(f"{what} has a malformed data: URI ({err})") from None
        real = validate.confined_path(uri, self.base_dir, self.roots, what, self.path)
        return validate.read_confined(real, what, self.path, max_bytes)

    def _view_span(self, view_index, byte_offset, element: int, count: int, what, strided=True) -> tuple:
        """(bufferView, first byte in its buffer, stride) of ``count`` elements of ``element``
        bytes at ``byte_offset`` in a bufferView, checked against the view's and its buffer's
        declared lengths from the JSON alone (nothing is read)."""
        view = self.element("bufferViews", view_index, what)
        buffer = self.element("buffers", view.get("buffer"), f"bufferView {view_index}")
        start, length = view.get("byteOffset", 0), view.get("byteLength")
        stride = (view.get("byteStride") if strided else None) or element
        for name, value in (("byteOffset", start), ("byteLength", length), ("byteStride", stride)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise self.error(f"bufferView {view_index} has invalid {name} {value!r}")
        if isinstance(byte_offset, bool) or not isinstance(byte_offset, int):
            raise self.error(f"{what} has invalid byteOffset {byte_offset!r}")
        buffer_length = buffer.get("byteLength")
        if isinstance(buffer_length, int) and start + length > buffer_length:
            raise self.error(f"bufferView {view_index} spans bytes {start}..{start + length} of buffer "
                             f"{view['buffer']}, which has {buffer_length}")
        if stride < element:
            raise self.error(f"bufferView {view_index} has byteStride {stride}, "
                             f"less than the {element}-byte elements of {what}")
        end = byte_offset + stride * (count - 1) + element if count else byte_offset
        if byte_offset < 0 or end > length:
            raise self.error(f"{what} reads bytes {byte_offset}..{end} of bufferView {view_index}, which has {length}")
        return view, start + byte_offset, stride

    def view_array(self, view_index, byte_offset, dtype, count, width, what, strided=True) -> np.ndarray:
        """``count`` x ``width`` values of ``dtype`` from a bufferView, every byte range checked."""
        view, first, stride = self._view_span(view_index, byte_offset, dtype.itemsize * width, count, what, strided)
        buf = self.buffer(view["buffer"])  # at least the buffer's byteLength, which holds the view
        return np.ndarray((count, width), dtype, buffer=buf, offset=first, strides=(stride, dtype.itemsize)).copy()

    def check_accessor_sizes(self):
        """Every accessor's count checked against the bytes behind it, from the JSON alone, before
        anything is allocated: an accessor with a
        bufferView must fit inside it, so it is no larger than the file; one without is zeros
        that cost nothing in the file, and may hold at most ``limits.max_vertices`` elements."""
        accessors = self.json.get("accessors", [])
        if not isinstance(accessors, list):
            raise self.error(f"'accessors' must be an array, got {type(accessors).__name__}")
        users = _accessor_users(self.json)
        for index, acc in enumerate(accessors):
            what = f"accessor {index}" + (f" ({users[index]})" if index in users else "")
            if not isinstance(acc, dict):
                raise self.error(f"{what} is not an object")
            ctype, kind, count = acc.get("componentType"), acc.get("type"), acc.get("count")
            if ctype not in _COMPONENT_TYPES:
                raise self.error(f"{what} has unknown componentType {ctype!r}")
            if kind not in _TYPE_COMPONENTS:
                raise self.error(f"{what} has unknown type {kind!r}")
            if isinstance(count, bool) or not isinstance(count, int) or count < 0:
                raise self.error(f"{what} has invalid count {count!r}")
            element = np.dtype(_COMPONENT_TYPES[ctype]).itemsize * _TYPE_COMPONENTS[kind]
            if "bufferView" in acc:
                self._view_span(acc["bufferView"], acc.get("byteOffset", 0), element, count, what)
            elif count > self.limits.max_vertices:
                raise self.error(f"{what} has no bufferView and count {count}: it would allocate {count} zero "
                                 f"elements, more than the {self.limits.max_vertices} of LoadLimits.max_vertices")

    def accessor_layout(self, index: int) -> tuple[np.dtype, int]:
        """(component dtype, components per element) of accessor ``index``, whose componentType
        and type check_accessor_sizes has checked."""
        acc = self.json["accessors"][index]
        return np.dtype(_COMPONENT_TYPES[acc["componentType"]]), _TYPE_COMPONENTS[acc["type"]]

    def charge_pose_read(self, accessor: int, what: str, per_element: int = 1):
        """Count the elements of ``accessor`` (morph displacements, skin joints, weights and
        matrices) against ``LoadLimits.max_vertices`` before it is read to pose a mesh. Many targets,
        influence sets or nodes may name one accessor, so these reads are not bounded by the file's
        size as the mesh data itself is; this bounds them."""
        self._pose_values += self.json["accessors"][accessor]["count"] * per_element
        if self._pose_values > self.limits.max_vertices:
            raise self.error(f"posing its meshes (morph targets, skins) reads more than the "
                             f"{self.limits.max_vertices} vertex values of LoadLimits.max_vertices; the limit is "
                             f"passed at {what}")

    def accessor(self, index, what, widths=(1, 2, 3, 4)) -> np.ndarray:
        """Accessor ``index`` as a (count, width) array: float64 if float or normalized, else
        the stored integer type; the data decoded for it from a Draco-compressed primitive
        (``decoded``) where there is some. Sparse substitution is applied. Its count has been
        checked by :meth:`check_accessor_sizes`."""
        acc = self.element("accessors", index, what)
        what = f"accessor {index} ({what})"
        ctype, kind, count = acc.get("componentType"), acc.get("type"), acc.get("count")
        width = _READ_WIDTHS.get(kind)
        if width not in widths:
            expected = " or ".join(k for k, w in _READ_WIDTHS.items() if w in widths)
            raise self.error(f"{what} has type {kind!r}; expected {expected}")
        dtype = np.dtype(_COMPONENT_TYPES[ctype])
        if index in self.decoded:
            data = self.decoded[index].copy()
        elif "bufferView" in acc:
            data = self.view_array(acc["bufferView"], acc.get("byteOffset", 0), dtype, count, width, what)
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
    def image(self, index: int) -> np.ndarray:
        """Image ``index`` decoded to a read-only (H, W, 4) array, uint8 for 8-bit images (cached:
        shared by every texture that uses it). Its size is read from its header and checked
        against LoadLimits before it is decoded."""
        if index not in self._images:
            spec = self.element("images", index, "a texture")
            what = f"image {index}"
            if "bufferView" in spec:
                view = self.element("bufferViews", spec["bufferView"], what)
                raw = self.view_array(spec["bufferView"], 0, np.dtype("u1"), view.get("byteLength"), 1, what,
                                      strided=False).tobytes()
            elif "uri" in spec:
                raw = self._uri_bytes(spec["uri"], what)
            else:
                raise self.error(f"{what} has neither a bufferView nor a uri")
            try:
                if is_ktx2(raw):  # KHR_texture_basisu (gltf_basisu)
                    size = ktx2_size(raw, what, self.limits.max_texture_side)
                    self._charge_texels(size, what)
                    self._images[index] = decode_ktx2(raw, what, size)
                else:
                    header = open_image(raw, what, self.limits.max_texture_side)
                    try:
                        self._charge_texels(header.size, what)
                    except InputError:
                        header.close()
                        raise
                    self._images[index] = decode_rgba(header, what)
            except InputError as err:
                raise self.error(str(err)) from None
        return self._images[index]

    def _charge_texels(self, size: tuple[int, int], what: str):
        """Count an image of ``size`` (width, height) against LoadLimits.max_texels before it is decoded."""
        width, height = size
        if self._texels + width * height > self.limits.max_texels:
            raise InputError(f"{what} ({width} x {height}) would bring the file's decoded texels to "
                             f"{self._texels + width * height}, more than the {self.limits.max_texels} "
                             "of LoadLimits.max_texels")
        self._texels += width * height


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
    targets: list = field(default_factory=list)  # the primitive's morph targets, as in the JSON
    uvs1: np.ndarray | None = None  # TEXCOORD_1

    @property
    def where(self) -> str:
        """The primitive, for messages: "mesh M primitive P"."""
        return f"mesh {self.key[0]} primitive {self.key[1]}"


def _accessor_users(gltf: dict) -> dict[int, str]:
    """What uses each accessor a mesh primitive refers to ("POSITION of mesh 0 primitive 1"), for
    messages about accessors; the first user where several share one."""
    users = {}
    meshes = gltf.get("meshes", [])
    for mi, mesh in enumerate(meshes if isinstance(meshes, list) else []):
        prims = mesh.get("primitives", []) if isinstance(mesh, dict) else []
        for pi, prim in enumerate(prims if isinstance(prims, list) else []):
            if not isinstance(prim, dict):
                continue
            attrs = prim.get("attributes", {})
            refs = [(name, acc) for name, acc in attrs.items()] if isinstance(attrs, dict) else []
            for name, acc in refs + [("indices", prim.get("indices"))]:
                if isinstance(acc, int) and not isinstance(acc, bool):
                    users.setdefault(acc, f"{name} of mesh {mi} primitive {pi}")
    return users


def _primitive_mode(doc: _Document, prim, where: str) -> int:
    mode = prim.get("mode", _TRIANGLES)
    if isinstance(mode, bool) or not isinstance(mode, int) or mode not in _MODES:
        raise doc.error(f"{where} has invalid mode {mode!r} (glTF modes are 0..6)")
    return mode


def _primitive_size(doc: _Document, prim, where: str) -> tuple[int, int]:
    """(vertices, triangles) of a triangle list, strip or fan primitive, from its accessors' counts
    (checked by _Document.check_accessor_sizes) before any of its data is read."""
    attrs = prim.get("attributes", {})
    if "POSITION" not in attrs:
        raise doc.error(f"{where} has no POSITION attribute")
    vertices = doc.element("accessors", attrs["POSITION"], f"POSITION of {where}")["count"]
    indices = vertices
    if "indices" in prim:
        indices = doc.element("accessors", prim["indices"], f"indices of {where}")["count"]
    if _primitive_mode(doc, prim, where) in (_TRIANGLE_STRIP, _TRIANGLE_FAN):
        return vertices, max(indices - 2, 0)
    return vertices, indices // 3


def _read_primitives(doc: _Document) -> dict[tuple[int, int], _PrimitiveData]:
    """Every triangle primitive of every mesh, read and checked."""
    out = {}
    for mi, mesh in enumerate(doc.json.get("meshes", [])):
        for pi, prim in enumerate(mesh.get("primitives", [])):
            if _primitive_mode(doc, prim, f"mesh {mi} primitive {pi}") in _TRIANGLE_MODES:
                decode_primitive(doc, (mi, pi), prim)
                out[mi, pi] = _read_primitive(doc, (mi, pi), prim)
    return out


def _read_primitive(doc: _Document, key, prim) -> _PrimitiveData:
    where = f"mesh {key[0]} primitive {key[1]}"
    n, triangles = _primitive_size(doc, prim, where)
    limits = doc.limits
    if n > limits.max_vertices or triangles > limits.max_triangles:
        raise doc.error(f"{where} has {n} vertices and {triangles} triangles, more than LoadLimits allows "
                        f"({limits.max_vertices} vertices, {limits.max_triangles} triangles)")
    attrs = prim.get("attributes", {})
    for name in ("NORMAL", "TEXCOORD_0", "TEXCOORD_1", "TANGENT", "COLOR_0"):
        if name in attrs:
            count = doc.element("accessors", attrs[name], f"{name} of {where}")["count"]
            if count != n:
                raise doc.error(f"{where} has {n} positions but {count} {name} values")
    positions = doc.accessor(attrs["POSITION"], f"POSITION of {where}", (3,)).astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
    if len(bad):
        raise doc.error(f"POSITION of {where} has NaN or Inf coordinates ({len(bad)} vertices, "
                        f"first {bad[:3].tolist()})")

    def attribute(name, widths):
        if name not in attrs:
            return None
        return doc.accessor(attrs[name], f"{name} of {where}", widths).astype(np.float64)

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
        targets=_morph_targets(doc, prim, n, where), uvs1=attribute("TEXCOORD_1", (2,)),
    )


def _primitive_faces(doc: _Document, prim, n: int, where: str) -> np.ndarray:
    """(F, 3) vertex indices of a triangle list, strip or fan, every index checked against ``n``.
    A fan of fewer than 3 vertices has no triangles."""
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
    if prim.get("mode", _TRIANGLES) == _TRIANGLE_FAN:
        i = np.arange(max(len(idx) - 2, 0))  # glTF 3.7.2.1: triangle i is (i + 1, i + 2, 0)
        return np.column_stack([idx[i + 1], idx[i + 2], np.full(len(i), idx[0] if len(idx) else 0)])
    if len(idx) % 3:
        raise doc.error(f"{where} has {len(idx)} indices, not a multiple of 3")
    return idx.reshape(-1, 3)


# ---------------------------------------------------------------------------- morph targets, skins, instancing
def _morph_targets(doc: _Document, prim, n: int, where: str) -> list[dict]:
    """A primitive's morph targets (glTF 2.0 "Morph Targets"), each the accessors of the POSITION,
    NORMAL and TANGENT displacements it holds, checked against the primitive's attributes and
    vertex count; they are read only when a weight applies them (_morphed). Other displaced
    attributes (TEXCOORD_n, COLOR_n) are noted (doc.notes)."""
    targets = prim.get("targets", [])
    if not isinstance(targets, list):
        raise doc.error(f"{where} targets must be an array, got {targets!r}")
    attrs = prim.get("attributes", {})
    out, ignored = [], set()
    for ti, target in enumerate(targets):
        if not isinstance(target, dict):
            raise doc.error(f"{where} morph target {ti} is not an object")
        for name, acc in target.items():
            if name not in _MORPHED:
                ignored.add(name)
                continue
            what = f"{name} of {where} morph target {ti}"
            if name not in attrs:
                raise doc.error(f"{what} displaces an attribute the primitive does not have")
            count = doc.element("accessors", acc, what)["count"]
            if count != n:
                raise doc.error(f"{where} has {n} positions but {count} displacements in {what}")
        out.append({name: acc for name, acc in target.items() if name in _MORPHED})
    for name in sorted(ignored):
        doc.notes.add(f"morph targets of {name}", f"morph targets of {name} ignored: pbrwarp applies POSITION, "
                      "NORMAL and TANGENT displacements only")
    return out


def _morph_weights(doc: _Document, node: dict, index: int, data: _PrimitiveData) -> tuple[float, ...]:
    """The default weights of a primitive's morph targets on node ``index``: ``node.weights``,
    else ``mesh.weights``, else zeros (glTF 2.0 "Morph Targets"); one per target."""
    mesh = doc.json["meshes"][node["mesh"]]
    source = f"node {index}" if "weights" in node else f"mesh {node['mesh']}"
    weights = node.get("weights", mesh.get("weights"))
    if weights is None:
        return (0.0,) * len(data.targets)
    where = data.where
    if not isinstance(weights, list) or len(weights) != len(data.targets):
        count = len(weights) if isinstance(weights, list) else weights
        raise doc.error(f"{source} has {count} morph weights, but {where} has {len(data.targets)} morph "
                        "targets (glTF asks for one weight per target)")
    return tuple(float(w) for w in _numbers(doc, weights, len(weights), f"{source} weights"))


def _morphed(doc: _Document, data: _PrimitiveData, weights: tuple) -> _PrimitiveData:
    """``data`` with its morph targets applied at ``weights``: attribute + sum of weight x
    displacement, normals and tangent directions renormalized (tangents keep their handedness)."""
    where = data.where
    if all(w == 0.0 for w in weights):
        return data
    morphed = {"POSITION": data.positions, "NORMAL": data.normals,
               "TANGENT": None if data.tangents is None else data.tangents[:, :3]}
    for ti, (weight, target) in enumerate(zip(weights, data.targets)):
        if weight == 0.0:
            continue
        for name, acc in target.items():
            what = f"{name} of {where} morph target {ti}"
            doc.charge_pose_read(acc, what)
            delta = doc.accessor(acc, what, (3,)).astype(np.float64)
            if not np.all(np.isfinite(delta)):
                raise doc.error(f"{what} has NaN or Inf displacements")
            morphed[name] = morphed[name] + weight * delta
    normals = None if data.normals is None else unit_rows(morphed["NORMAL"])
    tangents = None
    if data.tangents is not None:
        tangents = np.column_stack([unit_rows(morphed["TANGENT"]), data.tangents[:, 3]])
    return replace(data, positions=morphed["POSITION"], normals=normals, tangents=tangents)


def _joint_matrices(doc: _Document, node: dict, index: int, worlds: dict) -> np.ndarray:
    """(J, 4, 4) joint matrices of node ``index``'s skin: world(joint) x inverseBindMatrix
    (identity when the skin has none), glTF 2.0 "Skins"."""
    skin_index = node["skin"]
    skin = doc.element("skins", skin_index, f"node {index}")
    joints = skin.get("joints")
    if not isinstance(joints, list) or not joints:
        raise doc.error(f"skin {skin_index} has no joints (a non-empty array of node indices is required)")
    for joint in joints:
        doc.element("nodes", joint, f"skin {skin_index} joints")
        if joint not in worlds:
            raise doc.error(f"skin {skin_index} joint node {joint} is not in the scene being loaded; glTF asks "
                            "for a skin's joints in the scene of the node it skins")
    posed = np.stack([worlds[joint] for joint in joints])
    if "inverseBindMatrices" not in skin:
        return posed
    what = f"inverseBindMatrices of skin {skin_index}"
    acc = doc.element("accessors", skin["inverseBindMatrices"], what)
    if acc.get("componentType") != 5126 or acc["count"] < len(joints):
        raise doc.error(f"{what} must be {len(joints)} or more float MAT4 matrices, got {acc['count']} of "
                        f"componentType {acc.get('componentType')!r}")
    doc.charge_pose_read(skin["inverseBindMatrices"], what, per_element=4)  # a MAT4 holds four VEC4s
    inverse_bind = doc.accessor(skin["inverseBindMatrices"], what, (16,))[:len(joints)]
    if not np.all(np.isfinite(inverse_bind)):
        raise doc.error(f"{what} has NaN or Inf entries")
    return posed @ inverse_bind.reshape(-1, 4, 4).transpose(0, 2, 1)  # glTF matrices are column-major


def _skin_influences(doc: _Document, prim: dict, n: int, joints: int, where: str) -> list:
    """(joint indices, weights) of each JOINTS_k / WEIGHTS_k pair of a skinned primitive, each
    (n, 4), the indices checked against the skin's ``joints`` joints."""
    attrs = prim.get("attributes", {})
    sets, k = [], 0
    while f"JOINTS_{k}" in attrs or f"WEIGHTS_{k}" in attrs:
        names = (f"JOINTS_{k}", f"WEIGHTS_{k}")
        if not all(name in attrs for name in names):
            raise doc.error(f"{where} has only one of {names[0]} and {names[1]}")
        index_acc, weight_acc = (doc.element("accessors", attrs[name], f"{name} of {where}") for name in names)
        for name, acc in zip(names, (index_acc, weight_acc)):
            if acc["count"] != n:
                raise doc.error(f"{where} has {n} positions but {acc['count']} {name} values")
        if index_acc.get("componentType") not in (5121, 5123) or index_acc.get("normalized", False):
            raise doc.error(f"{names[0]} of {where} must be unsigned bytes or shorts, "
                            f"got componentType {index_acc.get('componentType')!r}")
        if weight_acc.get("componentType") != 5126 and not (
                weight_acc.get("componentType") in (5121, 5123) and weight_acc.get("normalized", False)):
            raise doc.error(f"{names[1]} of {where} must be floats or normalized unsigned bytes or shorts, "
                            f"got componentType {weight_acc.get('componentType')!r}")
        for name in names:
            doc.charge_pose_read(attrs[name], f"{name} of {where}")
        indices = doc.accessor(attrs[names[0]], f"{names[0]} of {where}", (4,)).astype(np.int64)
        if n and int(indices.max()) >= joints:
            raise doc.error(f"{names[0]} of {where} names joint {int(indices.max())}, but its skin has {joints} joints")
        weights = doc.accessor(attrs[names[1]], f"{names[1]} of {where}", (4,)).astype(np.float64)
        if not np.all(np.isfinite(weights)):
            raise doc.error(f"{names[1]} of {where} has NaN or Inf weights")
        sets.append((indices, weights))
        k += 1
    if not sets:
        raise doc.error(f"{where} is on a node with a skin but has no JOINTS_0 and WEIGHTS_0 attributes")
    return sets


def _skinned(data: _PrimitiveData, matrices: np.ndarray, influences: list) -> _PrimitiveData:
    """``data`` posed by linear blend skinning (glTF 2.0 "Skinned Mesh Attributes"): each vertex
    moved by its weighted sum of joint matrices M, normals by M's inverse transpose (the
    cofactor matrix times the sign of det M, which stays defined where M is singular), tangent
    directions by M; normals and tangents renormalized."""
    n = len(data.positions)
    positions = np.empty((n, 3))
    normals = None if data.normals is None else np.empty((n, 3))
    tangents = None if data.tangents is None else data.tangents.copy()
    for start in range(0, n, _SKIN_CHUNK):
        rows = slice(start, start + _SKIN_CHUNK)
        blend = sum(np.einsum("vk,vkij->vij", weights[rows], matrices[indices[rows]]) for indices, weights in influences)
        linear = blend[:, :3, :3]
        positions[rows] = np.einsum("vij,vj->vi", linear, data.positions[rows]) + blend[:, :3, 3]
        if normals is not None:
            c0, c1, c2 = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]
            cofactor = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=2)
            sign = np.sign(np.einsum("vi,vi->v", c0, cofactor[:, :, 0]))
            normals[rows] = np.einsum("vij,vj->vi", cofactor, data.normals[rows]) * sign[:, None]
        if tangents is not None:
            tangents[rows, :3] = np.einsum("vij,vj->vi", linear, data.tangents[rows, :3])
    if normals is not None:
        normals = unit_rows(normals)
    if tangents is not None:
        tangents[:, :3] = unit_rows(tangents[:, :3])
    return replace(data, positions=positions, normals=normals, tangents=tangents)


def _instance_count(doc: _Document, node: dict, index: int) -> int | None:
    """How many copies EXT_mesh_gpu_instancing places with node ``index`` (None without the
    extension), from its accessors' counts in the JSON alone."""
    ext = node.get("extensions", {}).get(_INSTANCING)
    if ext is None:
        return None
    attrs = ext.get("attributes", {}) if isinstance(ext, dict) else None
    if not isinstance(attrs, dict) or not any(name in attrs for name in ("TRANSLATION", "ROTATION", "SCALE")):
        raise doc.error(f"node {index} {_INSTANCING} has no TRANSLATION, ROTATION or SCALE attribute")
    counts = {name: doc.element("accessors", attrs[name], f"node {index} {_INSTANCING} {name}")["count"]
              for name in ("TRANSLATION", "ROTATION", "SCALE") if name in attrs}
    if len(set(counts.values())) > 1:
        raise doc.error(f"node {index} {_INSTANCING} attributes have different counts {counts}")
    return next(iter(counts.values()))


def _instance_matrices(doc: _Document, node: dict, index: int) -> list[np.ndarray]:
    """The local matrices (translation x rotation x scale) of node ``index``'s
    EXT_mesh_gpu_instancing instances, applied before the node's own transform; [identity]
    without the extension. Their count has been checked against LoadLimits (_check_instancing)."""
    count = _instance_count(doc, node, index)
    if count is None:
        return [np.eye(4)]
    attrs = node["extensions"][_INSTANCING]["attributes"]
    trs = {}
    for name, width in (("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)):
        if name in attrs:
            trs[name.lower()] = doc.accessor(attrs[name], f"node {index} {_INSTANCING} {name}", (width,)).tolist()
    return [_local_matrix(doc, {key: values[k] for key, values in trs.items()}, f"{index} instance {k}")
            for k in range(count)]


class _Builder:
    """Places every mesh node's triangle primitives in world space, with their glTF materials."""

    def __init__(self, doc: _Document, data: dict):
        self.doc = doc
        self.data = data
        self.materials = _Materials(doc)
        self._local: dict[tuple, Primitive] = {}  # (mesh, primitive), morph weights -> Primitive

    def primitives(self, nodes: list, worlds: dict) -> list[Primitive]:
        """The Primitives the walked ``nodes`` (_scene_nodes) place, named after their node (and
        ``/k`` for primitive k of a mesh with several); ``worlds`` holds every scene node's world
        matrix, for skins' joints."""
        out = []
        names = _node_names(self.doc)
        for index, world in nodes:
            node = self.doc.json["nodes"][index]
            if "mesh" not in node:
                continue
            prims = self.doc.json["meshes"][node["mesh"]].get("primitives", [])
            instances = _instance_matrices(self.doc, node, index)
            for pi in range(len(prims)):
                data = self.data.get((node["mesh"], pi))
                if data is None or len(data.faces) == 0:  # _note_points_and_lines says why
                    continue
                posed, placement = self._posed(node, index, data, world, worlds)
                name = names[index] if len(prims) == 1 else f"{names[index]}/{pi}"
                for k, instance in enumerate(instances):
                    try:
                        world_prim = transform_primitive(posed, placement @ instance)
                    except InputError as err:
                        raise self.doc.error(f"node {index}: {err}") from None
                    world_prim.name = name if len(instances) == 1 else f"{name}#{k}"
                    out.append(world_prim)
        return out

    def _posed(self, node: dict, index: int, data: _PrimitiveData, world, worlds: dict) -> tuple:
        """(Primitive, matrix that places it) for one primitive of node ``index``: the primitive
        at the node's morph weights in its mesh's space, placed by the node's world matrix; or,
        on a node with a skin, posed by the skin's joints in world space, placed by the identity
        (glTF ignores a skinned mesh node's own transform)."""
        weights = _morph_weights(self.doc, node, index, data)
        if "skin" not in node:
            return self._local_primitive(data, weights), world
        matrices = _joint_matrices(self.doc, node, index, worlds)
        where = data.where
        prim = self.doc.json["meshes"][data.key[0]]["primitives"][data.key[1]]
        influences = _skin_influences(self.doc, prim, len(data.positions), len(matrices), where)
        return self._from_data(_skinned(_morphed(self.doc, data, weights), matrices, influences)), np.eye(4)

    def _local_primitive(self, data: _PrimitiveData, weights: tuple) -> Primitive:
        """The Primitive of one glTF primitive in its mesh's space at morph ``weights``, shared
        by the nodes that place it with those weights."""
        key = (data.key, weights)
        if key not in self._local:
            self._local[key] = self._from_data(_morphed(self.doc, data, weights))
        return self._local[key]

    def _from_data(self, data: _PrimitiveData) -> Primitive:
        if data.material is None:
            material = Material(**_DEFAULT_MATERIAL)
        else:
            material = self.materials.get(data.material, data.where)
        normals = data.normals if data.normals is not None else np.zeros_like(data.positions)
        tangents = data.tangents
        second = [slot for slot, tex, _ in material.textures() if tex.texcoord == 1]
        if second and data.uvs1 is None:
            self.doc.notes.add("TEXCOORD_1 missing", "TEXCOORD_1 missing on {subjects}: their textures that ask for "
                               "it sampled with TEXCOORD_0 instead", "primitive", data.key,
                               f"{data.key[1]} of mesh {data.key[0]}")
        if tangents is None:
            uv_set = frame_uv_set(material, data.uvs, data.uvs1)
            if uv_set is not None:
                tangents = generate_tangents(data.positions, normals, data.uvs1 if uv_set == 1 else data.uvs,
                                             data.faces)
            elif material.anisotropy_strength > 0.0:
                self.doc.notes.add("anisotropy without tangents", "KHR_materials_anisotropy not applied on "
                                   "{subjects}: no TANGENT nor TEXCOORD_0 to give its direction (shaded isotropic)",
                                   "mesh", data.key, f"{data.key[0]} primitive {data.key[1]}")
        try:
            return Primitive(data.positions, data.faces, material, normals, data.uvs, tangents, data.colors,
                             uvs1=data.uvs1)
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
        (("extensions", "KHR_materials_specular", "specularTexture"), "specular_texture"),
        (("extensions", "KHR_materials_specular", "specularColorTexture"), "specular_color_texture"),
        (("extensions", "KHR_materials_anisotropy", "anisotropyTexture"), "anisotropy_texture"),
        (("extensions", "KHR_materials_iridescence", "iridescenceTexture"), "iridescence_texture"),
        (("extensions", "KHR_materials_iridescence", "iridescenceThicknessTexture"), "iridescence_thickness_texture"),
        (("extensions", "KHR_materials_clearcoat", "clearcoatTexture"), "clearcoat_texture"),
        (("extensions", "KHR_materials_clearcoat", "clearcoatRoughnessTexture"), "clearcoat_roughness_texture"),
        (("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture"), "clearcoat_normal_texture"),
        (("extensions", "KHR_materials_sheen", "sheenColorTexture"), "sheen_color_texture"),
        (("extensions", "KHR_materials_sheen", "sheenRoughnessTexture"), "sheen_roughness_texture"),
        (("extensions", "KHR_materials_transmission", "transmissionTexture"), "transmission_texture"),
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
        film = ext.get("KHR_materials_iridescence", {})
        coat = ext.get("KHR_materials_clearcoat", {})
        sheen = ext.get("KHR_materials_sheen", {})
        volume = ext.get("KHR_materials_volume", {})
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
            specular_color=ext.get("KHR_materials_specular", {}).get("specularColorFactor", (1.0, 1.0, 1.0)),
            ior=ext.get("KHR_materials_ior", {}).get("ior", 1.5),
            emissive=tuple(float(c) * emissive_strength for c in spec.get("emissiveFactor", (0.0, 0.0, 0.0))),
            normal_scale=spec.get("normalTexture", {}).get("scale", 1.0),
            occlusion_strength=spec.get("occlusionTexture", {}).get("strength", 1.0),
            double_sided=_boolean(spec.get("doubleSided", False), "doubleSided"),
            alpha_mode=spec.get("alphaMode", "OPAQUE"),
            alpha_cutoff=spec.get("alphaCutoff", 0.5),
            unlit="KHR_materials_unlit" in ext,
            anisotropy_strength=ext.get("KHR_materials_anisotropy", {}).get("anisotropyStrength", 0.0),
            anisotropy_rotation=ext.get("KHR_materials_anisotropy", {}).get("anisotropyRotation", 0.0),
            iridescence=film.get("iridescenceFactor", 0.0),
            iridescence_ior=film.get("iridescenceIor", 1.3),
            iridescence_thickness_min=film.get("iridescenceThicknessMinimum", 100.0),
            iridescence_thickness_max=film.get("iridescenceThicknessMaximum", 400.0),
            clearcoat=coat.get("clearcoatFactor", 0.0),
            clearcoat_roughness=coat.get("clearcoatRoughnessFactor", 0.0),
            clearcoat_normal_scale=coat.get("clearcoatNormalTexture", {}).get("scale", 1.0),
            sheen_color=sheen.get("sheenColorFactor", (0.0, 0.0, 0.0)),
            sheen_roughness=sheen.get("sheenRoughnessFactor", 0.0),
            transmission=ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0.0),
            # the thickness texture is for renderers that cannot measure the geometry, which a
            # ray tracer does (KHR_materials_volume, "Thickness Texture")
            thickness=volume.get("thicknessFactor", 0.0),
            attenuation_color=volume.get("attenuationColor", (1.0, 1.0, 1.0)),
            attenuation_distance=volume.get("attenuationDistance", math.inf),
            name=spec.get("name", ""),
            **textures,
        )

    def _texture(self, info: dict, label: str) -> Texture:
        """The Texture a textureInfo describes: image, sampler wrap modes, texture transform."""
        doc = self.doc
        tex = doc.element("textures", info.get("index"), label)
        transform = info.get("extensions", {}).get("KHR_texture_transform", {})
        tex_coord = transform.get("texCoord", info.get("texCoord", 0))
        if isinstance(tex_coord, bool) or not isinstance(tex_coord, int) or tex_coord < 0:
            raise doc.error(f"{label}: texCoord must be a non-negative integer, got {tex_coord!r}")
        if tex_coord > 1:
            doc.notes.add(f"TEXCOORD_{tex_coord}", f"TEXCOORD_{tex_coord} not read: {{subjects}} sampled with "
                          "TEXCOORD_0 instead", "texture slot", label)
            tex_coord = 0
        # EXT_texture_webp names a WebP image, which Pillow decodes; "source" is then the fallback
        source = tex.get("extensions", {}).get("EXT_texture_webp", {}).get("source", tex.get("source"))
        source = texture_source(doc, tex, info["index"], label, source)  # KHR_texture_basisu's KTX2 image first
        if source is None:
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
        key = (source, *wrap, offset, rotation, scale, tex_coord)
        if key not in self._textures:
            self._textures[key] = Texture(doc.image(source), wrap_s=wrap[0], wrap_t=wrap[1],
                                          offset=offset, rotation=rotation, scale=scale, texcoord=tex_coord)
        return self._textures[key]


def _boolean(value, what: str) -> bool:
    if not isinstance(value, bool):
        raise InputTypeError(f"{what} must be true or false, got {value!r}")
    return value


# ---------------------------------------------------------------------------- nodes, lights, cameras
def _scene_nodes(doc: _Document) -> tuple[list[tuple[int, np.ndarray]], set[int]]:
    """((node index, world matrix) for every node of the default scene, parents first; the nodes
    KHR_node_visibility hides: those whose own ``visible`` is false, and their descendants).

    The walk is iterative and visits each node once: glTF node hierarchies are disjoint trees
    (glTF 2.0, section 3.5.2: no cycles, at most one parent per node), so a node reached a second
    time -- its own ancestor, the child of two nodes, a root that is also a child, a root listed
    twice -- is an error, as is a node deeper than ``LoadLimits.max_node_depth``. Instancing in
    glTF is a mesh used by several nodes, which _check_instancing bounds."""
    scenes = doc.json.get("scenes", [])
    if not scenes:
        return []
    scene = doc.element("scenes", doc.json.get("scene", 0), "the default scene")
    max_depth = doc.limits.max_node_depth
    parents: dict[int, int | None] = {}  # node -> parent (None for a root), for each node visited
    out = []
    hidden = set()
    stack = [(root, None, np.eye(4), 1, False)
             for root in reversed(_index_list(doc, scene.get("nodes", []), "scene nodes"))]
    while stack:
        index, parent, parent_world, depth, parent_hidden = stack.pop()
        where = "the scene's root nodes" if parent is None else f"the children of node {parent}"
        node = doc.element("nodes", index, where)
        if index in parents:
            raise doc.error(_second_visit(index, parent, parents))
        if depth > max_depth:
            raise doc.error(f"node {index} is {depth} levels deep in the node hierarchy, deeper than the "
                            f"{max_depth} of LoadLimits.max_node_depth")
        parents[index] = parent
        if "mesh" in node:
            doc.element("meshes", node["mesh"], f"node {index}")
        world = parent_world @ _local_matrix(doc, node, index)
        out.append((index, world))
        visible = node.get("extensions", {}).get("KHR_node_visibility", {}).get("visible", True)
        if not isinstance(visible, bool):
            raise doc.error(f"node {index}: KHR_node_visibility's visible must be true or false, got {visible!r}")
        if parent_hidden or not visible:
            hidden.add(index)
        children = _index_list(doc, node.get("children", []), f"node {index} children")
        stack.extend((child, index, world, depth + 1, index in hidden) for child in reversed(children))
    return out, hidden


def _node_names(doc: _Document) -> dict[int, str]:
    """Each node's name (its index where it has none), made unique with a ``_k`` suffix."""
    names, used = {}, set()
    for index, node in enumerate(doc.json.get("nodes", [])):
        base = str(node.get("name", index)) if isinstance(node, dict) else str(index)
        name, k = base, 0
        while name in used:
            k += 1
            name = f"{base}_{k}"
        used.add(name)
        names[index] = name
    return names


def _index_list(doc: _Document, value, what: str) -> list:
    if not isinstance(value, list):
        raise doc.error(f"{what} must be an array of node indices, got {value!r}")
    return value


def _second_visit(index: int, parent: int | None, parents: dict) -> str:
    """Why the node walk reached node ``index`` again, now from ``parent``."""
    def named(p):
        return "the scene's root list" if p is None else f"node {p}"

    ancestor = parent
    while ancestor is not None:  # parents form a forest: this walk ends after at most depth steps
        if ancestor == index:
            return f"node {index} is its own ancestor (a cycle in the node hierarchy)"
        ancestor = parents[ancestor]
    return (f"node {index} is reached twice, from {named(parents[index])} and from {named(parent)}; glTF "
            "node hierarchies are trees (one parent per node, glTF 2.0 section 3.5.2)")


def _check_instancing(doc: _Document, nodes: list):
    """The primitives, vertices and triangles the scene's mesh nodes place (times the copies
    EXT_mesh_gpu_instancing makes of a node), counted from the
    JSON before any mesh is read or copied, against LoadLimits."""
    limits = doc.limits
    sizes: dict[int, tuple[int, int, int]] = {}  # mesh -> (primitives, vertices, triangles)
    instances = vertices = triangles = 0
    for index, _ in nodes:
        node = doc.json["nodes"][index]
        if "mesh" not in node:
            continue
        copies = _instance_count(doc, node, index)
        copies = 1 if copies is None else copies
        if copies > limits.max_instances:
            raise doc.error(f"node {index} places {copies} {_INSTANCING} instances, more than the "
                            f"{limits.max_instances} of LoadLimits.max_instances")
        mi = node["mesh"]
        if mi not in sizes:
            mesh = doc.element("meshes", mi, f"node {index}")
            prims = mesh.get("primitives", [])
            counts = [_primitive_size(doc, prim, f"mesh {mi} primitive {pi}") for pi, prim in enumerate(prims)
                      if _primitive_mode(doc, prim, f"mesh {mi} primitive {pi}") in _TRIANGLE_MODES]
            sizes[mi] = (len(prims), sum(c[0] for c in counts), sum(c[1] for c in counts))
        instances += sizes[mi][0] * copies
        vertices += sizes[mi][1] * copies
        triangles += sizes[mi][2] * copies
        for total, field_name, noun in ((instances, "max_instances", "mesh primitives"),
                                        (vertices, "max_vertices", "vertices"), (triangles, "max_triangles", "triangles")):
            limit = getattr(limits, field_name)
            if total > limit:
                raise doc.error(f"its nodes place more than {limit} {noun} (LoadLimits.{field_name}); the limit "
                                f"is passed at node {index}, which places mesh {mi}")


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
    # glTF rotations are unit quaternions: slightly off ones are normalized, lengths far from 1 are
    # a broken file rather than a rotation to guess at.
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
    down the node's -Z), with its ``range`` (unaffected by the node's scale, as the extension
    says)."""
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
    reach = spec.get("range")
    try:
        if kind == "point":
            return [PointLight(position=position, color=color, intensity=intensity, range=reach)]
        if kind == "directional":
            return [DirectionalLight(direction=direction, color=color, intensity=intensity)]
        if kind == "spot":
            cone = spec.get("spot", {})
            return [SpotLight(position=position, direction=direction, color=color, intensity=intensity,
                              inner_cone=cone.get("innerConeAngle", 0.0),
                              outer_cone=cone.get("outerConeAngle", math.pi / 4.0), range=reach)]
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
        doc.notes.add(f"camera type {spec.get('type')!r}", f"{{subjects}} of type {spec.get('type')!r} skipped: "
                      "pbrwarp reads perspective cameras only", "camera", node["camera"], _ident(spec, node["camera"]))
        return []
    yfov = spec.get("perspective", {}).get("yfov")
    try:
        return [Camera.from_matrix(world, math.degrees(float(yfov)))]
    except (InputError, InputTypeError, TypeError, ValueError) as err:
        raise doc.error(f"camera {node['camera']} (on node {index}): {err}") from None
