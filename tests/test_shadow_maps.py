"""Shadow maps, the fast shadow rung: they agree with ray-traced shadows away from shadow edges, show
no acne at any scene scale, are reused while lights and geometry stay, and reject bad settings."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw

from scenes import box, render_checked

LIGHTS = {
    "directional": pw.DirectionalLight(direction=(-0.8, -1.0, -0.4), intensity=3.0),
    "point": pw.PointLight(position=(1.0, 3.0, 1.0), intensity=40.0),
    "narrow spot": pw.SpotLight(position=(0.5, 4.0, 0.5), direction=(-0.1, -1.0, -0.1), intensity=80.0,
                                inner_cone=0.3, outer_cone=0.6),
    "wide spot (cube map)": pw.SpotLight(position=(0.5, 2.5, 0.5), direction=(0.0, -1.0, 0.0), intensity=60.0,
                                         inner_cone=0.8, outer_cone=1.3),
}


def floor_and_blocks(light, scale=1.0, offset=(0.0, 0.0, 0.0)):
    """A floor with a box and a sphere above it, everything scaled and moved as one."""
    m = trimesh.transformations.translation_matrix(offset) @ np.diag([scale, scale, scale, 1.0])
    scene = pw.Scene()
    scene.add_mesh(box((8, 0.1, 8), (0, -1, 0)), pw.Material(base_color=(0.8, 0.8, 0.8)), transform=m)
    scene.add_mesh(box((1.5, 1, 1.5), (-0.8, -0.2, 0)), pw.Material(base_color=(0.7, 0.3, 0.2), roughness=0.4), transform=m)
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3, radius=0.7), pw.Material(base_color=(0.2, 0.4, 0.7)),
                   transform=m @ trimesh.transformations.translation_matrix((1.0, 0.0, 0.5)))
    moved = light
    if hasattr(light, "position"):
        position = (m @ np.append(light.position, 1.0))[:3]
        moved = type(light)(**{**light.__dict__, "position": tuple(position)})
    scene.add_light(moved)
    cam = pw.Camera.look_at(eye=tuple((m @ [0.0, 4.0, 4.0, 1.0])[:3]), target=tuple((m @ [0.0, -1.0, 0.0, 1.0])[:3]))
    return scene, cam


def mismatch(a, b):
    """Share of pixels whose radiance differs by more than 1%."""
    return np.mean(np.abs(a - b).sum(-1) > 0.01 * np.maximum(b.sum(-1), 1e-12))


@pytest.mark.parametrize("kind", list(LIGHTS))
def test_shadow_maps_agree_with_ray_traced_shadows(kind):
    scene, cam = floor_and_blocks(LIGHTS[kind])
    rays = render_checked(scene, cam, size=(96, 72), shadows="rays")
    maps = render_checked(scene, cam, size=(96, 72), shadows=pw.ShadowMap(resolution=2048, pcf=1))
    no_shadows = render_checked(scene, cam, size=(96, 72), shadows=False)
    shadowed = mismatch(no_shadows.rgb, rays.rgb)
    assert shadowed >= 0.03  # there are shadows to get right
    # only pixels along shadow edges may disagree
    assert mismatch(maps.rgb, rays.rgb) <= 0.1 * shadowed, (mismatch(maps.rgb, rays.rgb), shadowed)


@pytest.mark.parametrize("scale,offset", [(1e-3, (0, 0, 0)), (1e3, (0, 0, 0)), (1.0, (1e4, 0, 0))])
def test_no_acne_and_the_same_shadows_at_any_scale(scale, offset):
    """Bias and normal offset are measured in texels, so the shadows do not depend on the scene's
    size or place; a lit surface never shadows itself."""
    light = LIGHTS["point"]
    reference, cam = floor_and_blocks(light)
    scaled, scaled_cam = floor_and_blocks(light, scale, offset)
    want = render_checked(reference, cam, size=(96, 72), shadows="map")
    got = render_checked(scaled, scaled_cam, size=(96, 72), shadows="map")
    # radiance of a point light scales with 1/scale^2: compare normalized images
    assert mismatch(got.rgb / got.rgb.max(), want.rgb / want.rgb.max()) <= 0.01
    rays = render_checked(scaled, scaled_cam, size=(96, 72), shadows="rays")
    assert mismatch(got.rgb, rays.rgb) <= 0.03


def test_lit_floor_has_no_self_shadowing():
    """A bare plane under a light at 80 degrees from its normal: every pixel fully lit."""
    scene = pw.Scene()
    scene.add_mesh(box((8, 0.1, 8), (0, -1, 0)), pw.Material(base_color=(0.8, 0.8, 0.8)))
    scene.add_mesh(box((0.1, 0.1, 0.1), (30, 30, 30)))  # far away, only so shadows stay on
    scene.add_light(pw.DirectionalLight(direction=(np.sin(1.4), -np.cos(1.4), 0.0), intensity=3.0))
    cam = pw.Camera.look_at(eye=(0, 4, 4), target=(0, -1, 0))
    rays = render_checked(scene, cam, size=(64, 48), shadows="rays")
    maps = render_checked(scene, cam, size=(64, 48), shadows="map")
    covered = rays.alpha > 0
    np.testing.assert_allclose(maps.rgb[covered], rays.rgb[covered], rtol=1e-6)


def test_maps_are_reused_until_lights_or_geometry_move():
    scene, cam = floor_and_blocks(LIGHTS["point"])
    from pbrwarp.gpu_scene import upload
    from pbrwarp.shadow_maps import build

    def kept():
        return build(scene, upload(scene), pw.ShadowMap(), None)

    render_checked(scene, cam, size=(32, 24), shadows="map")
    first = kept()
    scene.lights[0].intensity = 80.0
    render_checked(scene, pw.Camera.look_at(eye=(1, 5, 6), target=(0, -1, 0)), size=(32, 24), shadows="map")
    assert kept() is first
    scene.lights[0].position = (1.0, 3.5, 1.0)
    render_checked(scene, cam, size=(32, 24), shadows="map")
    assert kept() is not first


def test_settings_are_validated_and_explained():
    scene, cam = floor_and_blocks(LIGHTS["directional"])
    assert "shadow maps" in pw.explain(scene, shadows="map")
    assert "shadow rays" in pw.explain(scene, shadows="rays")
    for bad, match in ((dict(resolution=8), "resolution"), (dict(pcf=0), "pcf"), (dict(bias=-1.0), "bias")):
        with pytest.raises(pw.InputError, match=match):
            pw.ShadowMap(**bad)
    with pytest.raises(pw.InputError, match="shadows"):
        pw.render(scene, cam, width=8, height=8, shadows="maps")
