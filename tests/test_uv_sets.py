"""A second uv set (glTF TEXCOORD_1): read by the loader, sampled by the textures that ask for it,
with its own footprint, compiled in only when a texture reads it."""

import dataclasses

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.errors import InputError
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload

from assets import board
from scenes import render_checked
from test_texture_filtering import head_on_plane_check


def multi_uv_board():
    scene = pw.Scene.load(board("MultiUVTest"))
    assert scene.load_warnings == ()
    return scene


def face_colours(frame):
    """{(axis, sign): (fraction of white pixels, fraction of green pixels)} over each cube face
    the frame shows (pixels grouped by their normal's dominant axis)."""
    rgb, normal = frame.rgb, frame.normal
    covered = frame.alpha == 1.0
    axis = np.abs(normal).argmax(axis=2)
    sign = np.sign(np.take_along_axis(normal, axis[..., None], axis=2)[..., 0])
    white = rgb.min(axis=2) > 0.3
    green = (rgb[..., 1] > 0.15) & (rgb[..., 1] > 1.5 * rgb[..., 2]) & (rgb[..., 0] < rgb[..., 1])
    faces = {}
    for a in range(3):
        for s in (-1.0, 1.0):
            on = covered & (axis == a) & (sign == s)
            if on.sum() > 200:
                faces[a, s] = (white[on].mean(), green[on].mean())
    return faces


def test_multi_uv_board_shows_the_logo_its_second_uv_set_maps():
    """MultiUVTest's emissive texture holds the glTF logo in its top-left quarter and "Multiple
    UVs not supported in this viewer" (white text) elsewhere; TEXCOORD_1 maps every face onto the
    logo, TEXCOORD_0 onto the text (its README and screenshot). Lit by its emission alone, each
    face the camera sees shows green logo texels and no white text; read with TEXCOORD_0, the same
    faces show text and no logo."""
    scene = multi_uv_board()
    prim = scene.primitives[0]
    # the accessor's declared bounds (glTF requires min and max on POSITION only; this file gives them)
    np.testing.assert_allclose(prim.uvs1.min(axis=0), [0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(prim.uvs1.max(axis=0), [0.25, 0.25], atol=1e-7)
    assert prim.material.emissive_texture.texcoord == 1 and prim.material.base_color_texture.texcoord == 0
    cam = scene.cameras[0]  # the file's, which the screenshot shows
    faces = face_colours(render_checked(scene, cam, size=(160, 120)))
    assert len(faces) == 3
    for white, green in faces.values():
        assert white < 0.002 and green > 0.05, faces
    prim.material.emissive_texture.texcoord = 0
    faces = face_colours(render_checked(scene, cam, size=(160, 120)))
    for white, green in faces.values():
        assert white > 0.01 and green < 0.002, faces


def test_swapping_the_uv_sets_and_the_slots_that_read_them_changes_nothing():
    """The board's cube with uvs and uvs1 exchanged, and each texture reading the other set, is
    the same surface: the same image, lit, textures filtered trilinearly over each set's own
    footprint."""
    scene = multi_uv_board()
    scene.add_light(pw.DirectionalLight(direction=(-0.3, -1.0, -0.5), intensity=3.0))
    prim = scene.primitives[0]
    mat = prim.material
    swapped_mat = dataclasses.replace(mat, base_color_texture=pw.Texture(mat.base_color_texture.image, texcoord=1),
                                      emissive_texture=pw.Texture(mat.emissive_texture.image, texcoord=0))
    swapped = pw.Scene()
    swapped.add_mesh(pw.Primitive(prim.positions, prim.faces, swapped_mat, prim.normals, prim.uvs1, prim.tangents,
                                  uvs1=prim.uvs))
    swapped.lights = scene.lights
    cam = pw.Camera.frame(scene, aspect=1.0)
    for texture_filter in ("trilinear", "bilinear"):
        a = render_checked(scene, cam, size=(64, 64), texture_filter=texture_filter)
        b = render_checked(swapped, cam, size=(64, 64), texture_filter=texture_filter)
        np.testing.assert_allclose(a.rgb, b.rgb, rtol=1e-5, atol=1e-7)


def test_footprint_follows_the_uv_set_a_texture_reads():
    """The head-on plane of test_texture_filtering, its texture read with uvs1 while uvs spans
    a thousandth of the texture: every pixel still reads the level of the uvs1 footprint."""
    head_on_plane_check(2 ** 2.3, "raycast", uv_set=1)


def test_second_uv_set_is_compiled_in_only_when_read_and_explained():
    scene = multi_uv_board()
    features = scene_features(scene, upload(scene), shadows=True, spp=1)
    assert features.second_uv_set
    assert "second uv set (TEXCOORD_1) read by emissive_texture" in pw.explain(scene)
    scene.primitives[0].material.emissive_texture.texcoord = 0
    assert not scene_features(scene, upload(scene), shadows=True, spp=1).second_uv_set
    assert "no second uv set: every texture read uses TEXCOORD_0" in pw.explain(scene)


def test_texcoord_is_validated():
    image = np.zeros((2, 2, 3), np.float32)
    for bad in (2, -1, True, 0.5, "1"):
        with pytest.raises(InputError, match="Texture texcoord must be 0 or 1"):
            pw.Texture(image, texcoord=bad)


@pytest.mark.parametrize("tex_coord", ["1", -1, 1.5, True])
def test_gltf_tex_coord_must_be_a_set_index(tmp_path, tex_coord):
    from pbrwarp.errors import AssetFormatError
    from test_gltf_unhonoured import add_texture, quad_file

    def edit(b):
        add_texture(b)
        b.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = tex_coord

    with pytest.raises(AssetFormatError, match="texCoord must be a non-negative integer"):
        pw.Scene.load(quad_file(tmp_path, edit))
