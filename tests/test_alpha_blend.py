"""glTF alphaMode BLEND: a surface's alpha is its coverage, composited front to back along camera
rays; the frame's alpha is the coverage so composited."""

import math

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload

from assets import BOARDS, board
from scenes import head_on_camera, quad, render_checked

E = 3.0
GLOW = (0.2, 0.5, 0.9)  # radiance of the emissive plane behind, nits
CAMERA = head_on_camera(distance=3.0, fov=20.0)
SIZE = (24, 24)


def white_blend(alpha):
    """A white Lambert surface of coverage ``alpha``."""
    return pw.Material(base_color=(1.0, 1.0, 1.0, alpha), metallic=0.0, roughness=1.0, specular=0.0,
                       alpha_mode="BLEND")


def glowing(colour=GLOW):
    """A black emitter: its radiance is ``colour`` whatever lights it."""
    return pw.Material(base_color=(0.0, 0.0, 0.0), specular=0.0, emissive=colour)


def layered(*planes, light=True):
    """Planes facing the camera (z, material), each larger than the view, under a directional
    light of E lux straight onto them."""
    scene = pw.Scene()
    for z, material in planes:
        scene.add_mesh(quad(size=4.0, z=z, material=material))
    if light:
        scene.add_light(pw.DirectionalLight(direction=(0.0, 0.0, -1.0), intensity=E))
    return scene


@pytest.mark.parametrize("alpha", [0.0, 0.25, 0.5, 1.0])
def test_a_blended_plane_mixes_with_what_lies_behind(alpha):
    """alpha E/pi of the white Lambert plane plus (1 - alpha) of the emitter behind it. (The
    emitter is black, so the shadow the blended plane casts on it changes nothing.)"""
    frame = render_checked(layered((0.5, white_blend(alpha)), (0.0, glowing())), CAMERA, size=SIZE)
    expected = alpha * E / math.pi + (1.0 - alpha) * np.array(GLOW)
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), np.broadcast_to(expected, (SIZE[0] * SIZE[1], 3)),
                               rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(frame.alpha, 1.0)


@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.0])
def test_the_frame_alpha_is_the_coverage(alpha):
    """Over the background: rgb = alpha E/pi + (1 - alpha) background, frame alpha = alpha."""
    background = (0.1, 0.3, 0.2)
    frame = render_checked(layered((0.5, white_blend(alpha))), CAMERA, size=SIZE, background=background)
    np.testing.assert_allclose(frame.alpha, alpha, rtol=1e-6)
    expected = alpha * E / math.pi + (1.0 - alpha) * np.array(background)
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), np.broadcast_to(expected, (SIZE[0] * SIZE[1], 3)),
                               rtol=1e-5, atol=1e-7)


def test_two_blended_planes_composite_in_depth_order_whatever_the_file_order():
    """Unlit red (alpha 0.3) in front of unlit blue (alpha 0.6) over black: 0.3 red + 0.7 * 0.6
    blue, coverage 1 - 0.7 * 0.4; listing the planes the other way round changes nothing."""
    red = pw.Material(base_color=(1.0, 0.0, 0.0, 0.3), alpha_mode="BLEND", unlit=True)
    blue = pw.Material(base_color=(0.0, 0.0, 1.0, 0.6), alpha_mode="BLEND", unlit=True)
    frames = [render_checked(layered(*planes, light=False), CAMERA, size=SIZE)
              for planes in (((0.5, red), (0.0, blue)), ((0.0, blue), (0.5, red)))]
    for frame in frames:
        np.testing.assert_allclose(frame.rgb, np.broadcast_to((0.3, 0.0, 0.7 * 0.6), frame.rgb.shape), atol=1e-7)
        np.testing.assert_allclose(frame.alpha, 1.0 - 0.7 * 0.4, rtol=1e-6)
    np.testing.assert_array_equal(frames[0].rgb, frames[1].rgb)


@pytest.mark.parametrize("visibility", ["raycast", "raster"])
def test_both_visibility_paths_look_past_the_blended_surface(visibility):
    """The raster keeps only the nearest surface; the composite queries the BVH past it."""
    scene = layered((0.5, white_blend(0.5)), (0.0, glowing()))
    frame = render_checked(scene, CAMERA, size=SIZE, visibility=visibility)
    np.testing.assert_allclose(frame.rgb[12, 12], 0.5 * E / math.pi + 0.5 * np.array(GLOW), rtol=1e-5)


def test_the_environment_shows_through_in_proportion():
    scene = layered((0.5, white_blend(0.25)), light=False)
    scene.environment = pw.Environment.uniform(intensity=0.0)
    frame = render_checked(scene, CAMERA, size=SIZE)
    np.testing.assert_allclose(frame.rgb, 0.0, atol=1e-7)
    scene.environment = pw.Environment.uniform(intensity=2.0)
    glow = pw.Material(base_color=(1.0, 1.0, 1.0, 0.25), alpha_mode="BLEND", unlit=True)
    scene = layered((0.5, glow), light=False)
    scene.environment = pw.Environment.uniform(intensity=2.0)
    frame = render_checked(scene, CAMERA, size=SIZE)
    np.testing.assert_allclose(frame.rgb, 0.25 * 1.0 + 0.75 * 2.0, rtol=1e-5)


def test_blending_is_compiled_in_only_when_a_material_blends():
    opaque = layered((0.5, pw.Material()), (0.0, glowing()))
    assert not scene_features(opaque, upload(opaque), shadows=True, spp=1).alpha_blend
    assert "no alpha blending" in pw.explain(opaque)
    blended = layered((0.5, white_blend(0.5)), (0.0, glowing()))
    assert scene_features(blended, upload(blended), shadows=True, spp=1).alpha_blend
    assert "composite alpha-blended coverage front to back (1 material;" in pw.explain(blended)
    special = render_checked(blended, CAMERA, size=SIZE)
    general = render_checked(blended, CAMERA, size=SIZE, specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)
    np.testing.assert_array_equal(special.alpha, general.alpha)


def red_pixels(frame):
    r, g, b = np.moveaxis(frame.rgb, -1, 0)
    return int(np.sum((r > 0.05) & (r > 3.0 * g) & (r > 3.0 * b)))


@pytest.mark.skipif("AlphaBlendModeTest" not in BOARDS, reason="AlphaBlendModeTest needs PBRWARP_TEST_ASSETS")
def test_alpha_blend_board_shows_no_red_cross():
    """AlphaBlendModeTest: red crosses of zero alpha hide behind the BLEND box's ramp and the
    OPAQUE box's check marks; they show only where a mode is applied wrongly (its README). Rendered
    with BLEND treated as OPAQUE they appear, so the test can see them."""
    scene = pw.Scene.load(board("AlphaBlendModeTest"))
    assert scene.load_warnings == ()
    scene.environment = pw.Environment.uniform(intensity=1.0)
    camera = pw.Camera.frame(scene, aspect=2.0)
    # bilinear: the thin crosses stay sharp rather than blended into their surroundings by a
    # coarser mip level, so that where they show the test sees them
    frame = render_checked(scene, camera, size=(256, 128), texture_filter="bilinear")
    assert red_pixels(frame) == 0
    for prim in scene.primitives:
        if prim.material.alpha_mode == "BLEND":
            prim.material.alpha_mode = "OPAQUE"
    assert red_pixels(render_checked(scene, camera, size=(256, 128), texture_filter="bilinear")) > 0


@pytest.mark.parametrize("alpha", [0.0, 0.25, 0.75, 1.0])
def test_the_path_tracers_shadow_rays_pass_a_blended_surface_by_one_minus_alpha(alpha):
    """Paths pass a blended surface with probability 1 - alpha, so next-event estimation's shadow
    rays must pass that share of the light, or the two strategies MIS combines would disagree: a
    white Lambert plane under a black blended plane of coverage alpha, lit straight through it by
    E lux, has radiance (1 - alpha) E / pi at max_bounces=1. The blended plane faces away from
    the camera, whose rays pass single-sided back faces, so nothing is drawn: the result is exact."""
    shade = quad(size=4.0, z=0.5, material=pw.Material(base_color=(0.0, 0.0, 0.0, alpha), specular=0.0,
                                                       alpha_mode="BLEND", double_sided=False))
    shade = pw.Primitive(shade.positions, shade.faces[:, ::-1], shade.material, -shade.normals, shade.uvs)
    scene = layered((0.0, white_blend(1.0)))
    scene.primitives.append(shade)
    frame = pw.render(scene, CAMERA, width=SIZE[0], height=SIZE[1], spp=4, integrator="path", max_bounces=1,
                      progress=False)
    np.testing.assert_allclose(frame.rgb, (1.0 - alpha) * E / math.pi, rtol=1e-5, atol=1e-7)


def test_a_blended_emitter_lights_the_path_tracers_scene_by_its_coverage():
    """Paths meet an alpha-blended emitter with probability alpha; next-event estimation must weigh
    its emission by alpha too: a white plane under a blended emitter of coverage 0.4 and radiance
    L is lit as under an opaque one of radiance 0.4 L (the emitter faces the plane, away from the
    camera, whose rays pass single-sided back faces)."""

    def lit_by(material):
        panel = quad(size=1.5, z=1.0, material=material)
        scene = layered((0.0, white_blend(1.0)), light=False)
        scene.primitives.append(pw.Primitive(panel.positions, panel.faces[:, ::-1], material, -panel.normals,
                                             panel.uvs))
        return pw.render(scene, head_on_camera(distance=0.9, fov=60.0), width=16, height=16, spp=64,
                         integrator="path", max_bounces=1, seed=4, progress=False).rgb.mean()

    glow = (2.0, 2.0, 2.0)
    blended = lit_by(pw.Material(base_color=(0.0, 0.0, 0.0, 0.4), specular=0.0, emissive=glow, alpha_mode="BLEND",
                                 double_sided=False))
    opaque = lit_by(pw.Material(base_color=(0.0, 0.0, 0.0), specular=0.0, emissive=tuple(0.4 * g for g in glow),
                                double_sided=False))
    assert blended == pytest.approx(opaque, rel=0.03)
