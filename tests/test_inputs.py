"""Bad input gets a clear, documented error before anything reaches Warp."""

import math
import os

import numpy as np
import pytest
import trimesh
from PIL import Image

import pbrwarp as pw

from scenes import head_on_camera, quad


def simple_scene():
    scene = pw.Scene()
    scene.add_mesh(quad())
    return scene


@pytest.mark.parametrize("kw,match", [
    (dict(width=0), "width"), (dict(height=-3), "height"), (dict(width=2.5), "width"),
    (dict(spp=0), "spp"), (dict(threads=0), "threads"), (dict(background=(1, 2)), "background"),
    (dict(background=(0, -1, 0)), "background"),
])
def test_bad_render_options(kw, match):
    with pytest.raises((pw.InputError, pw.InputTypeError), match=match):
        pw.render(simple_scene(), head_on_camera(), **kw)


@pytest.mark.parametrize("fov", [0.0, 180.0, -10.0, 200.0, math.nan])
def test_bad_field_of_view(fov):
    with pytest.raises(pw.InputError, match="fov"):
        pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=fov)


def test_degenerate_cameras():
    with pytest.raises(pw.InputError, match="coincide"):
        pw.Camera.look_at(eye=(1, 1, 1), target=(1, 1, 1))
    with pytest.raises(pw.InputError, match="parallel"):
        pw.Camera.look_at(eye=(0, 3, 0), target=(0, 0, 0), up=(0, 1, 0))


@pytest.mark.parametrize("make", [
    lambda: pw.PointLight(intensity=-1.0),
    lambda: pw.DirectionalLight(intensity=-0.5),
    lambda: pw.SpotLight(intensity=-2.0),
    lambda: pw.PointLight(color=(1, -1, 1)),
    lambda: pw.PointLight(position=(0, math.inf, 0)),
    lambda: pw.DirectionalLight(direction=(0, 0, 0)),
    lambda: pw.SpotLight(inner_cone=0.8, outer_cone=0.4),
    lambda: pw.SpotLight(outer_cone=2.0),
])
def test_bad_lights(make):
    with pytest.raises(pw.InputError):
        make()


@pytest.mark.parametrize("kw", [
    dict(roughness=1.5), dict(roughness=-0.1), dict(metallic=2.0), dict(metallic=math.nan),
    dict(specular=-1.0), dict(base_color=(1, 1)), dict(base_color=(0.5, math.nan, 0.5)), dict(emissive=(-1, 0, 0)),
    dict(alpha_mode="GLASS"),
])
def test_out_of_range_material_factors_are_rejected(kw):
    with pytest.raises(pw.InputError, match="Material"):
        pw.Material(**kw)


def test_add_light_type_checked():
    with pytest.raises(pw.InputTypeError, match="PointLight"):
        pw.Scene().add_light("sun")


def test_nan_and_inf_vertices_rejected():
    mesh = trimesh.creation.box()
    mesh.vertices[3] = [np.nan, 0, 0]
    with pytest.raises(pw.InputError, match="NaN"):
        pw.Scene().add_mesh(mesh)
    with pytest.raises(pw.InputError, match="NaN or Inf"):
        pw.Primitive(np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), np.array([[0, 1, 2]]), pw.Material())


@pytest.mark.parametrize("faces,match", [
    (np.array([[0, 1, 3]]), "valid: 0..2"),
    (np.array([[0, -1, 2]]), "valid: 0..2"),
    (np.zeros((0, 3), int), "no faces"),
    (np.array([[0, 1]]), "shape"),
    (np.array([[0.0, 1.5, 2.0]]), "whole"),
])
def test_bad_faces_never_reach_warp(faces, match):
    with pytest.raises((pw.InputError, pw.InputTypeError), match=match):
        pw.Primitive(np.eye(3), faces, pw.Material())


def test_attribute_count_mismatch():
    with pytest.raises(pw.InputError, match="normals"):
        pw.Primitive(np.eye(3), np.array([[0, 1, 2]]), pw.Material(), normals=np.zeros((2, 3)))


def test_empty_scene_cannot_render():
    with pytest.raises(pw.InputError, match="no meshes"):
        pw.render(pw.Scene(), head_on_camera())


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(pw.AssetNotFoundError, match="not found"):
        pw.Scene.load(tmp_path / "nope.obj")
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\nproperty float x\nend_header\n\x00\x01")
    with pytest.raises(pw.AssetFormatError, match="bad.ply"):
        pw.Scene.load(bad)
    unknown = tmp_path / "scene.xyz123"
    unknown.write_text("hello")
    with pytest.raises(pw.AssetFormatError, match="unsupported extension"):
        pw.Scene.load(unknown)
    with pytest.raises(pw.AssetFormatError, match="folder"):
        pw.Scene.load(tmp_path)


@pytest.mark.parametrize("image,match", [
    (np.zeros((0, 4, 3)), "empty"), (np.zeros((4, 4, 5)), "shape"), ("texture.png", "numpy array or a Pillow image"),
    (np.full((2, 2, 3), np.nan), "NaN"),
])
def test_unreadable_textures(image, match):
    with pytest.raises((pw.InputError, pw.InputTypeError), match=match):
        pw.Material(base_color_texture=image)


def test_save_is_atomic_and_validates(tmp_path):
    scene = simple_scene()
    frame = pw.render(scene, head_on_camera(), width=8, height=8, progress=False)
    with pytest.raises(pw.InputError, match="does not exist"):
        frame.save(tmp_path / "missing" / "x.png")
    with pytest.raises(pw.InputError, match="extension"):
        frame.save(tmp_path / "x.unknownext")
    with pytest.raises(pw.InputError, match="extension"):
        frame.save(tmp_path / "x.psd")  # Pillow reads PSD but cannot write it
    with pytest.raises(pw.InputError, match="tonemap"):
        frame.save(tmp_path / "x.png", tonemap="filmic-ish")
    assert os.listdir(tmp_path) == []  # nothing half-written
    frame.save(tmp_path / "ok.png")
    frame.save(tmp_path / "ok.npy")
    assert sorted(os.listdir(tmp_path)) == ["ok.npy", "ok.png"]
    assert Image.open(tmp_path / "ok.png").size == (8, 8)
    assert np.load(tmp_path / "ok.npy").shape == (8, 8, 4)


def test_transparent_png_keeps_coverage(tmp_path):
    scene = pw.Scene()
    scene.add_mesh(quad(size=1.0, material=pw.Material(emissive=(0.5, 0.5, 0.5), base_color=(0, 0, 0))))
    frame = pw.render(scene, head_on_camera(), width=16, height=16, background=(1, 0, 0), progress=False)
    frame.save(tmp_path / "t.png", transparent=True, tonemap="none")
    rgba = np.asarray(Image.open(tmp_path / "t.png"))
    assert rgba.shape == (16, 16, 4)
    assert rgba[0, 0, 3] == 0 and rgba[8, 8, 3] == 255
    assert rgba[8, 8, 0] == rgba[8, 8, 1]  # the red background does not bleed into the surface


def test_explain_refuses_a_keyword_render_does_not_take():
    import trimesh

    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.box())
    with pytest.raises(pw.InputTypeError, match="'sp', which render does not take"):
        pw.explain(scene, sp=4)
    assert "simulated" in pw.explain(scene, camera=None, threads=1, progress=False, seed=3)


def test_explain_takes_the_camera_where_render_does():
    import trimesh

    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.box())
    camera = pw.Camera.frame(scene)
    # explain(scene, camera, ...) reads as the render call it describes
    assert pw.explain(scene, camera, shadows=False) == pw.explain(scene, shadows=False)
    with pytest.raises(pw.InputTypeError, match="camera must be a pbrwarp.Camera"):
        pw.explain(scene, "front")
