"""glTF geometry beyond triangle lists: fans, morph targets, skins, EXT_mesh_gpu_instancing and
KHR_mesh_quantization, each checked against the glTF 2.0 specification's formulas evaluated
here in NumPy on small files written by the test."""

import math
import warnings

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.gltf import _Document, load_gltf

from assets import board
from test_gltf import Builder


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def rotation_z(degrees):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], np.float64)


def translation(t):
    m = np.eye(4)
    m[:3, 3] = t
    return m


def quaternion_z(degrees):
    """glTF (x, y, z, w) of a rotation about +Z."""
    h = math.radians(degrees) / 2
    return [0.0, 0.0, math.sin(h), math.cos(h)]


def apply(matrix, points):
    return np.asarray(points, np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


# ---------------------------------------------------------------------------- triangle fans
FAN = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1.5, 0], [-1, 1, 0]], np.float32)


def fan_file(tmp_path, indices=None, name="fan.glb"):
    b = Builder()
    prim = {"attributes": {"POSITION": b.accessor(FAN, "VEC3")}, "mode": 6}
    if indices is not None:
        prim["indices"] = b.accessor(np.array(indices), "SCALAR", 5123)
    b.json["meshes"].append({"primitives": [prim]})
    b.node(mesh=0)
    return b, b.glb(tmp_path / name)


def fan_triangles(indices):
    """glTF 2.0 section 3.7.2.1: fan triangle i is (v[i + 1], v[i + 2], v[0])."""
    return np.array([[indices[i + 1], indices[i + 2], indices[0]] for i in range(len(indices) - 2)])


@pytest.mark.parametrize("indices", [None, [4, 3, 2, 1, 0], [2, 0, 1, 3]])
def test_fan_is_the_triangle_list_it_stands_for(tmp_path, indices):
    _, path = fan_file(tmp_path, indices)
    (prim,) = load_gltf(path).primitives
    order = list(range(len(FAN))) if indices is None else indices
    expected = fan_triangles(order)
    np.testing.assert_array_equal(prim.faces, expected)
    np.testing.assert_allclose(prim.positions[prim.faces], FAN.astype(np.float64)[expected])


def test_degenerate_fan_places_nothing(tmp_path):
    b = Builder()
    quad = b.quad()
    fan = {"attributes": {"POSITION": b.accessor(FAN[:2], "VEC3")}, "mode": 6}
    b.json["meshes"][quad]["primitives"].append(fan)
    b.node(mesh=quad)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing the file asks for is lost: a 2-vertex fan has no triangle
        content = load_gltf(b.glb(tmp_path / "degenerate.glb"))
    assert [len(p.faces) for p in content.primitives] == [2]


def test_fan_counts_against_the_triangle_limit(tmp_path):
    _, path = fan_file(tmp_path)
    with pytest.raises(pw.AssetFormatError, match="more than 2 triangles .LoadLimits.max_triangles"):
        load_gltf(path, limits=pw.LoadLimits(max_triangles=2))


# ---------------------------------------------------------------------------- morph targets
QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
RNG = np.random.default_rng(30)
DP = RNG.uniform(-0.5, 0.5, (2, 4, 3)).astype(np.float32)  # POSITION displacements of two targets
DN = RNG.uniform(-0.5, 0.5, (2, 4, 3)).astype(np.float32)  # NORMAL displacements


def morph_file(tmp_path, mesh_weights=None, node_weights=None, targets=None):
    """A quad with the two morph targets DP, DN, or those ``targets(builder)`` writes."""
    b = Builder()
    mesh = b.quad()
    if targets is None:
        targets = [{"POSITION": b.accessor(DP[t], "VEC3"), "NORMAL": b.accessor(DN[t], "VEC3")} for t in range(2)]
    else:
        targets = targets(b)
    b.json["meshes"][mesh]["primitives"][0]["targets"] = targets
    if mesh_weights is not None:
        b.json["meshes"][mesh]["weights"] = mesh_weights
    node = {"mesh": mesh}
    if node_weights is not None:
        node["weights"] = node_weights
    b.node(**node)
    return b.glb(tmp_path / "morph.glb")


@pytest.mark.parametrize("mesh_weights, node_weights, weights", [
    ([0.25, -0.5], None, [0.25, -0.5]),      # mesh.weights
    ([0.25, -0.5], [1.0, 0.75], [1.0, 0.75]),  # node.weights override them
    (None, None, [0.0, 0.0]),                # no weights: zeros
])
def test_morph_targets_at_default_weights(tmp_path, mesh_weights, node_weights, weights):
    (prim,) = load_gltf(morph_file(tmp_path, mesh_weights, node_weights)).primitives
    # glTF 2.0 "Morph Targets": attribute + sum of weight x displacement; normals renormalized.
    positions = QUAD + sum(w * DP[t].astype(np.float64) for t, w in enumerate(weights))
    normals = unit(np.array([0, 0, 1.0]) + sum(w * DN[t].astype(np.float64) for t, w in enumerate(weights)))
    np.testing.assert_allclose(prim.positions, positions, atol=1e-6)
    np.testing.assert_allclose(prim.normals, normals, atol=1e-6)


def test_morphed_tangents_keep_their_handedness(tmp_path):
    b = Builder()
    tangents = np.tile([1.0, 0.0, 0.0, -1.0], (4, 1)).astype(np.float32)
    dt = np.tile([0.0, 1.0, 0.0], (4, 1)).astype(np.float32)
    mesh = b.quad(TANGENT=b.accessor(tangents, "VEC4"))
    b.json["meshes"][mesh]["primitives"][0]["targets"] = [{"TANGENT": b.accessor(dt, "VEC3")}]
    b.json["meshes"][mesh]["weights"] = [1.0]
    b.node(mesh=mesh)
    (prim,) = load_gltf(b.glb(tmp_path / "tangent.glb")).primitives
    np.testing.assert_allclose(prim.tangents, np.tile([math.sqrt(0.5), math.sqrt(0.5), 0.0, -1.0], (4, 1)), atol=1e-6)


@pytest.mark.parametrize("mesh_weights, node_weights, message", [
    ([0.5], None, "mesh 0 has 1 morph weights, but mesh 0 primitive 0 has 2 morph targets"),
    ([0.5, 0.5], [1.0, 2.0, 3.0], "node 0 has 3 morph weights, but mesh 0 primitive 0 has 2 morph targets"),
    ([0.5, float("nan")], None, "must be 2 finite numbers"),
])
def test_morph_weight_mismatch_is_a_clear_error(tmp_path, mesh_weights, node_weights, message):
    with pytest.raises(pw.AssetFormatError, match=message):
        load_gltf(morph_file(tmp_path, mesh_weights, node_weights))


def test_one_accessor_named_by_many_targets_is_read_within_the_vertex_limit(tmp_path):
    """Targets may share an accessor, so what morphing reads is not bounded by the file's size:
    it counts against LoadLimits.max_vertices before each displacement is read."""
    path = morph_file(tmp_path, [1.0] * 1000, targets=lambda b: [{"POSITION": b.accessor(DP[0], "VEC3")}] * 1000)
    (prim,) = load_gltf(path).primitives
    np.testing.assert_allclose(prim.positions, QUAD + 1000 * DP[0].astype(np.float64), rtol=1e-9, atol=1e-9)
    with pytest.raises(pw.AssetFormatError, match="reads more than the 3999 vertex values of LoadLimits.max_vertices; "
                                                  "the limit is passed at POSITION of mesh 0 primitive 0 morph target 999"):
        load_gltf(path, limits=pw.LoadLimits(max_vertices=3999))


def test_morph_target_of_a_missing_attribute_or_count_is_an_error(tmp_path):
    with pytest.raises(pw.AssetFormatError, match="TANGENT of mesh 0 primitive 0 morph target 0 displaces an attribute"):
        load_gltf(morph_file(tmp_path, [1.0], targets=lambda b: [{"TANGENT": b.accessor(DP[0], "VEC3")}]))
    with pytest.raises(pw.AssetFormatError, match="4 positions but 3 displacements"):
        load_gltf(morph_file(tmp_path, [1.0], targets=lambda b: [{"POSITION": b.accessor(DP[0][:3], "VEC3")}]))


# ---------------------------------------------------------------------------- skins
# Two joints: joint 0 at the origin, joint 1 its child one unit up, bent 90 degrees about +Z.
# The bind pose has both unrotated, so the inverse bind matrices are I and T(0, -1, 0).
SKIN_POSITIONS = np.array([[0.1, 0.5, 0], [0.1, 1.5, 0], [0, 2, 0], [-0.1, 1, 0]], np.float32)
SKIN_NORMALS = np.array([[0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0]], np.float32)
SKIN_JOINTS = np.array([[0, 1, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 1, 0, 0]])
SKIN_WEIGHTS = np.array([[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0, 0], [0.25, 0.75, 0, 0]], np.float32)


def skin_file(tmp_path, joints=SKIN_JOINTS, inverse_bind=True, mesh_node=None, weights=(SKIN_WEIGHTS, 5126, False)):
    b = Builder()
    attrs = {"POSITION": b.accessor(SKIN_POSITIONS, "VEC3"), "NORMAL": b.accessor(SKIN_NORMALS, "VEC3"),
             "JOINTS_0": b.accessor(joints, "VEC4", 5121),
             "WEIGHTS_0": b.accessor(weights[0], "VEC4", weights[1], normalized=weights[2])}
    indices = b.accessor(np.array([0, 1, 2, 0, 2, 3]), "SCALAR", 5123)
    b.json["meshes"].append({"primitives": [{"attributes": attrs, "indices": indices}]})
    b.json["nodes"] = [{"children": [1]}, {"translation": [0, 1, 0], "rotation": quaternion_z(90)},
                       {"mesh": 0, "skin": 0, **(mesh_node or {})}]
    b.json["scenes"][0]["nodes"] = [0, 2]
    skin = {"joints": [0, 1]}
    if inverse_bind:
        ibm = np.stack([np.eye(4), translation([0, -1, 0])])
        skin["inverseBindMatrices"] = b.accessor(ibm.transpose(0, 2, 1).reshape(2, 16), "MAT4")  # column-major
    b.json["skins"] = [skin]
    return b.glb(tmp_path / "skin.glb")


def expected_skin(joint_matrices, weights=SKIN_WEIGHTS):
    """glTF 2.0 "Skinned Mesh Attributes": vertex = sum_i w_i M_{j_i} v, normals by the inverse
    transpose of that blended matrix."""
    positions, normals = [], []
    for v, n, j, w in zip(SKIN_POSITIONS, SKIN_NORMALS, SKIN_JOINTS, weights):
        m = sum(float(wi) * joint_matrices[ji] for ji, wi in zip(j, w))
        positions.append(apply(m, [v])[0])
        normals.append(unit(np.linalg.inv(m[:3, :3]).T @ n))
    return np.array(positions), np.array(normals)


@pytest.mark.parametrize("mesh_node", [None, {"translation": [5, 5, 5], "scale": [2, 2, 2]}])
def test_two_joint_bend_poses_vertices_by_the_spec_formula(tmp_path, mesh_node):
    """The skinned mesh node's own transform is ignored (glTF 2.0 "Joint Hierarchy")."""
    (prim,) = load_gltf(skin_file(tmp_path, mesh_node=mesh_node)).primitives
    joint1 = translation([0, 1, 0]) @ rotation_z(90)
    positions, normals = expected_skin([np.eye(4), joint1 @ translation([0, -1, 0])])
    np.testing.assert_allclose(prim.positions, positions, atol=1e-6)
    np.testing.assert_allclose(prim.normals, normals, atol=1e-6)
    # By hand: vertex 1, on joint 1 alone, turns about (0, 1, 0): (0.1, 1.5) -> (-0.5, 1.1).
    np.testing.assert_allclose(prim.positions[1], [-0.5, 1.1, 0.0], atol=1e-6)
    np.testing.assert_allclose(prim.normals[1], [0.0, 1.0, 0.0], atol=1e-6)
    # Vertex 2, half on each: the mean of (0, 2) and its image (-1, 1).
    np.testing.assert_allclose(prim.positions[2], [-0.5, 1.5, 0.0], atol=1e-6)


def test_skin_without_inverse_bind_matrices_uses_identity(tmp_path):
    (prim,) = load_gltf(skin_file(tmp_path, inverse_bind=False)).primitives
    positions, _ = expected_skin([np.eye(4), translation([0, 1, 0]) @ rotation_z(90)])
    np.testing.assert_allclose(prim.positions, positions, atol=1e-6)


def test_normalized_byte_weights_decode_and_unnormalized_ones_are_refused(tmp_path):
    quantized = np.round(SKIN_WEIGHTS * 255).astype(np.uint8)
    (prim,) = load_gltf(skin_file(tmp_path, weights=(quantized, 5121, True))).primitives
    joint1 = translation([0, 1, 0]) @ rotation_z(90)
    positions, _ = expected_skin([np.eye(4), joint1 @ translation([0, -1, 0])], quantized / 255.0)
    np.testing.assert_allclose(prim.positions, positions, atol=1e-6)
    with pytest.raises(pw.AssetFormatError, match="WEIGHTS_0 of mesh 0 primitive 0 must be floats or normalized"):
        load_gltf(skin_file(tmp_path, weights=(quantized, 5121, False)))


@pytest.mark.parametrize("edit, message", [
    (lambda j: j["scenes"][0].update(nodes=[2]), "skin 0 joint node 0 is not in the scene being loaded"),
    (lambda j: j["skins"][0].update(joints=[]), "skin 0 has no joints"),
    (lambda j: j["accessors"][j["skins"][0]["inverseBindMatrices"]].update(count=1),
     "inverseBindMatrices of skin 0 must be 2 or more float MAT4 matrices, got 1"),
    (lambda j: j["meshes"][0]["primitives"][0]["attributes"].pop("WEIGHTS_0"), "has only one of JOINTS_0 and WEIGHTS_0"),
    (lambda j: [j["meshes"][0]["primitives"][0]["attributes"].pop(k) for k in ("JOINTS_0", "WEIGHTS_0")],
     "is on a node with a skin but has no JOINTS_0 and WEIGHTS_0"),
])
def test_inconsistent_skins_are_clear_errors(tmp_path, edit, message):
    doc = _Document(str(skin_file(tmp_path)))
    edit(doc.json)
    b = Builder()
    b.json, b.bin = doc.json, bytearray(doc.glb_bin)
    with pytest.raises(pw.AssetFormatError, match=message):
        load_gltf(b.glb(tmp_path / "edited.glb"))


def test_joint_index_outside_the_skin_is_refused(tmp_path):
    joints = SKIN_JOINTS.copy()
    joints[3, 1] = 7
    with pytest.raises(pw.AssetFormatError, match="JOINTS_0 of mesh 0 primitive 0 names joint 7, but its skin has 2"):
        load_gltf(skin_file(tmp_path, joints=joints))


# ---------------------------------------------------------------------------- EXT_mesh_gpu_instancing
def instanced_file(tmp_path, t, r=None, s=None, node=None, extra=None):
    b = Builder()
    mesh = b.quad()
    attrs = {"TRANSLATION": b.accessor(np.asarray(t, np.float32), "VEC3")}
    if r is not None:
        attrs["ROTATION"] = b.accessor(np.asarray(r, np.float32), "VEC4")
    if s is not None:
        attrs["SCALE"] = b.accessor(np.asarray(s, np.float32), "VEC3")
    attrs.update(extra or {})
    b.node(mesh=mesh, extensions={"EXT_mesh_gpu_instancing": {"attributes": attrs}}, **(node or {}))
    b.json["extensionsUsed"] = b.json["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    return b, b.glb(tmp_path / "instanced.glb")


def test_instances_are_copies_at_their_trs_before_the_node_transform(tmp_path):
    t = [[0, 0, 0], [2, 0, 0], [0, 3, 0]]
    r = [[0, 0, 0, 1], quaternion_z(90), quaternion_z(180)]
    s = [[1, 1, 1], [2, 2, 2], [1, 0.5, 1]]
    _, path = instanced_file(tmp_path, t, r, s, node={"translation": [0, 0, 10]})
    prims = load_gltf(path).primitives
    assert len(prims) == 3 and [p.name for p in prims] == ["0#0", "0#1", "0#2"]
    for k, prim in enumerate(prims):
        local = translation(t[k]) @ rotation_z(90 * k) @ np.diag([*s[k], 1.0])
        np.testing.assert_allclose(prim.positions, apply(translation([0, 0, 10]) @ local, QUAD), atol=1e-6)
        np.testing.assert_array_equal(prim.faces, [[0, 1, 2], [0, 2, 3]])


def test_quantized_instance_rotations_decode(tmp_path):
    """EXT_mesh_gpu_instancing allows normalized signed shorts for ROTATION."""
    b = Builder()
    mesh = b.quad()
    q = np.round(np.array([[0, 0, 0, 1], quaternion_z(90)]) * 32767).astype(np.int16)
    attrs = {"TRANSLATION": b.accessor(np.zeros((2, 3), np.float32), "VEC3"),
             "ROTATION": b.accessor(q, "VEC4", 5122, normalized=True)}
    b.node(mesh=mesh, extensions={"EXT_mesh_gpu_instancing": {"attributes": attrs}})
    prims = load_gltf(b.glb(tmp_path / "rotations.glb")).primitives
    np.testing.assert_allclose(prims[1].positions, apply(rotation_z(90), QUAD), atol=1e-4)


def test_instance_count_is_checked_against_the_limits_before_reading(tmp_path, monkeypatch):
    n = 1 << 24  # zeros without a bufferView: no bytes in the file, 400 MB as float64 matrices
    b, _ = instanced_file(tmp_path, [[0, 0, 0]])
    b.json["accessors"].append({"componentType": 5126, "type": "VEC3", "count": n})
    b.json["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"] = len(b.json["accessors"]) - 1
    path = b.glb(tmp_path / "many.glb")
    read = []
    original = _Document.accessor
    monkeypatch.setattr(_Document, "accessor", lambda self, index, *a, **k: read.append(index) or original(self, index, *a, **k))
    with pytest.raises(pw.AssetFormatError, match="node 0 places 16777216 EXT_mesh_gpu_instancing instances, "
                                                  "more than the 65536 of LoadLimits.max_instances"):
        load_gltf(path)
    assert read == []  # refused from the JSON, before any accessor was read
    # The same copies of a mesh that has no primitives to copy are refused too.
    b.json["meshes"][0]["primitives"] = []
    with pytest.raises(pw.AssetFormatError, match="LoadLimits.max_instances"):
        load_gltf(b.glb(tmp_path / "empty.glb"))
    assert read == []


def test_instances_count_against_the_triangle_limit(tmp_path):
    _, path = instanced_file(tmp_path, [[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    assert len(load_gltf(path, limits=pw.LoadLimits(max_triangles=6)).primitives) == 3
    with pytest.raises(pw.AssetFormatError, match="more than 5 triangles .LoadLimits.max_triangles"):
        load_gltf(path, limits=pw.LoadLimits(max_triangles=5))


def test_instancing_attributes_of_different_counts_are_an_error(tmp_path):
    _, path = instanced_file(tmp_path, [[0, 0, 0], [1, 0, 0]], s=[[1, 1, 1]])
    with pytest.raises(pw.AssetFormatError, match="EXT_mesh_gpu_instancing attributes have different counts"):
        load_gltf(path)


# ---------------------------------------------------------------------------- KHR_mesh_quantization
def test_quantized_attributes_decode_to_their_float_values(tmp_path):
    b = Builder()
    ints = np.array([[0, 0, 0], [32767, 0, 0], [32767, 16384, -32768], [0, 32767, -100]], np.int16)
    normals = np.array([[0, 0, 127]] * 3 + [[0, 90, 90]], np.int8)
    uvs = np.array([[0, 1], [3, 1], [3, 0], [0, 0]], np.uint8)
    attrs = {"POSITION": b.accessor(ints, "VEC3", 5122, normalized=True),
             "NORMAL": b.accessor(normals, "VEC3", 5120, normalized=True),
             "TEXCOORD_0": b.accessor(uvs, "VEC2", 5121)}
    b.json["meshes"].append({"primitives": [{"attributes": attrs, "indices": b.accessor(np.array([0, 1, 2, 0, 2, 3]), "SCALAR", 5123)}]})
    b.node(mesh=0)
    b.json["extensionsUsed"] = b.json["extensionsRequired"] = ["KHR_mesh_quantization"]
    (prim,) = load_gltf(b.glb(tmp_path / "quantized.glb")).primitives
    # glTF 2.0 section 3.11 (normalized integers): f = max(c / 32767, -1) for signed shorts.
    np.testing.assert_allclose(prim.positions, np.maximum(ints / 32767.0, -1.0), atol=1e-7)
    assert prim.positions[2, 2] == -1.0
    np.testing.assert_allclose(prim.normals, unit(np.maximum(normals / 127.0, -1.0)), atol=1e-6)
    np.testing.assert_allclose(prim.uvs, uvs.astype(np.float64))


# ---------------------------------------------------------------------------- the Khronos test boards
def test_sample_mesh_primitive_modes_fan_and_strip_load():
    path = board("MeshPrimitiveModes")
    doc = _Document(str(path))
    with warnings.catch_warnings(record=True):  # points and lines: tests/test_gltf_unhonoured.py
        warnings.simplefilter("always")
        prims = load_gltf(path).primitives
    expected = []
    for mesh in doc.json["meshes"]:
        prim = mesh["primitives"][0]
        count = doc.json["accessors"][prim["indices"]]["count"]
        expected += {4: [count // 3], 5: [count - 2], 6: [count - 2]}.get(prim.get("mode", 4), [])
    assert sorted(len(p.faces) for p in prims) == sorted(expected) and len(expected) == 3


def test_sample_morph_primitives_plane_is_displaced_at_half_strength():
    """README: mesh.weights [0.5] raises the centre of each quadrant by half its target."""
    path = board("MorphPrimitivesTest")
    doc = _Document(str(path))
    (mesh,) = doc.json["meshes"]
    prims = load_gltf(path).primitives
    assert mesh["weights"] == [0.5] and len(prims) == 2
    for prim, spec in zip(prims, mesh["primitives"]):
        lift = doc.json["accessors"][spec["targets"][0]["POSITION"]]["max"][1]
        base = doc.json["accessors"][spec["attributes"]["POSITION"]]["max"][1]
        assert prim.positions[:, 1].max() == pytest.approx(base + 0.5 * lift, abs=1e-6)


def test_sample_quantized_morph_cube_spans_its_dequantized_box():
    """AnimatedMorphCube/glTF-Quantized requires KHR_mesh_quantization: unsigned-short positions
    that the node's scale dequantizes to the 2 x 2 x 2 cube of the float version."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (prim,) = load_gltf(board("AnimatedMorphCube")).primitives
    extent = prim.positions.max(axis=0) - prim.positions.min(axis=0)
    np.testing.assert_allclose(np.sort(extent), [2.0, 2.0, 2.0], rtol=1e-3)
