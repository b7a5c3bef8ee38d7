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


# ---------------------------------------------------------------------------- AnisotropyRotationTest
def highlight_axis(image):
    """(angle in degrees of the highlight's long axis from image x, counter-clockwise as seen;
    its length over its width): the principal axes of the radiance-weighted second moments of
    the pixels above a tenth of the brightest."""
    w = np.where(image > 0.1 * image.max(), image, 0.0)
    ys, xs = np.mgrid[: image.shape[0], : image.shape[1]]
    dx, dy = xs - (w * xs).sum() / w.sum(), -(ys - (w * ys).sum() / w.sum())  # y up
    cxx, cyy, cxy = ((w * dx * dx).sum(), (w * dy * dy).sum(), (w * dx * dy).sum())
    angle = 0.5 * np.degrees(np.arctan2(2 * cxy, cxx - cyy))
    spread = np.sqrt(np.maximum(np.linalg.eigvalsh([[cxx, cxy], [cxy, cyy]]), 1e-12))
    return angle, spread[1] / spread[0]


def band_highlight(scene, node):
    """A band of AnisotropyRotationTest seen head-on from +z (its centre, where the band faces
    the camera), lit by a directional light along the view: the red channel of its highlight."""
    x, y, _ = {n["name"]: n for n in board_json("AnisotropyRotationTest")["nodes"]}[node]["translation"]
    camera = pw.Camera(eye=(x, y, 8.0), forward=(0, 0, -1), up=(0, 1, 0), fov_y=2 * np.degrees(np.arctan(0.6 / 7)))
    frame = pw.render(scene, camera, width=96, height=96, spp=4, shadows=False, progress=False)
    image = np.asarray(frame.rgb, np.float64)
    assert np.isfinite(image).all()
    return image[..., 0]


def anisotropy_board():
    scene = pw.Scene.load(board("AnisotropyRotationTest"))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=3.0))
    return scene


@pytest.mark.skipif("AnisotropyRotationTest" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
@pytest.mark.parametrize("node", ["Band 1L", "Band 2L", "Band 3L", "Band 4L", "Band 5L",
                                  "Band 1R", "Band 2R", "Band 3R", "Band 5R"])
def test_anisotropy_rotation_board_stretches_every_highlight_horizontally(node):
    """AnisotropyRotationTest: barrel-shaped bands of anisotropic metal (strength 0.5, roughness
    0.1) whose roughness is stretched along their horizontal tangents; three bands' tangents are
    tilted 30 degrees clockwise and turned back by anisotropyRotation (2L), the anisotropy
    texture (4L) or 10 + 20 degrees of both (2R). Its README: each should look like its plain
    neighbours, the highlight stretched horizontally. Here: every highlight's long axis (image
    moments) is within 5 degrees of horizontal, and at least 3 times its width."""
    angle, elongation = highlight_axis(band_highlight(anisotropy_board(), node))
    assert abs(angle) < 5.0 and elongation > 3.0, (angle, elongation)


@pytest.mark.skipif("AnisotropyRotationTest" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
def test_anisotropy_rotation_board_without_its_rotation_tilts_the_highlight():
    """The measurement sees a wrong direction: band 2L without its anisotropyRotation keeps the
    tangents' 30 degree tilt, and its highlight tilts with it (steeper on the barrel, whose
    vertical curvature is lower)."""
    scene = anisotropy_board()
    (material,) = {id(p.material): p.material for p in scene.primitives
                   if p.material.name == "Aniso Tan + Rotation"}.values()
    material.anisotropy_rotation = 0.0
    angle, elongation = highlight_axis(band_highlight(scene, "Band 2L"))
    assert abs(angle) > 20.0, (angle, elongation)


# ---------------------------------------------------------------------------- TextureTransformMultiTest
TRANSFORM_ROWS = ["BaseColor", "Emission", "Normal", "MetalRough", "Occlusion", "Unlit", "Clearcoat", "ClearcoatRough",
                  "ClearcoatNormal"]


def transform_board():
    """TextureTransformMultiTest under a uniform white environment only, so that a tile's
    shading depends on how far its normal map tilts the normal, not which way (the tangent frame
    a rotated normal texture is read in is left open by KHR_texture_transform:
    KhronosGroup/glTF-Sample-Viewer#592; pbrwarp does not turn it with the texture)."""
    scene = pw.Scene.load(board("TextureTransformMultiTest"))
    scene.environment = pw.Environment.uniform()
    return scene


def transform_tile(scene, node):
    """The luminance of a tile of TextureTransformMultiTest (0.2 wide), its inner 80% seen
    head-on from far away, 32 x 32 pixels."""
    x, y, _ = {n["name"]: n for n in board_json("TextureTransformMultiTest")["nodes"]}[node]["translation"]
    camera = pw.Camera(eye=(x, y, 10.0), forward=(0, 0, -1), up=(0, 1, 0), fov_y=2 * np.degrees(np.arctan(0.08 / 10.0)))
    frame = pw.render(scene, camera, width=32, height=32, spp=4, shadows=False, progress=False)
    lum = np.asarray(frame.rgb, np.float64) @ [0.2126, 0.7152, 0.0722]
    assert np.isfinite(lum).all()
    return lum


def correlation(a, b):
    return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])


@pytest.mark.skipif("TextureTransformMultiTest" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
@pytest.mark.parametrize("row", TRANSFORM_ROWS)
def test_texture_transform_board_rows_show_the_sample_checkmark(row):
    """TextureTransformMultiTest: per input (base colour, emission, normal, metal/roughness,
    occlusion, unlit, the clear coat's factor, roughness and normal), a tile reading TEXCOORD_0
    and one reading TEXCOORD_1 through KHR_texture_transform, beside a control tile whose own uvs
    show the checkmark untransformed. Its README: a correct render shows three tiles that look
    virtually identical (a missing or wrong transform shows a crossed-out circle or an X).
    Here: the control shows contrast, and both transformed tiles correlate with it (> 0.75; the
    board maps the control's checkmark about a pixel of these renders off the transformed ones',
    which caps the correlation near 0.9 on sharp edges)."""
    scene = transform_board()
    uv0, uv1, sample = (transform_tile(scene, row + column) for column in ("UV0", "UV1", "Sample"))
    assert sample.std() > 0.01 * sample.mean(), (sample.std(), sample.mean())
    assert correlation(uv0, sample) > 0.75 and correlation(uv1, sample) > 0.75, (correlation(uv0, sample),
                                                                                 correlation(uv1, sample))


@pytest.mark.skipif("TextureTransformMultiTest" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
def test_texture_transform_board_tiles_without_their_transform_fail_the_check():
    """The measurement sees a wrong transform: the base colour's UV 0 tile with its transform
    dropped shows the texture's crossed-out circle, and its UV 1 tile read with TEXCOORD_0 a
    blank corner; neither correlates with the control's checkmark."""
    scene = transform_board()
    sample = transform_tile(scene, "BaseColorSample")
    by_node = {p.name: p for p in scene.primitives}
    untransformed = by_node["BaseColorUV0"].material.base_color_texture
    untransformed.offset, untransformed.rotation, untransformed.scale = (0.0, 0.0), 0.0, (1.0, 1.0)
    by_node["BaseColorUV1"].material.base_color_texture.texcoord = 0
    assert correlation(transform_tile(scene, "BaseColorUV0"), sample) < 0.3
    uv1_on_uv0 = transform_tile(scene, "BaseColorUV1")
    assert uv1_on_uv0.std() < 0.01 * uv1_on_uv0.mean() or correlation(uv1_on_uv0, sample) < 0.3
