"""KHR_draco_mesh_compression (pbrwarp/gltf_draco.py): Draco primitives decode to the geometry
they compress, every decoded array is checked against its accessor, hostile bytes are refused
without harm to the process, and without DracoPy the error or warning says how to install it.

The compressed files are made here with DracoPy's encoder from in-repository meshes (the Duck
sample model), so the uncompressed geometry is at hand to compare with; Box/glTF-Draco, the
Khronos board, is the file from a real exporter.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.errors import AssetFormatError
from pbrwarp.gltf import _Document, _read_primitives, load_gltf
from pbrwarp.gltf_draco import EXTENSION, INSTALL

from assets import ASSETS, board
from test_gltf import Builder
from test_hostile_files import damaged_copies, load_each_in_child

DracoPy = pytest.importorskip("DracoPy")

DUCK = ASSETS / "gltf" / "Duck" / "glTF-Binary" / "Duck.glb"
POSITION, NORMAL, COLOR, TEX_COORD = 0, 1, 2, 3  # DracoPy.AttributeType values
TANGENT_ID, COLOR_ID = 7, 8  # unique ids given to the generic attributes encoded below


def duck():
    """The Duck's one primitive, uncompressed (world space: its node's matrix applied)."""
    return load_gltf(DUCK).primitives[0]


def draco_glb(path: Path, raw: bytes, *, counts=None, ids=None, fallback=None, required=True, tweak=None) -> Path:
    """A .glb of one primitive compressed into ``raw``. The accessors' counts and the
    extension's attribute ids are read from what DracoPy decodes (``counts``/``ids`` override
    them); ``fallback``: uncompressed arrays by attribute name (plus "indices") to store as the
    accessors' data, else the accessors have none. ``tweak(builder)`` edits the JSON last."""
    mesh = DracoPy.decode(raw)
    by_type = {item["attribute_type"]: item["unique_id"] for item in mesh.attributes}
    names = {"POSITION": (by_type[POSITION], "VEC3", 5126)}
    if NORMAL in by_type:
        names["NORMAL"] = (by_type[NORMAL], "VEC3", 5126)
    if TEX_COORD in by_type:
        names["TEXCOORD_0"] = (by_type[TEX_COORD], "VEC2", 5126)
    held = {item["unique_id"] for item in mesh.attributes}
    if TANGENT_ID in held:
        names["TANGENT"] = (TANGENT_ID, "VEC4", 5126)
    if COLOR_ID in held:
        names["COLOR_0"] = (COLOR_ID, "VEC4", 5121)
    counts = {"vertices": len(mesh.points), "indices": mesh.faces.size, **(counts or {})}
    b = Builder()
    fallback = fallback or {}

    def accessor(name, kind, ctype, count):
        spec = {"componentType": ctype, "type": kind, "count": count}
        if name == "COLOR_0":
            spec["normalized"] = True
        if name in fallback:
            spec["bufferView"] = b.view(np.ascontiguousarray(fallback[name]).tobytes())
        b.json["accessors"].append(spec)
        return len(b.json["accessors"]) - 1

    view = b.view(raw)
    attributes = {name: accessor(name, kind, ctype, counts["vertices"]) for name, (_, kind, ctype) in names.items()}
    prim = {"attributes": attributes, "indices": accessor("indices", "SCALAR", 5125, counts["indices"]),
            "extensions": {EXTENSION: {"bufferView": view,
                                       "attributes": ids or {name: uid for name, (uid, _, _) in names.items()}}}}
    b.json["meshes"].append({"name": "compressed", "primitives": [prim]})
    b.node(mesh=0)
    b.json["extensionsUsed"] = [EXTENSION]
    if required:
        b.json["extensionsRequired"] = [EXTENSION]
    if tweak is not None:
        tweak(b)
    return b.glb(path)


def grid_keys(points, origin, step):
    """Each point's cell on Draco's quantization grid (integer coordinates)."""
    return np.rint((np.asarray(points, np.float64) - origin) / step).astype(np.int64)


def triangle_set(keys, faces):
    """The triangles as a sorted list of corner-key tuples, each rotated to start at its least
    corner (winding kept): comparable however the vertices and faces are ordered."""
    corners = keys[faces]  # (F, 3, 3)
    out = []
    for tri in corners.tolist():
        k = min(range(3), key=lambda i: tri[i])
        out.append(tuple(map(tuple, tri[k:] + tri[:k])))
    return sorted(out)


# ---------------------------------------------------------------------------- decoded geometry
@pytest.mark.parametrize("level", [1, 7])
def test_edgebreaker_duck_decodes_to_its_triangles_within_the_quantization_step(tmp_path, level):
    """Draco reorders the Duck's vertices and faces (edgebreaker); on the quantization grid of
    its 14-bit positions (step = range / (2^14 - 1), every input within half a step of its
    dequantized value) the decoded triangles are exactly the original ones, and the normals and
    texture coordinates of matching vertices agree within their own quantization."""
    src = duck()
    bits = 14
    raw = DracoPy.encode(src.positions, src.faces, quantization_bits=bits, compression_level=level,
                         normals=src.normals, tex_coord=src.uvs, normal_quantization_bits=12,
                         tex_coord_quantization_bits=14)
    scene = load_gltf(draco_glb(tmp_path / "duck.glb", raw))
    got = scene.primitives[0]
    assert scene.load_warnings == ()
    origin = src.positions.min(axis=0)
    step = float(np.ptp(src.positions, axis=0).max()) / (2**bits - 1)
    assert np.all(np.abs(got.positions - grid_keys(got.positions, origin, step) * step - origin) < 1e-3 * step + 1e-6)
    assert len(got.faces) == len(src.faces)
    assert triangle_set(grid_keys(got.positions, origin, step), got.faces) == \
        triangle_set(grid_keys(src.positions, origin, step), src.faces)
    # each decoded vertex against the original vertices of its cell (seams put several there, with different
    # UVs or normals): the closest of them is within the attribute's quantization
    cells: dict[tuple, list[int]] = {}
    for i, k in enumerate(grid_keys(src.positions, origin, step).tolist()):
        cells.setdefault(tuple(k), []).append(i)
    uv_step = float(np.ptp(src.uvs, axis=0).max()) / (2**14 - 1)
    for i, k in enumerate(grid_keys(got.positions, origin, step).tolist()):
        candidates = cells[tuple(k)]
        uv_error = np.abs(src.uvs[candidates] - got.uvs[i]).max(axis=1)
        cosine = src.normals[candidates] @ got.normals[i] / np.linalg.norm(got.normals[i])
        best = int(np.argmin(uv_error - cosine))
        assert uv_error[best] <= 0.5 * uv_step * (1 + 1e-3) + 1e-7
        assert cosine[best] > np.cos(np.radians(0.2))


def test_sequential_encoding_keeps_order_and_every_attribute(tmp_path):
    """With preserve_order the decoded arrays line up with the originals row for row: positions
    within half a quantization step (and float32 rounding), float generic attributes (TANGENT) exact, COLOR_0 as
    normalized unsigned bytes, indices exact."""
    src = duck()
    rng = np.random.default_rng(7)
    n = len(src.positions)
    tangents = np.column_stack([src.normals[:, [1, 2, 0]], np.where(rng.random(n) < 0.5, -1.0, 1.0)])
    colors = rng.integers(0, 256, (n, 4)).astype(np.uint8)
    bits = 16
    raw = DracoPy.encode(src.positions, src.faces, quantization_bits=bits, preserve_order=True,
                         generic_attributes={TANGENT_ID: tangents.astype(np.float32), COLOR_ID: colors})
    got = load_gltf(draco_glb(tmp_path / "ordered.glb", raw)).primitives[0]
    step = float(np.ptp(src.positions, axis=0).max()) / (2**bits - 1)
    float32 = np.finfo(np.float32).eps * np.abs(src.positions).max()  # the arrays' own rounding
    assert np.abs(got.positions - src.positions).max() <= 0.5 * step + 4 * float32
    np.testing.assert_array_equal(got.faces, src.faces)
    np.testing.assert_allclose(got.tangents, tangents.astype(np.float32), atol=1e-6)
    np.testing.assert_allclose(got.colors, colors / 255.0, atol=1e-7)


def test_skin_joints_and_weights_come_from_the_draco_data(tmp_path):
    """JOINTS_0 (unsigned shorts) and WEIGHTS_0 (floats) as Draco generic attributes pose the
    mesh: vertices weighted fully to joint 1, a node translated by (0, 5, 0), move by it; those
    weighted to joint 0, at the origin, stay."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    joints = np.array([[0, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0]], np.uint16)
    weights = np.array([[1, 0, 0, 0]] * 4, np.float32)
    raw = DracoPy.encode(corners, faces, quantization_bits=16, preserve_order=True,
                         generic_attributes={3: joints, 4: weights})

    def skin(b):
        prim = b.json["meshes"][0]["primitives"][0]
        for name, uid, ctype in (("JOINTS_0", 3, 5123), ("WEIGHTS_0", 4, 5126)):
            b.json["accessors"].append({"componentType": ctype, "type": "VEC4", "count": 4})
            prim["attributes"][name] = len(b.json["accessors"]) - 1
            prim["extensions"][EXTENSION]["attributes"][name] = uid
        b.json["nodes"][0]["skin"] = 0
        b.json["nodes"] += [{"translation": [0, 0, 0]}, {"translation": [0, 5, 0]}]
        b.json["scenes"][0]["nodes"] += [1, 2]
        b.json["skins"] = [{"joints": [1, 2]}]

    got = load_gltf(draco_glb(tmp_path / "skinned.glb", raw, tweak=skin)).primitives[0]
    np.testing.assert_allclose(got.positions, corners + np.array([[0, 0, 0], [0, 5, 0], [0, 5, 0], [0, 0, 0]]),
                               atol=1e-4)


def test_draco_board_loads_as_its_uncompressed_twin():
    """Box/glTF-Draco (exported by COLLADA2GLTF) is the Cesium box that BoxTextured holds
    uncompressed: 12 triangles spanning -0.5..0.5 on every axis, with axis-aligned unit normals."""
    with_draco = pw.Scene.load(board("Box"))
    plain = pw.Scene.load(ASSETS / "gltf" / "BoxTextured" / "glTF-Binary" / "BoxTextured.glb")
    assert with_draco.load_warnings == ()
    assert with_draco.triangle_count == plain.triangle_count == 12
    for scene in (with_draco, plain):
        positions = np.concatenate([p.positions for p in scene.primitives])
        np.testing.assert_allclose([positions.min(axis=0), positions.max(axis=0)], [[-0.5] * 3, [0.5] * 3], atol=1e-6)
    normals = with_draco.primitives[0].normals
    np.testing.assert_allclose(np.sort(np.abs(normals), axis=1), np.tile([0, 0, 1], (len(normals), 1)), atol=1e-6)


def test_shared_draco_models_load_within_their_declared_bounds():
    """Every Draco model of the shared set (PBRWARP_TEST_ASSETS) loads, its positions inside
    the accessor min/max the exporter wrote (from the uncompressed data it compressed)."""
    paths = sorted(ASSETS.glob("gltf-ext/*/glTF-Draco/*.gltf"))
    assert paths
    for path in paths:
        doc = json.loads(path.read_text())
        scene = load_gltf(path)
        accessors = [doc["accessors"][p["attributes"]["POSITION"]] for m in doc["meshes"] for p in m["primitives"]]
        declared = sum(doc["accessors"][p["indices"]]["count"] // 3 for m in doc["meshes"] for p in m["primitives"])
        assert sum(len(p.faces) for p in scene.primitives) == declared
        lo = np.min([a["min"] for a in accessors], axis=0)
        hi = np.max([a["max"] for a in accessors], axis=0)
        local = _read_primitives(_Document(str(path)))  # in the mesh's own space, where min and max apply
        positions = np.concatenate([d.positions for d in local.values()])
        assert np.all(positions >= lo - 1e-6) and np.all(positions <= hi + 1e-6), path


# ---------------------------------------------------------------------------- checks
def small_box():
    """A 2 x 2 x 2 cube's 8 corners and 12 triangles, Draco-encoded (edgebreaker)."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return DracoPy.encode(corners, faces)


@pytest.mark.parametrize("kwargs, message", [
    (dict(counts={"vertices": 9}), "declares 8 encoded vertices|decodes 8 POSITION values, but"),
    (dict(counts={"indices": 33}), "declares 12 triangles, but its indices accessor declares 11"),
    (dict(counts={"indices": 35}), "indices of mesh 0 primitive 0 count 35, not a multiple of 3"),
    (dict(ids={"POSITION": 5}), "maps POSITION to Draco attribute 5, which its compressed data does not hold"),
    (dict(ids={"POSITION": -1}), "maps POSITION to -1, not a Draco attribute id"),
    (dict(ids={"POSITION": 0, "NORMAL": 0}), "holds NORMAL, which the primitive's attributes do not list"),
    (dict(tweak=lambda b: b.json["accessors"][0].update(type="VEC2")), "has 3 components, but accessor 0 is VEC2"),
    (dict(tweak=lambda b: b.json["accessors"][0].update(componentType=5123)), "holds floats, but accessor 0"),
    (dict(tweak=lambda b: b.json["meshes"][0]["primitives"][0].update(mode=5)), "pbrwarp decodes Draco triangle"),
    (dict(tweak=lambda b: b.json["meshes"][0]["primitives"][0]["extensions"][EXTENSION].pop("bufferView")),
     "has no bufferView"),
    (dict(tweak=lambda b: b.json["meshes"][0]["primitives"][0]["extensions"][EXTENSION].update(bufferView=7)),
     r"bufferViews\[7\]"),
], ids=["vertex_count", "triangle_count", "index_count", "unknown_id", "bad_id", "not_listed", "width", "type",
        "strip", "no_view", "bad_view"])
def test_mismatched_files_are_refused_naming_file_and_primitive(tmp_path, kwargs, message):
    path = draco_glb(tmp_path / "box.glb", small_box(), **kwargs)
    with pytest.raises(AssetFormatError, match=f"box.glb: .*({message})"):
        load_gltf(path)


def test_decoded_values_must_fit_the_accessor_type(tmp_path):
    """The Duck's 2,399 vertices do not fit an indices accessor of unsigned bytes."""
    src = duck()
    raw = DracoPy.encode(src.positions, src.faces)
    path = draco_glb(tmp_path / "duck.glb", raw, tweak=lambda b: b.json["accessors"][-1].update(componentType=5121))
    with pytest.raises(AssetFormatError, match=r"duck.glb: the Draco data of indices of mesh 0 primitive 0 holds "
                                               r"values 0\.\.\d+, outside accessor \d+'s uint8"):
        load_gltf(path)


def test_limits_bound_the_declared_and_decoded_counts(tmp_path):
    path = draco_glb(tmp_path / "box.glb", small_box())
    with pytest.raises(AssetFormatError, match="max_triangles"):
        load_gltf(path, limits=pw.LoadLimits(max_triangles=11))
    assert len(load_gltf(path, limits=pw.LoadLimits(max_triangles=12)).primitives[0].faces) == 12


def varint(n: int) -> bytes:
    out = bytearray()
    while True:
        out.append((n & 0x7F) | (0x80 if n >> 7 else 0))
        n >>= 7
        if not n:
            return bytes(out)


@pytest.mark.parametrize("header, message", [
    (b"DRACO\x02\x02\x01\x01\x00\x00" + b"\x00" + varint(2**28) + varint(2**28) + b"\x01" + varint(2**28) + b"\x00",
     "declares 268435456 triangles, but its indices accessor declares 12"),
    (b"DRACO\x02\x02\x01\x00\x00\x00" + varint(12) + varint(2**28), "declares 268435456 points"),
    (b"DRACO\x02\x02\x01\x01\x00\x00" + b"\x00" + varint(8) + varint(12) + b"\x01" + varint(2**28) + b"\x00",
     "declares 268435456 symbols"),
    (b"DRACO\x02\x02\x00\x00\x00\x00", "not a triangle mesh"),
    (b"DRACO\x01\x02\x01\x00\x00\x00", "bitstream version 1.2"),
    (b"DRACO\x02\x02\x01\x00\x00\x80" + varint(2**20), "inside its header"),
    (b"DRACX\x02\x02\x01\x00\x00\x00", "does not start with b'DRACO'"),
], ids=["edgebreaker_faces", "sequential_points", "symbols", "point_cloud", "version", "metadata", "magic"])
def test_draco_header_counts_are_checked_before_decoding(tmp_path, header, message):
    """A stream declaring a mesh far larger than its accessors is refused from its header: the
    decoder would allocate by the declared counts (DracoPy turns 2^28 faces into MemoryError at
    best)."""
    raw = small_box()
    path = draco_glb(tmp_path / "box.glb", raw)
    data = bytearray(path.read_bytes())
    at = bytes(data).index(raw)
    forged = header + b"\0" * (len(raw) - len(header)) if len(header) <= len(raw) else header[:len(raw)]
    data[at:at + len(raw)] = forged
    path.write_bytes(bytes(data))
    with pytest.raises(AssetFormatError, match=f"box.glb: the {EXTENSION} data of mesh 0 primitive 0 .*{message}"):
        load_gltf(path)


def test_header_with_metadata_is_skipped_to_its_counts(tmp_path):
    """Geometry metadata (nested entries) before the connectivity header is walked over."""
    from pbrwarp.gltf_draco import _header_counts

    def element(entries, subs=()):
        out = varint(len(entries)) + b"".join(bytes([len(k)]) + k + bytes([len(v)]) + v for k, v in entries)
        return out + varint(len(subs)) + b"".join(bytes([len(k)]) + k + element(*sub) for k, sub in subs)

    nested = element([(b"name", b"duck")], [(b"child", ([(b"a", b"1")], [(b"grandchild", ([], []))])),
                                            (b"other", ([], []))])
    metadata = varint(1) + varint(3) + element([(b"k", b"v")]) + nested
    raw = b"DRACO\x02\x02\x01\x00\x00\x80" + metadata + varint(12) + varint(8) + b"\x00"
    assert _header_counts(raw) == (12, 8, "points")


# ---------------------------------------------------------------------------- hostile bytes

def test_truncated_and_random_draco_bytes_are_refused_without_crashing(tmp_path):
    """Truncations of a valid stream, bytes flipped inside it, and random bytes after a valid
    header: each file loads (when the damage decodes to a consistent mesh) or is refused with an
    AssetFormatError, in a child process that must exit normally (a crash in the decoder would
    kill it) under an address-space limit."""
    src = duck()
    raw = DracoPy.encode(src.positions, src.faces, normals=src.normals, tex_coord=src.uvs)
    rng = np.random.default_rng(30)
    variants = damaged_copies(raw, rng, header=16, copies=40)
    variants += [rng.integers(0, 256, len(raw), dtype=np.uint8).tobytes() for _ in range(5)]
    template = draco_glb(tmp_path / "template.glb", raw).read_bytes()
    at = template.index(raw)
    paths = []
    for i, variant in enumerate(variants):
        padded = variant + b"\0" * (len(raw) - len(variant))  # the bufferView keeps its length; its bytes change
        paths.append(tmp_path / f"hostile{i}.glb")
        paths[-1].write_bytes(template[:at] + padded + template[at + len(raw):])
    outcomes = load_each_in_child(paths)
    assert outcomes[str(paths[0])] == "refused"  # the empty stream


# ---------------------------------------------------------------------------- without DracoPy
@pytest.fixture
def no_dracopy(monkeypatch):
    """Import of DracoPy fails, as where the draco extra is not installed."""
    monkeypatch.setitem(sys.modules, "DracoPy", None)


def test_without_dracopy_a_compressed_only_primitive_names_the_install_command(tmp_path, no_dracopy):
    path = draco_glb(tmp_path / "box.glb", small_box())
    with pytest.raises(AssetFormatError, match=rf"box.glb: mesh 0 primitive 0 is compressed with {EXTENSION} and "
                                               r"has no uncompressed fallback; decoding it needs DracoPy: "
                                               + INSTALL.replace("[", r"\[").replace("]", r"\]")):
        pw.Scene.load(path)
    with pytest.raises(AssetFormatError, match="needs DracoPy"):
        pw.Scene.load(board("Box"))


def test_without_dracopy_the_fallback_is_read_with_a_warning(tmp_path, no_dracopy):
    raw = small_box()
    mesh = DracoPy.decode(raw)
    path = draco_glb(tmp_path / "box.glb", raw, required=False,
                     fallback={"POSITION": mesh.points.astype(np.float32), "indices": mesh.faces.astype(np.uint32)})
    with pytest.warns(UserWarning, match=rf"{EXTENSION} on mesh 'compressed' not decoded: DracoPy is not installed"):
        scene = pw.Scene.load(path)
    assert scene.triangle_count == 12
    assert len(scene.load_warnings) == 1 and INSTALL in scene.load_warnings[0]


def test_with_dracopy_the_compressed_data_wins_over_the_fallback(tmp_path):
    """The fallback holds the cube scaled by 2: the decoded (unscaled) cube is what loads."""
    raw = small_box()
    mesh = DracoPy.decode(raw)
    path = draco_glb(tmp_path / "box.glb", raw, required=False,
                     fallback={"POSITION": 2 * mesh.points.astype(np.float32), "indices": mesh.faces.astype(np.uint32)})
    scene = load_gltf(path)
    assert scene.load_warnings == ()
    np.testing.assert_allclose(np.abs(scene.primitives[0].positions), 1.0, atol=1e-3)
