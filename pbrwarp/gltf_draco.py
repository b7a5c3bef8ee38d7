"""KHR_draco_mesh_compression: glTF primitives compressed with Draco, decoded by DracoPy.

DracoPy (the ``draco`` extra, ``pip install "pbrwarp[draco]"``) binds Google's Draco decoder. A
compressed primitive's ``bufferView`` is decoded into a mesh whose attributes are found by the
unique ids the extension's ``attributes`` map names; the decoded arrays then stand in for the
primitive's accessors, which keep their ``count``, ``type``, ``componentType`` and ``normalized``
(KHR_draco_mesh_compression, "accessors": they "must match the decompressed data").

The bytes are hostile until checked. Before the decoder sees them, the Draco header's face and
vertex counts (the Draco bitstream specification, "ParseSequentialConnectivityData" and
"ParseEdgebreakerConnectivityData") are compared with the primitive's accessors, whose counts
LoadLimits already bounds, so a stream that declares a huge mesh is refused before it allocates
one. After decoding, every array is checked against its accessor: count, width, value type and
range, and the indices against the vertex count (by the reader). A mismatch is an
``AssetFormatError`` naming the file and the primitive.

Without DracoPy a compressed primitive with uncompressed fallback data is read from the fallback,
with a warning saying how to decode it; one without is an error giving the install command.
"""

from __future__ import annotations

import numpy as np

EXTENSION = "KHR_draco_mesh_compression"
INSTALL = 'pip install "pbrwarp[draco]"'
_TRIANGLES = 4
_METADATA_FLAG = 0x8000  # Draco header flags: geometry metadata follows the header
_MESH = 1  # Draco encoder_type of a triangle mesh (0 is a point cloud)
_SEQUENTIAL, _EDGEBREAKER = 0, 1  # Draco encoder_method


def decoder():
    """The DracoPy module, or None when the ``draco`` extra is not installed."""
    try:
        import DracoPy
    except ImportError:
        return None
    return DracoPy


def decode_primitive(doc, key: tuple[int, int], prim: dict):
    """Decode primitive ``key`` (mesh, primitive) if it carries KHR_draco_mesh_compression,
    filling ``doc.decoded`` (accessor index -> array in the accessor's component type) for every
    accessor of its attributes and indices that the compressed data holds. ``doc``: the reader's
    document (pbrwarp.gltf._Document)."""
    extensions = prim.get("extensions", {})
    spec = extensions.get(EXTENSION) if isinstance(extensions, dict) else None
    if spec is None:
        return
    where = f"mesh {key[0]} primitive {key[1]}"
    ids = _check_spec(doc, spec, prim, where)
    draco = decoder()
    if draco is None:
        _fall_back(doc, key, prim, where)
        return
    view = doc.element("bufferViews", spec["bufferView"], f"{EXTENSION} of {where}")
    raw = doc.view_array(spec["bufferView"], 0, np.dtype("u1"), view.get("byteLength"), 1,
                         f"{EXTENSION} data of {where}", strided=False).tobytes()
    attributes = prim["attributes"]
    vertices = doc.element("accessors", attributes["POSITION"], f"POSITION of {where}")["count"]
    indices = doc.element("accessors", prim["indices"], f"indices of {where}")["count"]
    if indices % 3:
        raise doc.error(f"indices of {where} count {indices}, not a multiple of 3")
    _check_header(doc, raw, vertices, indices // 3, where)
    try:
        mesh = draco.decode(raw)
    except Exception as err:  # DracoPy raises its own types, MemoryError and ValueError on bad bytes
        raise doc.error(f"the {EXTENSION} data of {where} cannot be decoded ({type(err).__name__}: {err})") from None
    if not isinstance(mesh, draco.DracoMesh):
        raise doc.error(f"the {EXTENSION} data of {where} is a Draco point cloud, not a triangle mesh")
    faces = np.asarray(mesh.faces).reshape(-1)
    if len(faces) != indices:
        raise doc.error(f"the {EXTENSION} data of {where} decodes to {len(faces) // 3} triangles, but its indices "
                        f"accessor declares {indices // 3}")
    decoded = {prim["indices"]: _as_accessor(doc, prim["indices"], faces.reshape(-1, 1), f"indices of {where}")}
    by_id = {item["unique_id"]: item for item in mesh.attributes}
    for name, unique_id in ids.items():
        if unique_id not in by_id:
            raise doc.error(f"{EXTENSION} of {where} maps {name} to Draco attribute {unique_id}, which its "
                            f"compressed data does not hold (it has {sorted(by_id)})")
        data = np.asarray(by_id[unique_id]["data"])
        data = data.reshape(len(data), -1)
        if len(data) != vertices:
            raise doc.error(f"the {EXTENSION} data of {where} decodes {len(data)} {name} values, but its POSITION "
                            f"accessor declares {vertices} vertices")
        decoded[attributes[name]] = _as_accessor(doc, attributes[name], data, f"{name} of {where}")
    for index, data in decoded.items():
        earlier = doc.decoded.setdefault(index, data)
        if earlier is not data and not np.array_equal(earlier, data):
            raise doc.error(f"accessor {index} is filled by two Draco-compressed primitives with different data "
                            f"(the second is {where})")


def _check_spec(doc, spec, prim: dict, where: str) -> dict[str, int]:
    """The extension's attribute map (name -> Draco unique id), its properties checked."""
    what = f"{EXTENSION} of {where}"
    if not isinstance(spec, dict):
        raise doc.error(f"{what} is not an object")
    ids, attributes = spec.get("attributes"), prim.get("attributes", {})
    if not isinstance(ids, dict) or not ids:
        raise doc.error(f"{what} has no attributes map (attribute name -> Draco unique id)")
    for name, unique_id in ids.items():
        if isinstance(unique_id, bool) or not isinstance(unique_id, int) or unique_id < 0:
            raise doc.error(f"{what} maps {name} to {unique_id!r}, not a Draco attribute id")
        if name not in attributes:
            raise doc.error(f"{what} holds {name}, which the primitive's attributes do not list")
    if "POSITION" not in ids:
        raise doc.error(f"{what} does not hold POSITION")
    if prim.get("mode", _TRIANGLES) != _TRIANGLES:
        raise doc.error(f"{where} is Draco-compressed with mode {prim.get('mode')!r}; pbrwarp decodes Draco "
                        "triangle lists (mode 4) only")
    if "indices" not in prim:
        raise doc.error(f"{where} is Draco-compressed but has no indices accessor for its decoded triangles")
    if "bufferView" not in spec:
        raise doc.error(f"{what} has no bufferView")
    return ids


def _fall_back(doc, key: tuple[int, int], prim: dict, where: str):
    """Without DracoPy: note that the fallback is read, or refuse a primitive that has none."""
    accessors = list(prim["attributes"].values()) + [prim["indices"]]
    if all("bufferView" in doc.element("accessors", index, where) for index in accessors):
        mesh = doc.json["meshes"][key[0]]
        name = mesh.get("name") if isinstance(mesh.get("name"), str) and mesh.get("name") else key[0]
        doc.notes.add(f"undecoded {EXTENSION}", f"{EXTENSION} on {{subjects}} not decoded: DracoPy is not "
                      f"installed ({INSTALL}); the uncompressed fallback data is read instead",
                      "mesh", key[0], repr(name) if isinstance(name, str) else str(name))
        return
    raise doc.error(f"{where} is compressed with {EXTENSION} and has no uncompressed fallback; decoding it needs "
                    f"DracoPy: {INSTALL}")


def _as_accessor(doc, index: int, data: np.ndarray, what: str) -> np.ndarray:
    """Decoded ``data`` (count, width) in accessor ``index``'s component type, after checking
    that its width and value type match the accessor and its values fit the component type."""
    acc = doc.json["accessors"][index]
    dtype, width = doc.accessor_layout(index)
    if data.shape[1] != width:
        raise doc.error(f"the Draco data of {what} has {data.shape[1]} components, but accessor {index} is "
                        f"{acc['type']}")
    if dtype.kind == "f":
        if data.dtype.kind != "f":
            raise doc.error(f"the Draco data of {what} holds integers, but accessor {index} is float")
        return data.astype(dtype)
    if data.dtype.kind not in "iub":
        raise doc.error(f"the Draco data of {what} holds floats, but accessor {index} has integer componentType "
                        f"{acc['componentType']}")
    limits = np.iinfo(dtype)
    if len(data) and (int(data.min()) < limits.min or int(data.max()) > limits.max):
        raise doc.error(f"the Draco data of {what} holds values {int(data.min())}..{int(data.max())}, outside "
                        f"accessor {index}'s {dtype.name}")
    return data.astype(dtype)


# ---------------------------------------------------------------------------- the Draco header
class _Reader:
    """Little-endian reads from a Draco stream, each refusing to run past its end."""

    def __init__(self, raw: bytes):
        self.raw, self.at = raw, 0

    def bytes(self, count: int) -> bytes:
        if self.at + count > len(self.raw):
            raise ValueError(f"it ends at byte {len(self.raw)}, inside its header")
        self.at += count
        return self.raw[self.at - count: self.at]

    def u8(self) -> int:
        return self.bytes(1)[0]

    def u32(self) -> int:
        return int.from_bytes(self.bytes(4), "little")

    def varint(self) -> int:
        """A Draco varUI32: 7 bits a byte, low first, at most 5 bytes."""
        value = 0
        for shift in range(0, 35, 7):
            byte = self.u8()
            value |= (byte & 0x7F) << shift
            if not byte & 0x80:
                return value
        raise ValueError("a variable-length number in its header runs past 5 bytes")


def _check_header(doc, raw: bytes, vertices: int, faces: int, where: str):
    """Compare the face and vertex counts in a Draco stream's header with the accessors' (which
    LoadLimits bounds) before decoding it: the decoder allocates by those counts."""
    what = f"the {EXTENSION} data of {where}"
    try:
        counts = _header_counts(raw)
    except ValueError as err:
        raise doc.error(f"{what} is not a valid Draco mesh: {err}") from None
    declared_faces, bound, noun = counts
    if declared_faces != faces:
        raise doc.error(f"{what} declares {declared_faces} triangles, but its indices accessor declares {faces}")
    if bound > vertices:
        raise doc.error(f"{what} declares {bound} {noun}, but its POSITION accessor declares {vertices} vertices")


def _header_counts(raw: bytes) -> tuple[int, int, str]:
    """(faces, a lower bound of the decoded vertices, what that bound counts) from the header and
    connectivity header of a Draco mesh stream of bitstream version 2.x, skipping its metadata."""
    reader = _Reader(raw)
    if reader.bytes(5) != b"DRACO":
        raise ValueError("it does not start with b'DRACO'")
    major, minor, kind, method = reader.u8(), reader.u8(), reader.u8(), reader.u8()
    flags = int.from_bytes(reader.bytes(2), "little")
    if major != 2:
        raise ValueError(f"Draco bitstream version {major}.{minor}; glTF's KHR_draco_mesh_compression uses 2.x")
    if kind != _MESH:
        raise ValueError(f"its encoder type is {kind}, not a triangle mesh ({_MESH})")
    if flags & _METADATA_FLAG:
        _skip_geometry_metadata(reader)
    varints = minor >= 2  # bitstream 2.2 writes the sequential counts as varUI32, earlier as UI32
    if method == _SEQUENTIAL:
        faces = reader.varint() if varints else reader.u32()
        points = reader.varint() if varints else reader.u32()
        return faces, points, "points"
    if method == _EDGEBREAKER:
        reader.u8()  # traversal type
        if not varints:
            reader.varint()  # num_new_vertices (bitstreams before 2.2)
        vertices, faces = reader.varint(), reader.varint()
        reader.u8()  # num_attribute_data
        symbols, split_symbols = reader.varint(), reader.varint()
        if symbols > faces or split_symbols > faces:
            raise ValueError(f"it declares {symbols} symbols and {split_symbols} split symbols for {faces} faces")
        return faces, vertices, "encoded vertices"
    raise ValueError(f"unknown encoder method {method}")


def _skip_geometry_metadata(reader: _Reader):
    """Skip a stream's geometry metadata (the Draco bitstream specification, "DecodeMetadata"):
    ``num_att_metadata`` attribute elements, each after its attribute id, then the file's
    element. An element holds entries (key, value) and sub-elements, each after its key; they
    nest, so they are walked with an explicit stack rather than recursion."""
    elements = reader.varint()
    for _ in range(elements):
        reader.varint()  # the attribute's id
        _skip_element(reader)
    _skip_element(reader)


def _skip_element(reader: _Reader):
    remaining = [1]  # elements left to read at each nesting level
    while remaining:
        if remaining[-1] == 0:
            remaining.pop()
            continue
        remaining[-1] -= 1
        if len(remaining) > 1:
            reader.bytes(reader.u8())  # a sub-element's key
        for _ in range(reader.varint()):
            reader.bytes(reader.u8())  # key
            reader.bytes(reader.u8())  # value
        remaining.append(reader.varint())
