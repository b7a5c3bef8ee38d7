"""The Khronos test boards (tests/assets/gltf-ext/): per board, the property its README describes."""

import json
import struct

import numpy as np
import pytest

import pbrwarp as pw

from assets import BOARDS, board

def board_json(name):
    """The JSON chunk of the test board ``name``'s .glb."""
    raw = board(name).read_bytes()
    length, = struct.unpack_from("<I", raw, 12)
    return json.loads(raw[20:20 + length])


EMISSIVE = np.array([0.1, 0.5, 0.9])  # every cube's emissiveFactor in EmissiveStrengthTest


@pytest.mark.parametrize("cube, x, strength", [("Cube1", -6.0, 1.0), ("Cube2", -3.0, 2.0), ("Cube4", 0.0, 4.0),
                                               ("Cube8", 3.0, 8.0), ("Cube16", 6.0, 16.0)])
def test_emissive_strength_board_cubes_double_left_to_right(cube, x, strength):
    """EmissiveStrengthTest: five black cubes emitting (0.1, 0.5, 0.9) times 1, 2, 4, 8 and 16
    (KHR_materials_emissive_strength; the leftmost has no extension). Unlit by any light, a
    cube's face seen head-on has exactly that radiance, in nits."""
    scene = pw.Scene.load(board("EmissiveStrengthTest"))
    camera = pw.Camera.look_at(eye=(x, 0.0, 10.0), target=(x, 0.0, 0.0), fov_y=5.0)
    frame = pw.render(scene, camera, width=8, height=8, shadows=False, progress=False)
    np.testing.assert_allclose(frame.rgb[2:6, 2:6], np.broadcast_to(EMISSIVE * strength, (4, 4, 3)), rtol=1e-5)


SPECULAR_BOARD_ROOT = np.array([0.325, 0.0, 0.0])  # SampleRoot's translation; the spheres are its children


@pytest.mark.parametrize("node, f0", [
    ("1.1_specularFactor", (0.0, 0.0, 0.0)),                 # specular 0: perfectly black
    ("1.4_specularFactor", (0.04 * 0.520996,) * 3),         # f0 = 0.04 specularFactor
    ("1.5_specularFactor", (0.04,) * 3),
    ("3.3_whiteColorFactor", (0.04 * 0.212231,) * 3),       # f0 = 0.04 specularColorFactor
    ("5.4_yellowColorFactor", (0.04 * 0.520996, 0.04 * 0.520996, 0.0)),  # tinted yellow
    ("7.4_HDR_colorFactor", (0.04 * 13.276,) * 3),          # colour factor above 1: f0 = 0.531
    ("7.5_HDR_colorFactor", (1.0, 1.0, 1.0)),               # 0.04 x 25 clamped to 1: a mirror
])
def test_specular_board_spheres_reflect_their_f0_head_on(node, f0):
    """SpecularTest: black, smooth dielectric spheres whose KHR_materials_specular factor or colour
    sets f0 = min(0.04 specularColorFactor, 1) specularFactor (ior 1.5). In a uniform white
    environment of radiance 1 nit a sphere's centre, seen head-on, reflects the environment by
    Fresnel at normal incidence: radiance f0."""
    scene = pw.Scene.load(board("SpecularTest"))
    scene.environment = pw.Environment.uniform()
    nodes = {n["name"]: n for n in board_json("SpecularTest")["nodes"]}
    centre = SPECULAR_BOARD_ROOT + np.array(nodes[node]["translation"])
    camera = pw.Camera.look_at(eye=tuple(centre + (0.0, 0.0, 1.0)), target=tuple(centre), fov_y=0.5)
    frame = pw.render(scene, camera, width=4, height=4, shadows=False, progress=False)
    np.testing.assert_allclose(frame.rgb[1:3, 1:3], np.broadcast_to(f0, (2, 2, 3)), rtol=0.02, atol=2e-4)


def gltf_floats(name, accessor):
    """Accessor ``accessor`` of a board's .gltf read as float32 rows, by NumPy from the JSON's
    bufferView and the .bin file it names (tightly packed, no stride: these boards' layout)."""
    path = board(name)
    spec = json.loads(path.read_text())
    acc = spec["accessors"][accessor]
    view = spec["bufferViews"][acc["bufferView"]]
    data = (path.parent / spec["buffers"][view["buffer"]]["uri"]).read_bytes()
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return spec, np.frombuffer(data, np.float32, acc["count"] * width, start).reshape(acc["count"], width)


def test_sparse_accessor_board_raises_three_vertices_of_the_top_row():
    """SimpleSparseAccessor: a strip of 14 vertices, (x, 0) and (x, 1) for x = 0..6, whose
    POSITION accessor's sparse part substitutes 3 of them (its README's figure): the loaded mesh
    holds the base grid with exactly those three replaced, raised above the top row."""
    spec, base = gltf_floats("SimpleSparseAccessor", 1)
    sparse = spec["accessors"][1]["sparse"]
    data = (board("SimpleSparseAccessor").parent / spec["buffers"][0]["uri"]).read_bytes()
    views = spec["bufferViews"]
    indices = np.frombuffer(data, np.uint16, sparse["count"], views[sparse["indices"]["bufferView"]]["byteOffset"])
    values = np.frombuffer(data, np.float32, sparse["count"] * 3,
                           views[sparse["values"]["bufferView"]]["byteOffset"]).reshape(-1, 3)
    expected = base.astype(np.float64).copy()
    expected[indices] = values
    (prim,) = pw.Scene.load(board("SimpleSparseAccessor")).primitives
    np.testing.assert_array_equal(prim.positions, expected)
    changed = np.flatnonzero(np.any(prim.positions != base, axis=1))
    assert changed.tolist() == sorted(indices.tolist()) and len(changed) == 3
    assert np.all(prim.positions[changed, 1] > 1.0)


def test_simple_skin_board_at_its_stored_pose_is_its_bind_pose():
    """SimpleSkin: a strip of 10 vertices skinned to two joints; the animation bends it, but the
    nodes store the bind pose (joint 1 at (0, 1, 0), its inverse bind matrix the translation by
    (0, -1, 0)), so every joint matrix, world times inverse bind, is the identity and the static
    pose viewers show without playing the animation is the mesh as stored."""
    spec, positions = gltf_floats("SimpleSkin", 1)
    _, inverse_bind = gltf_floats("SimpleSkin", spec["skins"][0]["inverseBindMatrices"])
    worlds = [np.eye(4), np.eye(4)]
    worlds[1][:3, 3] = spec["nodes"][2]["translation"]
    for world, ibm in zip(worlds, inverse_bind):
        np.testing.assert_allclose(world @ ibm.reshape(4, 4).T, np.eye(4), atol=1e-6)
    with pytest.warns(UserWarning, match="animation"):
        (prim,) = pw.Scene.load(board("SimpleSkin")).primitives
    np.testing.assert_allclose(prim.positions, positions, atol=1e-6)


@pytest.mark.skipif("RecursiveSkeletons" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
def test_recursive_skeletons_board_places_one_mesh_by_84_skins():
    """RecursiveSkeletons: one mesh bound by 84 skins to four skeletons (its README): 84 posed
    copies of the mesh's 40 vertices, no two the same, every vertex finite; only the animation
    is warned about."""
    with pytest.warns(UserWarning, match="animation") as caught:
        scene = pw.Scene.load(board("RecursiveSkeletons"))
    assert len(caught) == 1
    prims = scene.primitives
    assert len(prims) == 84 and {len(p.positions) for p in prims} == {40}
    assert all(np.isfinite(p.positions).all() for p in prims)
    assert len({p.positions.round(5).tobytes() for p in prims}) == 84
