"""Never silently wrong: everything in a glTF file that pbrwarp does not honour is named in one
warning per kind at load, kept in ``Scene.load_warnings`` and listed by ``pw.explain`` and the
CLI's ``--explain``; an unsupported extension listed in ``extensionsRequired`` is an error."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.cli import main
from pbrwarp.errors import AssetFormatError
from pbrwarp.gltf import load_gltf
from pbrwarp.gltf_notes import _EXTENSIONS, IGNORED

from assets import BOARDS, GLTF, asset_id, board
from test_gltf import Builder

# The extensions issue 30 names as dropped without a word, each on one material.
MATERIAL_EXTENSIONS = {
    "KHR_materials_dispersion": "without dispersion",
    "KHR_materials_diffuse_transmission": "rendered opaque",
    "KHR_materials_pbrSpecularGlossiness": "metallic-roughness values",
}


def quad_file(tmp_path, edit=None, name="model.glb"):
    """A quad on one node (with material 0 if the edit defines materials), edited, written as GLB."""
    b = Builder()
    b.node(mesh=b.quad(), name="quad")
    if edit is not None:
        edit(b)
    if b.json.get("materials"):
        b.json["meshes"][0]["primitives"][0]["material"] = 0
    return b.glb(tmp_path / name)


def load_warned(path):
    """(scene, messages warned) of Scene.load, each message after the file name it starts with."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = pw.Scene.load(path)
    messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert tuple(messages) == scene.load_warnings, "the scene keeps exactly what the load warned"
    for message in messages:
        assert message.startswith(f"{path}: "), message
    return scene, [m[len(f"{path}: "):] for m in messages]


def materials(*specs):
    return lambda b: b.json.update(materials=list(specs))


def extension_on_material(name, body=None):
    return materials({"name": "mat", "extensions": {name: body or {}}})


def add_texture(b, **texture):
    b.json["textures"] = [dict(source=b.image(), **texture)]
    b.json["materials"] = [{"name": "mat", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]


def add_morph_target(b, mesh_weights=None, node_weights=None, attribute="POSITION"):
    width = 2 if attribute.startswith("TEXCOORD") else 3
    target = b.accessor(np.full((4, width), 0.5, np.float32), f"VEC{width}")
    b.json["meshes"][0]["primitives"][0]["targets"] = [{attribute: target}]
    if mesh_weights is not None:
        b.json["meshes"][0]["weights"] = mesh_weights
    if node_weights is not None:
        b.json["nodes"][0]["weights"] = node_weights


def add_scene(b, default=True):
    b.json["scenes"][0]["name"] = "main"
    b.json["scenes"].append({"name": "other", "nodes": []})
    if not default:
        del b.json["scene"]


def add_light(b, **light):
    b.json["extensions"] = {"KHR_lights_punctual": {"lights": [dict(type="point", name="lamp", **light)]}}
    b.node(translation=[0, 0, 2], extensions={"KHR_lights_punctual": {"light": 0}})


# ---------------------------------------------------------------------------- each kind, named
@pytest.mark.parametrize("extension", sorted(MATERIAL_EXTENSIONS))
def test_ignored_material_extension_is_named_with_what_is_rendered_instead(tmp_path, extension):
    scene, messages = load_warned(quad_file(tmp_path, extension_on_material(extension)))
    assert messages == [f"{extension} on material 'mat' ignored: {_EXTENSIONS[extension][1]}"]
    assert MATERIAL_EXTENSIONS[extension] in messages[0]
    assert scene.triangle_count == 2


@pytest.mark.parametrize("edit, expected", [
    # extensions elsewhere than on materials: the element using each is named
    (lambda b: add_texture(b, extensions={"EXT_texture_avif": {"source": 0}}),
     r"EXT_texture_avif on texture 0 ignored: the textures' fallback PNG or JPEG images are used"),
    (lambda b: b.json["meshes"][0]["primitives"][0].update(extensions={"EXT_meshopt_compression": {}}),
     r"EXT_meshopt_compression on mesh 'Quad' ignored: the uncompressed fallback buffers are read instead"),
    (lambda b: b.json["meshes"][0]["primitives"][0].update(
        extensions={"KHR_materials_variants": {"mappings": [{"material": 0, "variants": [0]}]}})
     or b.json.update(extensions={"KHR_materials_variants": {"variants": [{"name": "red"}]}}),
     r"KHR_materials_variants on mesh 'Quad' ignored: each primitive shows its default material"),
    (lambda b: b.json.update(extensions={"EXT_lights_image_based": {"lights": []}}),
     r"EXT_lights_image_based ignored: no environment lighting from the file"),
    (lambda b: b.json.update(extensionsUsed=["KHR_animation_pointer"]), r"KHR_animation_pointer ignored"),
    (extension_on_material("ACME_sparkle"), r"ACME_sparkle on material 'mat' ignored: pbrwarp does not know"),
    # core glTF that pbrwarp does not honour
    (materials({"name": "frosted", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}}),
     r"objects seen through material 'frosted' with roughness above 0 not blurred \(KHR_materials_transmission\): "
     r"only the environment seen through them is, but with Monte Carlo environment lighting"),
    (lambda b: b.json.update(animations=[{"name": "spin", "channels": [], "samplers": []}]),
     r"animation 'spin' not played: the static pose the nodes store \(their transforms and morph weights\) is shown"),
    (lambda b: add_morph_target(b, mesh_weights=[0.5], attribute="TEXCOORD_0"),
     r"morph targets of TEXCOORD_0 ignored: pbrwarp applies POSITION, NORMAL and TANGENT displacements only"),
    (add_scene, r"the file has 2 scenes; only scene 'main' \(the default\) is loaded"),
    (lambda b: add_scene(b, default=False), r"only scene 'main' \(the first; the file names no default\) is loaded"),
    (lambda b: add_texture(b, sampler=0) or b.json.update(samplers=[{"magFilter": 9728}]),
     r"magFilter NEAREST of sampler 0 not honoured: their textures are filtered bilinearly"),
    (lambda b: b.json.update(cameras=[{"type": "orthographic", "name": "top"}]) or b.node(camera=0),
     r"camera 'top' of type 'orthographic' skipped: pbrwarp reads perspective cameras only"),
    (lambda b: add_texture(b) or b.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(texCoord=2),
     r"TEXCOORD_2 not read: texture slot material 0 \('mat'\) baseColorTexture sampled with TEXCOORD_0 instead"),
    (lambda b: add_texture(b) or b.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(texCoord=1),
     r"TEXCOORD_1 missing on primitive 0 of mesh 0: their textures that ask for it sampled with TEXCOORD_0 instead"),
], ids=["avif", "meshopt", "variants", "image_based_lights",
        "only_in_extensionsUsed", "unknown", "rough_transmission", "animation", "texcoord_morph_target",
        "default_scene", "first_scene", "nearest", "orthographic", "texcoord_2", "texcoord_1_missing"])
def test_unhonoured_feature_is_named_in_one_warning(tmp_path, edit, expected):
    scene, messages = load_warned(quad_file(tmp_path, edit))
    assert len(messages) == 1 and re.search(expected, messages[0]), messages
    assert scene.triangle_count == 2


def test_one_message_per_kind_counting_what_it_affects(tmp_path):
    names = ["cloth", None, "felt", "silk", "wool"]
    specs = [dict({"extensions": {"KHR_materials_dispersion": {}}}, **({"name": n} if n else {})) for n in names]
    for felt_or_wool in (specs[2], specs[4]):
        felt_or_wool["extensions"]["KHR_materials_diffuse_transmission"] = {}
    scene, messages = load_warned(quad_file(tmp_path, materials(*specs)))
    assert messages == [
        "KHR_materials_dispersion on 5 materials ('cloth', 1, 'felt', ...) ignored: rendered without dispersion",
        "KHR_materials_diffuse_transmission on 2 materials ('felt', 'wool') ignored: rendered opaque (no light "
        "passes through)"]


def test_points_and_lines_count_primitives_not_placements(tmp_path):
    def edit(b):
        prim = b.json["meshes"][0]["primitives"][0]
        b.json["meshes"][0]["primitives"] += [dict(prim, mode=1), dict(prim, mode=3)]
        b.node(mesh=0, translation=[2, 0, 0])  # the same mesh placed twice

    scene, messages = load_warned(quad_file(tmp_path, edit))
    assert messages == ["primitive 1 of mesh 'Quad' drawn as lines skipped: pbrwarp renders triangles only",
                        "primitive 2 of mesh 'Quad' drawn as line strips skipped: pbrwarp renders triangles only"]
    assert scene.triangle_count == 4


@pytest.mark.parametrize("extension", sorted(name for name, (status, _) in _EXTENSIONS.items() if status == IGNORED)
                         + ["ACME_sparkle"])
def test_required_extension_pbrwarp_ignores_is_an_error(tmp_path, extension):
    def edit(b):
        b.json["extensionsUsed"] = b.json["extensionsRequired"] = [extension, "KHR_texture_transform"]

    with pytest.raises(AssetFormatError, match=f"model.glb: it requires extensions pbrwarp does not support: "
                                               f"{extension}$"):
        pw.Scene.load(quad_file(tmp_path, edit))


# ---------------------------------------------------------------------------- nothing to say
def honoured_only(b):
    """Everything here is honoured (or, for the brdf branch's KHR_materials_ior and specular,
    read by it), so loading warns nothing."""
    image = b.image()
    b.json["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33648}, {"minFilter": 9984}]
    b.json["textures"] = [{"source": image, "sampler": 0}, {"source": image, "sampler": 1}]
    transform = {"KHR_texture_transform": {"offset": [0.5, 0.0], "texCoord": 0}}
    b.json["materials"] = [{
        "name": "honoured", "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": True,
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": transform},
                                 "metallicRoughnessTexture": {"index": 1}, "roughnessFactor": 0.0},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0},
                       "KHR_materials_ior": {"ior": 1.4},
                       "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [1, 0.5, 0.5],
                                                  "specularTexture": {"index": 1}},
                       "KHR_materials_transmission": {"transmissionFactor": 0.5, "transmissionTexture": {"index": 1}},
                       "KHR_materials_volume": {"thicknessFactor": 0.1, "attenuationColor": [1, 0.9, 0.8],
                                                "attenuationDistance": 2.0}},
        "extras": {"ACME_only_in_extras": True, "extensions": {"ACME_sparkle": {}}},
    }]
    add_morph_target(b, mesh_weights=[0.25], node_weights=[0.5])  # morph targets: honoured
    add_light(b, intensity=3.0)
    b.json["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1, "aspectRatio": 1.5}}]
    b.node(camera=0, translation=[0, 0, 3])
    b.json["asset"]["extensions"] = {"KHR_xmp_json_ld": {"packet": 0}}
    used = ["KHR_texture_transform", "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_specular",
            "KHR_materials_transmission", "KHR_materials_volume", "KHR_lights_punctual", "KHR_xmp_json_ld"]
    b.json["extensionsUsed"] = used
    b.json["extensionsRequired"] = used


def test_a_file_using_only_honoured_features_warns_nothing(tmp_path):
    path = quad_file(tmp_path, honoured_only)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = pw.Scene.load(path)
    assert scene.load_warnings == () and len(scene.lights) == 1 and len(scene.cameras) == 1
    assert "not honoured" not in pw.explain(scene)


@pytest.mark.parametrize("path", GLTF, ids=asset_id)
def test_sample_models_of_core_glTF_warn_nothing(path):
    """The glTF test models (SOURCES.md) use core features pbrwarp honours: no warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_gltf(path).load_warnings == ()


def test_docs_table_gives_each_extension_its_status():
    """docs/loading.md's extension table and _EXTENSIONS say the same (flip both together)."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "loading.md").read_text().split("### Extensions")[1]
    rows = dict(re.findall(r"^\| `(\w+)` \| ([a-z ]+) \|", text, re.MULTILINE))
    assert {name: status for name, (status, _) in _EXTENSIONS.items()} == rows


def test_scenes_built_in_python_have_no_load_warnings():
    assert pw.Scene().load_warnings == ()


def test_mesh_files_keep_their_load_warnings_too(tmp_path):
    """An OBJ naming a material library that does not exist: loaded without it, said and kept."""
    path = tmp_path / "tri.obj"
    path.write_text("mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.warns(UserWarning) as caught:
        scene = pw.Scene.load(path)
    assert [str(w.message) for w in caught] == list(scene.load_warnings) == [
        f"{path} names the file 'missing.mtl', which does not exist; loaded without it"]


# ---------------------------------------------------------------------------- explain and the CLI
def unhonoured_file(tmp_path):
    return quad_file(tmp_path, lambda b: materials({"name": "cloth", "extensions": {
                                                    "KHR_materials_dispersion": {},
                                                    "KHR_materials_diffuse_transmission": {}}})(b)
                     or b.json.update(animations=[{"name": "wave", "channels": [], "samplers": []}]))


def test_explain_lists_what_the_file_asks_for_that_is_not_honoured(tmp_path):
    scene, messages = load_warned(unhonoured_file(tmp_path))
    assert len(messages) == 3
    text = pw.explain(scene, width=16, height=16)
    section = text.split("not honoured from the file (warned at load):\n", 1)[1].splitlines()
    assert section == [f"  ! {m}" for m in scene.load_warnings]


def test_cli_explain_lists_them_too(tmp_path, capsys):
    path = unhonoured_file(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the load's warnings go to stderr; --explain prints them again
        assert main(["render", str(path), "-o", str(tmp_path / "out.png"), "--size", "16x12", "--explain"]) == 0
    out = capsys.readouterr().out
    for name in ("KHR_materials_dispersion on material 'cloth'",
                 "KHR_materials_diffuse_transmission on material 'cloth'",
                 "animation 'wave' not played"):
        assert f"  ! {path}: {name}" in out


# ---------------------------------------------------------------------------- the Khronos test boards
# Each board of ../shared/assets/gltf-ext (SOURCES.md there) with what a load must name, or the
# clear error for an extension it requires; boards pbrwarp renders as the sample viewer does warn
# nothing. Runs over the small boards in tests/assets, and over all with PBRWARP_TEST_ASSETS.
BOARD_NOTES = {
    "AlphaBlendModeTest": [], "AnimatedMorphCube": ["animation"],
    "AnisotropyRotationTest": [], "AnisotropyStrengthTest": [],
    "AttenuationTest": [], "Avocado": [], "Box": [], "ClearCoatTest": [],
    "EmissiveStrengthTest": [], "IridescenceSuzanne": ["roughness above 0 not blurred"],
    "MeshPrimitiveModes": ["points", "lines", "line loops", "line strips"],
    "MorphPrimitivesTest": [], "MultiUVTest": [],
    "RecursiveSkeletons": ["animation"], "SheenCloth": [],
    "SimpleSkin": ["animation"], "SimpleSparseAccessor": [], "SpecularTest": [],
    "TextureTransformMultiTest": [],
    "TransmissionRoughnessTest": ["roughness above 0 not blurred"],
    "TransmissionTest": ["roughness above 0 not blurred"], "UnlitTest": [],
}


@pytest.mark.parametrize("name", [name for name in BOARD_NOTES if name in BOARDS])
def test_khronos_test_boards_name_what_is_not_rendered(name):
    path = board(name)
    expected = BOARD_NOTES[name]
    if expected is AssetFormatError:
        with pytest.raises(AssetFormatError, match="requires extensions pbrwarp does not support"):
            load_gltf(path)
        return
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        messages = load_gltf(path).load_warnings
    assert len(messages) == len(expected), messages
    for note, message in zip(expected, messages):
        assert note in message
