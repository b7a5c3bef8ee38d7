"""Alpha-masked (glTF alphaMode MASK) surfaces let shadow rays, shadow maps and shadowed
environment rays through where they are cut out, as they let camera rays through: a white Lambert floor lit straight down by E lux has radiance
E/pi beneath a cut-out and 0 beneath an opaque part."""

import math
import sys

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.light_buffers import no_light_buffers
from pbrwarp.scene import Primitive

from scenes import render_checked

E = 3.0
# pure Lambert: specular 0 and metallic 0 leave no specular lobe
WHITE = dict(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=1.0, specular=0.0)
CAMERA = pw.Camera.look_at(eye=(0.0, 0.5, 3.0), target=(0.0, 0.0, 0.0), fov_y=40.0)
SIZE = (96, 72)


def quad(y, x0=-1.0, x1=1.0, material=None):
    """A horizontal square at height y over x in [x0, x1], z in [-1, 1], u along x."""
    positions = np.array([[x0, y, -1.0], [x1, y, -1.0], [x1, y, 1.0], [x0, y, 1.0]], np.float32)
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], np.float32)
    normals = np.tile(np.array([0.0, 1.0, 0.0], np.float32), (4, 1))
    return Primitive(positions, np.array([[0, 2, 1], [0, 3, 2]], np.int64), material, normals, uvs)


def scene_with(*occluders, light=None):
    scene = pw.Scene()
    scene.add_mesh(trimesh.Trimesh([[-6, 0, -6], [6, 0, -6], [6, 0, 6], [-6, 0, 6]], [[0, 2, 1], [0, 3, 2]]),
                   pw.Material(**WHITE))
    for occluder in occluders:
        scene.add_mesh(occluder)
    scene.add_light(light or pw.DirectionalLight(direction=(0.0, -1.0, 0.0), intensity=E))
    return scene


def masked(alpha=None, texture=None):
    colour = (1.0, 1.0, 1.0, 1.0 if alpha is None else alpha)
    return pw.Material(base_color=colour, alpha_mode="MASK", alpha_cutoff=0.5, base_color_texture=texture,
                       double_sided=True)


def under_quad(frame):
    """Radiance of the floor pixels straight beneath the quad's middle (|x|, |z| < 0.8)."""
    depth, h, w = frame.depth, *frame.depth.shape
    ys, xs = np.mgrid[0:h, 0:w]
    # world positions of the pixel centres from the camera and depth (distance along the ray)
    forward = np.asarray(CAMERA.forward, float)
    right, up = np.asarray(CAMERA.right, float), np.asarray(CAMERA.up, float)
    tan_half = math.tan(math.radians(CAMERA.fov_y) / 2)
    dirs = (forward + right[None, None] * ((xs + 0.5) / w * 2 - 1)[..., None] * tan_half * w / h
            + up[None, None] * (1 - (ys + 0.5) / h * 2)[..., None] * tan_half)
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    points = np.asarray(CAMERA.eye, float) + dirs * depth[..., None]
    inside = (np.abs(points[..., 0]) < 0.8) & (np.abs(points[..., 2]) < 0.8) & (np.abs(points[..., 1]) < 1e-3)
    assert inside.sum() > 100
    return frame.rgb[inside], points[inside]


@pytest.mark.parametrize("alpha,expected", [(0.0, E / math.pi), (1.0, 0.0)])
def test_a_cut_out_casts_no_shadow_and_an_opaque_mask_does(alpha, expected):
    frame = render_checked(scene_with(quad(1.0, material=masked(alpha))), CAMERA, size=SIZE)
    radiance, _ = under_quad(frame)
    np.testing.assert_allclose(radiance, expected, rtol=1e-5, atol=1e-6)


def test_light_passes_several_cut_outs():
    frame = render_checked(scene_with(quad(1.0, material=masked(0.0)), quad(1.5, material=masked(0.2)),
                                      quad(2.0, material=masked(0.4))), CAMERA, size=SIZE)
    np.testing.assert_allclose(under_quad(frame)[0], E / math.pi, rtol=1e-5)


@pytest.mark.parametrize("light", [pw.DirectionalLight(direction=(0.0, -1.0, 0.0), intensity=E),
                                   pw.PointLight(position=(0.3, 4.0, 0.2), intensity=40.0)],
                         ids=["directional", "point"])
def test_a_textured_mask_shadows_only_where_it_is_opaque(light, monkeypatch):
    """The left half of a 64-texel-wide alpha texture is cut out: the floor is shadowed as by an
    opaque quad over the right half only, with and without light buffers."""
    rgba = np.full((8, 64, 4), 255, np.uint8)
    rgba[:, :32, 3] = 0
    texture = pw.Texture(rgba, wrap_s="clamp", wrap_t="clamp")
    cut = render_checked(scene_with(quad(1.0, material=masked(texture=texture)), light=light), CAMERA, size=SIZE)
    half = render_checked(scene_with(quad(1.0, 0.0, 1.0, material=pw.Material(**WHITE)), light=light), CAMERA,
                          size=SIZE)
    differs = ~np.all(np.isclose(cut.rgb, half.rgb, rtol=1e-5, atol=1e-6), axis=-1)
    # only along the texture's one-texel blend between the halves
    assert differs.mean() < 0.02, differs.mean()
    lit, points = under_quad(cut)
    assert np.all(lit[points[:, 0] < -0.1] > 0.0) and np.all(lit[points[:, 0] > 0.1] == 0.0)
    monkeypatch.setattr(sys.modules["pbrwarp.render"], "build_light_buffers", lambda *args: no_light_buffers())
    bvh_only = render_checked(scene_with(quad(1.0, material=masked(texture=texture)), light=light), CAMERA, size=SIZE)
    np.testing.assert_array_equal(cut.rgb, bvh_only.rgb)


@pytest.mark.parametrize("light", [pw.DirectionalLight(direction=(0.0, -1.0, 0.0), intensity=E),
                                   pw.PointLight(position=(0.3, 4.0, 0.2), intensity=40.0)],
                         ids=["directional", "point"])
def test_shadow_maps_see_through_cut_outs(light):
    """Shadow maps, rasterized from the light, look through a masked quad where it is cut out:
    beneath a fully cut-out quad the floor is lit as with no quad at all, and a half-masked
    texture shadows like the ray-traced reference but along its blurred edge."""
    bare = render_checked(scene_with(light=light), CAMERA, size=SIZE, shadows="map")
    cut = render_checked(scene_with(quad(1.0, material=masked(0.0)), light=light), CAMERA, size=SIZE, shadows="map")
    np.testing.assert_array_equal(cut.rgb, bare.rgb)
    rgba = np.full((8, 64, 4), 255, np.uint8)
    rgba[:, :32, 3] = 0
    texture = pw.Texture(rgba, wrap_s="clamp", wrap_t="clamp")
    scene = scene_with(quad(1.0, material=masked(texture=texture)), light=light)
    mapped = render_checked(scene, CAMERA, size=SIZE, shadows="map")
    traced = render_checked(scene, CAMERA, size=SIZE, shadows="rays")
    differs = ~np.all(np.isclose(mapped.rgb, traced.rgb, rtol=1e-3, atol=1e-4), axis=-1)
    assert differs.mean() < 0.03, differs.mean()


def test_shadow_maps_follow_a_changed_cut_out():
    material = masked(0.0)
    scene = scene_with(quad(1.0, material=material))
    assert under_quad(render_checked(scene, CAMERA, size=SIZE, shadows="map"))[0].min() > 0.0
    material.base_color = (1.0, 1.0, 1.0, 1.0)
    assert under_quad(render_checked(scene, CAMERA, size=SIZE, shadows="map"))[0].max() == 0.0


def test_shadowed_environment_light_passes_cut_outs():
    """Monte Carlo environment light traced against the scene: a cut-out quad over the floor
    changes nothing, an opaque one darkens it."""
    ibl = pw.IBL(method="monte_carlo", samples=16, shadowed=True)

    def render(*occluders):
        scene = scene_with(*occluders)
        scene.lights.clear()
        scene.environment = pw.Environment.uniform((1.0, 1.0, 1.0))
        return render_checked(scene, CAMERA, size=SIZE, ibl=ibl, background=(0.0, 0.0, 0.0))

    bare = render()
    np.testing.assert_array_equal(render(quad(1.0, material=masked(0.0))).rgb, bare.rgb)
    assert under_quad(render(quad(1.0, material=masked(1.0))))[0].mean() < 0.9 * under_quad(bare)[0].mean()


def test_explain_says_occlusion_rays_pass_cut_outs():
    assert "occlusion rays pass alpha cut-outs (1 material)" in pw.explain(scene_with(quad(1.0, material=masked(0.0))))
    assert "no cut-outs in occlusion rays" in pw.explain(scene_with(quad(1.0, material=pw.Material())))
