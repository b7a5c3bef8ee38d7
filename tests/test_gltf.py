"""glTF loading: the Khronos sample models in the test assets and small files written here."""

import base64
import json
import math
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from pbrwarp.camera import Camera
from pbrwarp.errors import AssetFormatError, AssetNotFoundError
from pbrwarp.gltf import _Document, _scene_nodes, load_gltf
from pbrwarp.lights import DirectionalLight, PointLight, SpotLight
from pbrwarp.scene import Scene
from pbrwarp.tangents import generate_tangents

from assets import ASSETS

GLTF = ASSETS / "gltf"

# SOURCES.md: triangles after node instancing.
TRIANGLES = {
    "NormalTangentMirrorTest": 5240, "NormalTangentTest": 7774, "MetalRoughSpheresNoTextures": 1040409,
    "TextureCoordinateTest": 10, "WaterBottle": 4510, "Suzanne": 3936, "Duck": 4212, "OrientationTest": 524,
    "TextureSettingsTest": 72, "NegativeScaleTest": 7724, "TextureEncodingTest": 3844, "TwoSidedPlane": 2,
    "BoxTextured": 12,
}


def model_path(name):
    if not GLTF.is_dir():
        pytest.skip(f"test assets not found at {GLTF}")
    found = sorted((GLTF / name).glob("glTF*/*.gl[tb]*"))
    if not found:
        pytest.skip(f"{name} not found in {GLTF}")
    return found[0]


@pytest.fixture(scope="module")
def model():
    """Load each sample model once per module (the shared set's 2048² textures take a while to decode)."""
    cache = {}

    def load(name):
        if name not in cache:
            cache[name] = load_gltf(model_path(name))
        return cache[name]

    return load


# ---------------------------------------------------------------------------- sample models
def test_every_sample_model_loads_with_sourced_triangle_counts(model):
    if not GLTF.is_dir():
        pytest.skip(f"test assets not found at {GLTF}")
    names = sorted(p.name for p in GLTF.iterdir() if p.is_dir() and p.name != "LICENSES")
    assert set(names) == set(TRIANGLES), "SOURCES.md table and the gltf/ folder disagree"
    for name in names:
        content = model(name)
        assert sum(len(p.faces) for p in content.primitives) == TRIANGLES[name], name
        for prim in content.primitives:
            assert np.all(np.isfinite(prim.positions))
            if prim.tangents is not None:
                assert prim.uvs is not None


@pytest.mark.parametrize("name, vertices, mirrored, perpendicular", [
    ("NormalTangentMirrorTest", 2770, 80, 1.0),
    ("WaterBottle", 2549, 82, 0.98),  # 47 vertices where every face has zero UV area carry (1, 0, 0)
    ("TwoSidedPlane", 6, 0, 1.0),
    ("Suzanne", 11808, 0, None),  # its tangents are not orthogonalised against the normals
])
def test_supplied_tangents_unit_perpendicular_with_sourced_handedness(model, name, vertices, mirrored, perpendicular):
    prim, = model(name).primitives
    t, n = prim.tangents, prim.normals
    assert t is not None and len(t) == vertices
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-6)
    if perpendicular is not None:
        assert np.mean(np.abs(np.sum(t[:, :3] * n, axis=1)) < 1e-3) >= perpendicular
    assert set(np.unique(t[:, 3])) <= {-1.0, 1.0}
    assert int(np.sum(t[:, 3] < 0)) == mirrored


def test_generated_tangents_reproduce_mikktspace_tangents_of_mirror_test(model):
    """NormalTangentMirrorTest's supplied tangents came from MikkTSpace: regenerating them from
    positions, normals and UVs must agree in direction and in handedness at every vertex."""
    prim, = model("NormalTangentMirrorTest").primitives
    generated = generate_tangents(prim.positions, prim.normals, prim.uvs, prim.faces)
    assert np.all(generated[:, 3] == prim.tangents[:, 3])
    assert np.min(np.sum(generated[:, :3] * prim.tangents[:, :3], axis=1)) > 0.9999


def test_normal_tangent_test_gets_generated_tangents_along_du(model):
    """No TANGENT in the file: tangents are generated. Checked against the UV gradient of each
    flat face: t must keep glTF v constant, increase u, and cross(n, t) * w must point along
    decreasing v (up the image, where the normal map's green channel points)."""
    prim, = model("NormalTangentTest").primitives
    t, n = prim.tangents, prim.normals
    assert t is not None
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-9)
    assert np.max(np.abs(np.sum(t[:, :3] * n, axis=1))) < 1e-9
    p, f, uv = prim.positions, prim.faces, prim.uvs
    e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
    face_n = np.cross(e1, e2)
    face_n /= np.linalg.norm(face_n, axis=1, keepdims=True)
    gram = np.stack([np.stack([np.sum(e1 * e1, 1), np.sum(e1 * e2, 1)], -1),
                     np.stack([np.sum(e1 * e2, 1), np.sum(e2 * e2, 1)], -1)], -1)
    d_uv = np.stack([uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]], 1)  # (F, 2 edges, 2)
    coef = np.linalg.solve(gram, d_uv)  # in-plane gradients as combinations of e1, e2
    grad_u = coef[:, 0, 0:1] * e1 + coef[:, 1, 0:1] * e2
    grad_v = coef[:, 0, 1:2] * e1 + coef[:, 1, 1:2] * e2
    # Corners of flat regions: the vertex normal equals the face normal.
    corner_v = f.ravel()
    corner_f = np.repeat(np.arange(len(f)), 3)
    flat = np.sum(n[corner_v] * face_n[corner_f], axis=1) > 0.9999
    assert flat.sum() > 1000
    tv, fv = t[corner_v[flat]], corner_f[flat]
    gu, gv = grad_u[fv], grad_v[fv]
    assert np.all(np.sum(tv[:, :3] * gu, axis=1) > 0)
    v_change = np.abs(np.sum(tv[:, :3] * gv, axis=1)) / np.linalg.norm(gv, axis=1)
    assert np.mean(v_change < 1e-3) > 0.95
    bitangent = np.cross(n[corner_v[flat]], tv[:, :3]) * tv[:, 3:]
    assert np.mean(np.sum(bitangent * gv, axis=1) < 0) > 0.99


def test_texture_settings_samplers(model):
    wraps = {p.material.name: (p.material.base_color_texture.wrap_s, p.material.base_color_texture.wrap_t)
             for p in model("TextureSettingsTest").primitives if p.material.base_color_texture is not None}
    assert wraps["TextureMirrorMaterialT"] == ("repeat", "mirror")
    assert wraps["TextureMirrorMaterialS"] == ("mirror", "repeat")
    assert wraps["TextureClampMaterialT"] == ("repeat", "clamp")
    assert wraps["TextureClampMaterialS"] == ("clamp", "repeat")
    assert wraps["DoubleSidedMaterial"] == ("repeat", "repeat")
    sided = {p.material.name: p.material.double_sided for p in model("TextureSettingsTest").primitives}
    assert sided["DoubleSidedMaterial"] is True and sided["SingleSidedMaterial"] is False


def test_textures_shared_when_image_and_sampler_match(model):
    by_name = {p.material.name: p.material for p in model("TextureSettingsTest").primitives}
    assert by_name["DoubleSidedMaterial"].base_color_texture is by_name["SingleSidedMaterial"].base_color_texture
    mat = model("WaterBottle").primitives[0].material
    assert mat.occlusion_texture is mat.metallic_roughness_texture  # packed ORM, decoded once
    from PIL import Image

    with Image.open(model_path("WaterBottle").parent / "WaterBottle_normal.png") as normal_map:
        assert mat.normal_texture.shape == normal_map.size[::-1]  # decoded at the file's full size
    assert mat.emissive_texture is not None and mat.emissive == (1.0, 1.0, 1.0)
    for slot, tex, _ in mat.textures():
        assert tex.srgb is None, slot


def test_uvs_use_gltf_convention(model):
    """TextureCoordinateTest: the quad at the top left of the scene shows the top left of the
    image, i.e. glTF UVs near (0, 0), not trimesh's flipped ones."""
    quads = {p.name: p for p in model("TextureCoordinateTest").primitives if p.uvs is not None}
    corners = [("TopLeftObj", (-1, 1), (0, 0)), ("TopRightObj", (1, 1), (0.6, 0)),
               ("BottomLeftObj", (-1, -1), (0, 0.6)), ("BottomRightObj", (1, -1), (0.6, 0.6))]
    for name, (sx, sy), (u_lo, v_lo) in corners:
        prim = quads[name]
        centre = prim.positions.mean(axis=0)
        assert np.sign(centre[0]) == sx and np.sign(centre[1]) == sy
        np.testing.assert_allclose(prim.uvs.min(axis=0), (u_lo, v_lo), atol=1e-6)
        np.testing.assert_allclose(prim.uvs.max(axis=0), (u_lo + 0.4, v_lo + 0.4), atol=1e-6)


def test_negative_scale_keeps_winding_and_normals_consistent(model):
    prims = model("NegativeScaleTest").primitives
    scene = trimesh.load(model_path("NegativeScaleTest"), force="scene")
    mirrored = [p for p in prims if np.linalg.det(scene.graph[p.name][0][:3, :3]) < 0]
    assert len(mirrored) == 4
    for prim in prims:
        p, f = prim.positions, prim.faces
        geometric = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
        shading = prim.normals[f].sum(axis=1)
        assert np.mean(np.sum(geometric * shading, axis=1) > 0) > 0.95, prim.name


def test_orientation_test_arrows_point_at_their_targets(model):
    """Each arrow's long axis (after its node rotation, by quaternion or by matrix) must pass
    through the target of the same colour; a transposed rotation misses by about a unit."""
    prims = {p.name: p for p in model("OrientationTest").primitives}
    for axis in ("X1", "X2", "Y1", "Y2", "Z1", "Z2"):
        arrow = prims["Arrow" + axis].positions
        target = prims["Target" + axis].positions.mean(axis=0)
        centre = arrow.mean(axis=0)
        direction = np.linalg.svd(arrow - centre)[2][0]
        offset = target - centre
        miss = np.linalg.norm(offset - direction * np.dot(offset, direction))
        assert miss < 0.1, axis


def test_node_world_matrices_agree_with_trimesh():
    path = model_path("OrientationTest")
    scene = trimesh.load(path, force="scene")
    doc = _Document(str(path))
    seen = 0
    for index, world in _scene_nodes(doc)[0]:
        name = doc.json["nodes"][index]["name"]
        np.testing.assert_allclose(world, scene.graph[name][0], atol=1e-6)
        seen += 1
    assert seen == 13


def test_duck_camera_looks_at_the_duck(model):
    content = model("Duck")
    cam, = content.cameras
    assert isinstance(cam, Camera)
    assert cam.fov_y == pytest.approx(math.degrees(0.6605925559997559))
    lo, hi = content.primitives[0].bounds()
    to_duck = (lo + hi) / 2 - np.array(cam.eye)
    assert np.dot(cam.forward, to_duck) / np.linalg.norm(to_duck) > 0.95


def test_scene_load_uses_gltf_loader():
    scene = Scene.load(model_path("TwoSidedPlane"))
    assert scene.triangle_count == 2 and scene.primitives[0].tangents is not None


# ---------------------------------------------------------------------------- files written here
class Builder:
    """A minimal glTF writer for tests: one binary buffer, accessors appended tightly."""

    def __init__(self):
        self.bin = bytearray()
        self.json = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": [],
                     "meshes": [], "nodes": [], "scenes": [{"nodes": []}], "scene": 0}

    def view(self, data: bytes, stride=None) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        spec = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            spec["byteStride"] = stride
        self.bin += data
        self.json["bufferViews"].append(spec)
        return len(self.json["bufferViews"]) - 1

    def accessor(self, array, kind, ctype=5126, normalized=False, view=None, offset=0, count=None) -> int:
        dtype = {5126: "<f4", 5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4"}[ctype]
        array = np.asarray(array)
        if view is None:
            view = self.view(np.ascontiguousarray(array, dtype=dtype).tobytes())
        spec = {"bufferView": view, "byteOffset": offset, "componentType": ctype, "type": kind,
                "count": len(array) if count is None else count}
        if normalized:
            spec["normalized"] = True
        self.json["accessors"].append(spec)
        return len(self.json["accessors"]) - 1

    def quad(self, material=None, **extra_attributes) -> int:
        """A unit quad in z = 0 facing +z with glTF UVs (top of the image at +y); a mesh index."""
        pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
        attrs = {"POSITION": self.accessor(pos, "VEC3"),
                 "NORMAL": self.accessor(np.tile([0, 0, 1], (4, 1)), "VEC3"),
                 "TEXCOORD_0": self.accessor([[0, 1], [1, 1], [1, 0], [0, 0]], "VEC2"), **extra_attributes}
        prim = {"attributes": attrs, "indices": self.accessor(np.array([0, 1, 2, 0, 2, 3]), "SCALAR", 5123)}
        if material is not None:
            prim["material"] = material
        self.json["meshes"].append({"name": "Quad", "primitives": [prim]})
        return len(self.json["meshes"]) - 1

    def node(self, **spec) -> int:
        self.json["nodes"].append(spec)
        index = len(self.json["nodes"]) - 1
        self.json["scenes"][0]["nodes"].append(index)
        return index

    def image(self) -> int:
        from PIL import Image
        import io

        buf = io.BytesIO()
        Image.fromarray(np.arange(48, dtype=np.uint8).reshape(4, 4, 3)).save(buf, format="PNG")
        self.json.setdefault("images", []).append({"bufferView": self.view(buf.getvalue()), "mimeType": "image/png"})
        return len(self.json["images"]) - 1

    def glb(self, path) -> Path:
        self.json["buffers"] = [{"byteLength": len(self.bin)}]
        text = json.dumps(self.json).encode()
        text += b" " * (-len(text) % 4)
        binary = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
        path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
        return path

    def gltf(self, path, bin_name=None) -> Path:
        """A .gltf with the buffer as a data: URI, or as the file ``bin_name`` next to it."""
        if bin_name is None:
            uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()
        else:
            (path.parent / bin_name).write_bytes(bytes(self.bin))
            uri = bin_name
        self.json["buffers"] = [{"byteLength": len(self.bin), "uri": uri}]
        path.write_text(json.dumps(self.json))
        return path


def quarter_turn_about_x():
    """The glTF rotation (x, y, z, w) of +90 degrees about +X: -Z turns to +Y, +Y to +Z."""
    s = math.sqrt(0.5)
    return [s, 0.0, 0.0, s]


def material_extension_file(tmp_path, extension, body, required=False):
    """A one-quad .glb (node 'quad') whose material 0 ('mat') has ``extension`` with ``body``;
    texture 0 is a small image, for the body's textureInfos."""
    b = Builder()
    b.json["textures"] = [{"source": b.image()}]
    b.json["materials"] = [{"name": "mat", "extensions": {extension: body}}]
    b.node(mesh=b.quad(material=0), name="quad")
    b.json["extensionsUsed"] = [extension]
    if required:
        b.json["extensionsRequired"] = [extension]
    return b.glb(tmp_path / f"{extension}.glb")


def loaded_material(path):
    """The material of a file's only primitive, the load warning about nothing."""
    content = load_gltf(path)
    assert content.load_warnings == ()
    (prim,) = content.primitives
    return prim.material


def test_lights_on_nodes(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    b.json["extensionsUsed"] = ["KHR_lights_punctual"]
    b.json["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 40.0},
        {"type": "spot", "intensity": 7.0, "spot": {"outerConeAngle": 0.5}},
        {"type": "directional", "intensity": 3.0},
    ]}}
    b.node(translation=[1, 2, 3], extensions={"KHR_lights_punctual": {"light": 0}})
    b.node(translation=[0, 5, 0], rotation=quarter_turn_about_x(), extensions={"KHR_lights_punctual": {"light": 1}})
    parent = b.node(rotation=quarter_turn_about_x(), children=[4])
    b.json["nodes"].append({"extensions": {"KHR_lights_punctual": {"light": 2}}, "translation": [0, 0, 9]})
    assert parent == 3
    point, spot, sun = load_gltf(b.glb(tmp_path / "lights.glb")).lights
    assert isinstance(point, PointLight) and point.position == (1, 2, 3)
    assert point.color == (1.0, 0.5, 0.25) and point.intensity == 40.0
    assert isinstance(spot, SpotLight) and spot.intensity == 7.0
    np.testing.assert_allclose(spot.position, (0, 5, 0))
    np.testing.assert_allclose(spot.direction, (0, 1, 0), atol=1e-12)  # -Z turned by +90 deg about X
    assert spot.inner_cone == 0.0 and spot.outer_cone == 0.5
    assert isinstance(sun, DirectionalLight) and sun.intensity == 3.0
    np.testing.assert_allclose(sun.direction, (0, 1, 0), atol=1e-12)  # inherits the parent's rotation


def test_spot_light_default_outer_cone(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    b.json["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "spot"}]}}
    b.node(extensions={"KHR_lights_punctual": {"light": 0}})
    spot, = load_gltf(b.glb(tmp_path / "spot.glb")).lights
    assert spot.outer_cone == pytest.approx(math.pi / 4) and spot.intensity == 1.0
    np.testing.assert_allclose(spot.direction, (0, 0, -1))


def test_cameras(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    b.json["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}},
                         {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 1}}]
    b.node(camera=0, translation=[0, 0, 4], rotation=quarter_turn_about_x())
    b.node(camera=1)
    with pytest.warns(UserWarning, match="orthographic"):
        content = load_gltf(b.glb(tmp_path / "cams.glb"))
    cam, = content.cameras
    assert cam.fov_y == pytest.approx(math.degrees(0.5))
    np.testing.assert_allclose(cam.eye, (0, 0, 4))
    np.testing.assert_allclose(cam.forward, (0, 1, 0), atol=1e-12)
    np.testing.assert_allclose(cam.up, (0, 0, 1), atol=1e-12)


def test_mesh_below_camera_node_is_placed(tmp_path):
    """A mesh node under a camera node is placed by the camera node's transform."""
    b = Builder()
    mesh = b.quad()
    b.json["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}]
    b.node(mesh=mesh, name="placed")
    b.node(camera=0, translation=[0, 0, 4], children=[2])
    b.json["nodes"].append({"mesh": mesh, "name": "child"})
    content = load_gltf(b.glb(tmp_path / "camchild.glb"))
    prims = {p.name: p for p in content.primitives}
    assert sorted(prims) == ["child", "placed"] and len(content.cameras) == 1
    np.testing.assert_allclose(prims["child"].positions - prims["placed"].positions, np.tile([0, 0, 4], (4, 1)))


def test_node_visibility_hides_meshes_and_lights_below_a_hidden_node(tmp_path):
    """KHR_node_visibility: a node with visible false hides its mesh and light and every
    descendant's, even a descendant marked visible; cameras stay; a hidden joint still poses."""
    b = Builder()
    mesh = b.quad()
    b.json["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point"}]}}
    b.json["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}]
    hidden = {"KHR_node_visibility": {"visible": False}}
    shown = {"KHR_node_visibility": {"visible": True}}
    b.node(mesh=mesh, name="plain")
    b.node(mesh=mesh, name="off", extensions=hidden, children=[2, 3, 4])
    b.json["nodes"].append({"mesh": mesh, "name": "child", "extensions": shown})
    b.json["nodes"].append({"name": "lamp", "extensions": {"KHR_lights_punctual": {"light": 0}}})
    b.json["nodes"].append({"name": "eye", "camera": 0})
    b.node(mesh=mesh, name="on", extensions=shown)
    b.json["extensionsUsed"] = ["KHR_node_visibility", "KHR_lights_punctual"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        content = load_gltf(b.glb(tmp_path / "visibility.glb"))
    assert [p.name for p in content.primitives] == ["plain", "on"]
    assert content.lights == [] and len(content.cameras) == 1


def test_node_visibility_must_be_boolean(tmp_path):
    b = Builder()
    b.node(mesh=b.quad(), extensions={"KHR_node_visibility": {"visible": "no"}})
    with pytest.raises(AssetFormatError, match="visible must be true or false"):
        load_gltf(b.glb(tmp_path / "bad.glb"))


def test_primitives_are_named_after_their_nodes(tmp_path):
    """A node's name (its index without one, a _k suffix where two share one); /k marks primitive
    k of a mesh with several."""
    b = Builder()
    mesh = b.quad()
    b.json["meshes"][mesh]["primitives"].append(dict(b.json["meshes"][mesh]["primitives"][0], mode=0))
    single = b.quad()
    b.node(mesh=mesh, name="twice")
    b.node(mesh=single, name="twice")
    b.node(mesh=single)
    b.json["meshes"][mesh]["primitives"][1]["mode"] = 4
    names = [p.name for p in load_gltf(b.glb(tmp_path / "names.glb")).primitives]
    assert names == ["twice/0", "twice/1", "twice_1", "2"]


def test_points_and_lines_are_skipped_with_a_warning(tmp_path):
    b = Builder()
    mesh = b.quad()
    prim = b.json["meshes"][mesh]["primitives"][0]
    b.json["meshes"][mesh]["primitives"] += [dict(prim, mode=0), dict(prim, mode=1), dict(prim, mode=3)]
    b.node(mesh=mesh)
    with pytest.warns(UserWarning) as caught:
        content = load_gltf(b.glb(tmp_path / "modes.glb"))
    assert len(content.primitives) == 1
    assert [str(w.message) for w in caught] == list(content.load_warnings)
    assert [m.split(": ", 1)[1] for m in content.load_warnings] == [
        "primitive 1 of mesh 'Quad' drawn as points skipped: pbrwarp renders triangles only",
        "primitive 2 of mesh 'Quad' drawn as lines skipped: pbrwarp renders triangles only",
        "primitive 3 of mesh 'Quad' drawn as line strips skipped: pbrwarp renders triangles only"]


def test_material_extensions_and_texture_settings(tmp_path):
    b = Builder()
    image = b.image()
    b.json["samplers"] = [{"wrapS": 33648, "wrapT": 33071}]
    b.json["textures"] = [{"source": image, "sampler": 0}, {"source": image}]
    transform = {"KHR_texture_transform": {"offset": [0.25, 0.5], "rotation": 0.3, "scale": [2.0, 3.0]}}
    b.json["materials"] = [{
        "name": "fancy",
        "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 0.75], "metallicFactor": 0.2,
                                 "roughnessFactor": 0.6, "baseColorTexture": {"index": 0, "extensions": transform},
                                 "metallicRoughnessTexture": {"index": 1}},
        "normalTexture": {"index": 1, "scale": 0.4},
        "occlusionTexture": {"index": 1, "strength": 0.3, "texCoord": 1},
        "emissiveFactor": [1.0, 0.5, 0.0],
        "alphaMode": "MASK", "alphaCutoff": 0.7, "doubleSided": True,
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.25},
                       "KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
    }]
    b.node(mesh=b.quad(material=0))
    with pytest.warns(UserWarning, match="TEXCOORD_1 missing on primitive 0 of mesh 0"):
        prim, = load_gltf(b.glb(tmp_path / "material.glb")).primitives
    m = prim.material
    assert m.name == "fancy" and m.base_color == (0.5, 0.25, 1.0, 0.75)
    assert m.metallic == pytest.approx(0.2) and m.roughness == pytest.approx(0.6)
    assert m.specular == 0.25 and m.emissive == (4.0, 2.0, 0.0)
    assert m.normal_scale == pytest.approx(0.4) and m.occlusion_strength == pytest.approx(0.3)
    assert m.alpha_mode == "MASK" and m.alpha_cutoff == pytest.approx(0.7) and m.double_sided is True
    tex = m.base_color_texture
    assert (tex.wrap_s, tex.wrap_t) == ("mirror", "clamp")
    assert tex.offset == (0.25, 0.5) and tex.rotation == pytest.approx(0.3) and tex.scale == (2.0, 3.0)
    assert m.metallic_roughness_texture is m.normal_texture  # same image, sampler and uv set
    assert m.occlusion_texture.texcoord == 1 and m.normal_texture.texcoord == 0
    assert m.occlusion_texture.image is m.normal_texture.image
    assert m.metallic_roughness_texture is not tex
    assert (m.normal_texture.wrap_s, m.normal_texture.wrap_t) == ("repeat", "repeat")
    # No TANGENT but a normal map: generated; u runs along +x, top of the image at +y.
    np.testing.assert_allclose(prim.tangents, np.tile([1.0, 0, 0, 1.0], (4, 1)), atol=1e-12)


def test_ext_texture_webp_reads_the_webp_image(tmp_path):
    """EXT_texture_webp: the texture's WebP image (lossless here) is read, not its PNG fallback."""
    from PIL import Image
    import io

    b = Builder()
    pixels = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3)[::-1].copy()
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="WEBP", lossless=True)
    b.json.setdefault("images", []).append({"bufferView": b.view(buf.getvalue()), "mimeType": "image/webp"})
    webp = len(b.json["images"]) - 1
    fallback = b.image()
    b.json["textures"] = [{"source": fallback, "extensions": {"EXT_texture_webp": {"source": webp}}}]
    b.json["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    b.json["extensionsUsed"] = b.json["extensionsRequired"] = ["EXT_texture_webp"]
    b.node(mesh=b.quad(material=0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prim, = load_gltf(b.glb(tmp_path / "webp.glb")).primitives
    np.testing.assert_array_equal(np.asarray(prim.material.base_color_texture.image)[..., :3], pixels)


def test_default_material_and_no_tangents_without_normal_map(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    prim, = load_gltf(b.gltf(tmp_path / "plain.gltf")).primitives
    m = prim.material
    assert m.base_color == (1.0, 1.0, 1.0, 1.0) and m.metallic == 1.0 and m.roughness == 1.0
    assert m.double_sided is False and m.alpha_mode == "OPAQUE"
    assert prim.tangents is None
    np.testing.assert_allclose(prim.uvs, [[0, 1], [1, 1], [1, 0], [0, 0]])


def rotated_to_min(faces):
    """Each triangle rotated to start at its smallest index (same triangle, same winding)."""
    out = []
    for f in np.asarray(faces).tolist():
        k = f.index(min(f))
        out.append(tuple(f[k:] + f[:k]))
    return out


def test_interleaved_normalized_sparse_accessors_and_instancing(tmp_path):
    b = Builder()
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    normal = np.zeros((4, 3), np.float32)  # missing normals: zero rows (flat shading)
    interleaved = np.concatenate([pos, normal], axis=1).tobytes()
    view = b.view(interleaved, stride=24)
    attrs = {
        "POSITION": b.accessor(pos, "VEC3", view=view, offset=0),
        "NORMAL": b.accessor(normal, "VEC3", view=view, offset=12),
        "COLOR_0": b.accessor(np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]), "VEC3", 5121, True),
        "TEXCOORD_0": b.accessor(np.array([[0, 65535], [65535, 65535], [65535, 0], [0, 0]]), "VEC2", 5123, True),
    }
    tangent = b.accessor(np.tile([1.0, 0, 0, 1], (4, 1)), "VEC4")
    b.json["accessors"][tangent]["sparse"] = {
        "count": 1, "indices": {"bufferView": b.view(np.array([2], np.uint16).tobytes()), "componentType": 5123},
        "values": {"bufferView": b.view(np.array([[0, 1, 0, -1]], np.float32).tobytes())}}
    attrs["TANGENT"] = tangent
    strip = b.accessor(np.array([0, 1, 3, 2], np.uint8), "SCALAR", 5121)
    b.json["meshes"].append({"name": "Strip", "primitives": [{"attributes": attrs, "indices": strip, "mode": 5}]})
    b.node(mesh=0, name="a")
    b.node(mesh=0, name="b", translation=[0, 0, 2], scale=[-1, 1, 1])
    prims = {p.name: p for p in load_gltf(b.glb(tmp_path / "accessors.glb")).primitives}
    first, second = prims["a"], prims["b"]
    np.testing.assert_allclose(first.positions, pos)
    assert rotated_to_min(first.faces) == [(0, 1, 3), (1, 2, 3)]  # strip: odd triangles swapped
    np.testing.assert_allclose(first.normals, 0.0)
    np.testing.assert_allclose(first.colors, [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 1, 1]])
    np.testing.assert_allclose(first.uvs, [[0, 1], [1, 1], [1, 0], [0, 0]])
    np.testing.assert_allclose(first.tangents, [[1, 0, 0, 1], [1, 0, 0, 1], [0, 1, 0, -1], [1, 0, 0, 1]])
    # The mirrored instance: winding reversed, handedness flipped, x negated.
    np.testing.assert_allclose(second.positions, pos * [-1, 1, 1] + [0, 0, 2])
    assert rotated_to_min(second.faces) == [(0, 3, 1), (1, 3, 2)]
    np.testing.assert_allclose(second.tangents, [[-1, 0, 0, -1], [-1, 0, 0, -1], [0, 1, 0, 1], [-1, 0, 0, -1]])


def test_external_buffer_file(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    path = b.gltf(tmp_path / "external.gltf", bin_name="data file.bin")
    assert len(load_gltf(path).primitives) == 1
    (tmp_path / "data file.bin").unlink()
    with pytest.raises(AssetNotFoundError, match="data file.bin"):
        load_gltf(path)


# ---------------------------------------------------------------------------- broken files
def test_missing_file(tmp_path):
    with pytest.raises(AssetNotFoundError, match="nothing.glb"):
        load_gltf(tmp_path / "nothing.glb")


def test_truncated_glb(tmp_path):
    b = Builder()
    b.node(mesh=b.quad())
    data = b.glb(tmp_path / "whole.glb").read_bytes()
    for size in (10, 40, len(data) - 8):
        cut = tmp_path / f"cut{size}.glb"
        cut.write_bytes(data[:size])
        with pytest.raises(AssetFormatError, match=f"cut{size}.glb.*truncated"):
            load_gltf(cut)


def test_not_a_glb(tmp_path):
    path = tmp_path / "text.glb"
    path.write_text("hello")
    with pytest.raises(AssetFormatError, match="not a binary glTF"):
        load_gltf(path)


def test_bad_json(tmp_path):
    path = tmp_path / "bad.gltf"
    path.write_text('{"asset": {"version": "2.0"}, "meshes": [')
    with pytest.raises(AssetFormatError, match="bad.gltf.*invalid JSON"):
        load_gltf(path)
    path.write_text('{"asset": {"version": "1.0"}}')
    with pytest.raises(AssetFormatError, match="2.0"):
        load_gltf(path)


def broken(tmp_path, edit, name="broken.glb"):
    b = Builder()
    b.node(mesh=b.quad())
    edit(b)
    return b.glb(tmp_path / name)


@pytest.mark.parametrize("edit, message", [
    (lambda b: b.json["accessors"][0].update(count=400), "accessor 0 .POSITION.* reads bytes"),
    (lambda b: b.json["bufferViews"][0].update(byteLength=10**6), "bufferView 0 spans"),
    (lambda b: b.json["accessors"][0].update(bufferView=99), "bufferViews\\[99\\]"),
    (lambda b: b.json["meshes"][0]["primitives"][0].update(indices=b.accessor(np.array([0, 1, 9]), "SCALAR", 5123)),
     "vertex index 9, but only 4 vertices"),
    (lambda b: b.json["meshes"][0]["primitives"][0].update(material=3), "materials\\[3\\]"),
    (lambda b: b.json["accessors"][0].update(type="VEC2"), "expected VEC3"),
    (lambda b: b.json["accessors"][1].update(count=3), "4 positions but 3 NORMAL"),
    (lambda b: b.json.update(extensionsRequired=["EXT_meshopt_compression"]), "EXT_meshopt_compression"),
    (lambda b: b.json["accessors"][0].update(count="four"), "invalid count"),
    (lambda b: b.json["nodes"][0].update(rotation=[0, 0, 0]), "rotation must be 4"),
    (lambda b: b.json["nodes"][0].update(children=[0]), "cycle"),
    (lambda b: b.json["meshes"][0]["primitives"][0]["attributes"].pop("POSITION"), "no POSITION"),
    (lambda b: b.json.update(materials=[{"pbrMetallicRoughness": {"metallicFactor": 2.0}}])
     or b.json["meshes"][0]["primitives"][0].update(material=0), "material 0.*metallic"),
])
def test_inconsistent_files_raise_asset_format_error(tmp_path, edit, message):
    with pytest.raises(AssetFormatError, match=f"broken.glb.*{message}"):
        load_gltf(broken(tmp_path, edit))


def test_corrupt_image(tmp_path):
    def edit(b):
        b.json["images"] = [{"bufferView": b.view(b"not a png at all"), "mimeType": "image/png"}]
        b.json["textures"] = [{"source": 0}]
        b.json["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        b.json["meshes"][0]["primitives"][0]["material"] = 0

    with pytest.raises(AssetFormatError, match="image 0 cannot be decoded"):
        load_gltf(broken(tmp_path, edit))


def test_no_triangles(tmp_path):
    b = Builder()
    b.quad()  # a mesh no node uses
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(AssetFormatError, match="no triangle meshes"):
            load_gltf(b.glb(tmp_path / "empty.glb"))
