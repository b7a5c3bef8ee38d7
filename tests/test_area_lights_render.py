"""Area lights in the direct integrator: images against analytic irradiance (a Lambert plane under
a sphere and under a rectangle), both rungs, the Monte Carlo rung converging, soft shadows, no
NaN at or inside the light, and what explain and the compiled features say."""

import math

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.loading import generated_source
from pbrwarp.kernels.render import render_kernel

from scenes import box, head_on_camera, lambert_white, quad, render_checked as render
from test_area_lights import brute_force_projected_solid_angle, parallel_rect_form_factor
from test_images import hit_points

CAM = head_on_camera(distance=5.0, fov=50.0)
REPRESENTATIVE = pw.AreaLighting()
# The sample counts are compiled in: the tests keep to few of them.
SAMPLES = 64


def monte_carlo(samples):
    return pw.AreaLighting(method="monte_carlo", samples=samples)


def plane_under(*lights, size=12.0, material=None):
    scene = pw.Scene()
    scene.add_mesh(quad(size=size, material=material))
    for light in lights:
        scene.add_light(light)
    return scene


SPHERE_CENTRE = np.array([0.3, -0.2, 1.5])


def sphere_scene(intensity=5.0):
    return plane_under(pw.SphereLight(position=tuple(SPHERE_CENTRE), radius=0.4, intensity=intensity))


def sphere_expected(p, intensity=5.0, radius=0.4):
    """A white Lambert plane under a sphere wholly above its horizon: radiance
    (1 / pi) pi L sin^2(alpha) cos(theta) = L r^2 h / d^3."""
    d = SPHERE_CENTRE - p
    dist = np.linalg.norm(d, axis=-1)
    return intensity * radius**2 * d[..., 2] / dist**3


RECT = dict(position=(0.2, -0.1, 1.2), edge_u=(0.0, 1.6, 0.0), edge_v=(2.4, 0.0, 0.0))  # emits along -z


def rect_expected(p, intensity=3.0):
    """A white Lambert plane under a parallel rectangle: radiance L F, F the form factor."""
    flat = p.reshape(-1, 3)
    f = [parallel_rect_form_factor(-1.0, 1.4, -0.9, 0.7, 1.2, x, y) for x, y, _ in flat]
    return intensity * np.array(f).reshape(p.shape[:-1])


def relative_errors(frame, expected):
    mask = frame.alpha == 1.0
    return frame.rgb[mask][:, 0] / expected[mask] - 1.0


@pytest.mark.parametrize("rung", [REPRESENTATIVE, monte_carlo(SAMPLES)], ids=["representative", "monte_carlo"])
def test_lambert_plane_under_a_sphere_light(rung):
    frame = render(sphere_scene(), CAM, size=(31, 31), area_lighting=rung)
    errors = relative_errors(frame, sphere_expected(hit_points(frame, CAM)))
    if rung.method == "representative_point":
        assert np.abs(errors).max() < 1e-4  # exact for Lambert, the sphere above the horizon
    else:
        assert np.abs(errors).max() < 0.03
        assert abs(errors.mean()) < 4.0 * errors.std() / math.sqrt(len(errors)) + 1e-4


@pytest.mark.parametrize("rung", [REPRESENTATIVE, monte_carlo(SAMPLES)], ids=["representative", "monte_carlo"])
def test_lambert_plane_under_a_rect_light(rung):
    scene = plane_under(pw.RectLight(intensity=3.0, **RECT))
    frame = render(scene, CAM, size=(31, 31), area_lighting=rung)
    errors = relative_errors(frame, rect_expected(hit_points(frame, CAM)))
    if rung.method == "representative_point":
        assert np.abs(errors).max() < 1e-3  # Lambert's polygon formula: exact
    else:
        assert np.abs(errors).max() < 0.06
        assert abs(errors.mean()) < 4.0 * errors.std() / math.sqrt(len(errors)) + 1e-4


@pytest.mark.parametrize("light, expected", [
    (pw.SphereLight(position=tuple(SPHERE_CENTRE), radius=0.4, intensity=5.0), sphere_expected),
    (pw.RectLight(intensity=3.0, **RECT), rect_expected),
], ids=["sphere", "rect"])
def test_the_monte_carlo_rung_converges(light, expected):
    scene = plane_under(light)
    rms = []
    for samples in (4, SAMPLES):
        frame = render(scene, CAM, size=(31, 31), area_lighting=monte_carlo(samples))
        rms.append(math.sqrt(np.mean(relative_errors(frame, expected(hit_points(frame, CAM))) ** 2)))
    # 16 times the samples: at least the 4 times smaller error of 1 / sqrt(N), less a margin
    assert rms[1] < rms[0] / 3.0, rms


def test_representative_rung_clips_a_rect_at_the_horizon():
    # a wall (the plane x = 0, facing +x) beside a tilted rectangle that crosses its plane: the
    # wall sees the part of the rectangle in front of it, over its horizon
    light = pw.RectLight(position=(0.3, 0.2, 0.7), edge_u=(0.0, -1.4, 0.0), edge_v=(-0.8, 0.0, 0.6), intensity=2.0)
    scene = pw.Scene()
    turn = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    scene.add_mesh(quad(size=3.0), transform=turn)  # +z turned to +x
    scene.add_light(light)
    cam = pw.Camera.look_at(eye=(5.0, 0.0, 0.0), target=(0, 0, 0), fov_y=30.0)
    frame = render(scene, cam, size=(9, 9))
    p = hit_points(frame, cam)
    mask = frame.alpha == 1.0
    assert mask.sum() > 40
    expected = np.array([2.0 * brute_force_projected_solid_angle(light, q, (1.0, 0.0, 0.0)) / math.pi
                         for q in p[mask]])
    assert np.sum(expected > 0.0) > 10
    np.testing.assert_allclose(frame.rgb[mask][:, 0], expected, rtol=3e-3, atol=1e-5)


def shadow_scenes():
    """(with a slab between a rectangle light and the plane, without), with the camera above."""
    light = pw.RectLight(position=(-1.5, 0.0, 2.0), edge_u=(0.0, 1.0, 0.0), edge_v=(1.0, 0.0, 0.0), intensity=4.0)
    lit = plane_under(light, size=10.0)
    shadowed = plane_under(light, size=10.0)
    shadowed.add_mesh(box((2.0, 2.0, 0.001), (-1.5, 0.0, 1.0)), lambert_white())
    return shadowed, lit


@pytest.mark.parametrize("rung", [REPRESENTATIVE, monte_carlo(SAMPLES)], ids=["representative", "monte_carlo"])
def test_soft_shadows_only_from_the_monte_carlo_rung(rung):
    cam = pw.Camera.look_at(eye=(0, 0, 6), target=(0, 0, 0), fov_y=50.0)
    shadowed_scene, lit_scene = shadow_scenes()
    shadowed = render(shadowed_scene, cam, size=(41, 41), area_lighting=rung)
    lit = render(lit_scene, cam, size=(41, 41), area_lighting=rung)
    seen_in_both = (np.abs(shadowed.depth - lit.depth) < 1e-4) & (lit.rgb[..., 0] > 0.0)
    ratio = shadowed.rgb[..., 0][seen_in_both] / lit.rgb[..., 0][seen_in_both]
    assert np.all(ratio <= 1.0 + 1e-6)
    umbra, penumbra = ratio < 1e-6, (ratio > 0.05) & (ratio < 0.95)
    assert umbra.sum() >= 3
    if rung.method == "monte_carlo":
        # the points that see part of the light (0 < x < 1 on the plane, under the slab's edge)
        assert penumbra.sum() >= 20
    else:
        assert penumbra.sum() == 0  # one shadow ray to the centre: hard shadows
    # where nothing is in the way, the same samples give the same light
    assert np.sum(ratio > 1.0 - 1e-6) >= 100


def glossy_and_mirror_plane(light):
    """A 4 x 4 plane at z = 0 under ``light``: its left half glossy (both lobes), its right half a
    mirror (roughness 0)."""
    scene = pw.Scene()
    glossy = pw.Material(base_color=(0.5, 0.5, 0.5), metallic=0.0, roughness=0.3)
    mirror = pw.Material(base_color=(0.9, 0.8, 0.7), metallic=1.0, roughness=0.0)
    for x, material in ((-1.0, glossy), (1.0, mirror)):
        for y in (-1.0, 1.0):
            shift = np.eye(4)
            shift[:2, 3] = (x, y)
            scene.add_mesh(quad(size=2.0, material=material), transform=shift)
    scene.add_light(light)
    return scene


@pytest.mark.parametrize("rung", [REPRESENTATIVE, monte_carlo(SAMPLES)], ids=["representative", "monte_carlo"])
@pytest.mark.parametrize("light", [
    pw.SphereLight(position=(0.0, 0.0, 0.0), radius=0.5, intensity=10.0),  # centred on the plane
    pw.SphereLight(position=(0.2, 0.0, 0.5), radius=0.5, intensity=10.0),  # touching it
    pw.RectLight(position=(0.0, 0.0, 0.0), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, 1.0, 0.0), intensity=10.0),  # in it
    pw.RectLight(position=(0.0, 0.3, 0.5), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, 0.0, 1.0), intensity=10.0),  # upright
], ids=["sphere-centred", "sphere-touching", "rect-in-plane", "rect-upright"])
def test_no_nan_at_on_or_inside_the_light(light, rung):
    scene = glossy_and_mirror_plane(light)
    cam = pw.Camera.look_at(eye=(0.0, -3.0, 3.0), target=(0, 0, 0), fov_y=50.0)
    frame = render(scene, cam, size=(25, 25), area_lighting=rung)  # asserts finite and >= 0
    p = hit_points(frame, cam)
    mask = frame.alpha == 1.0
    if isinstance(light, pw.SphereLight):
        inside = mask & (np.linalg.norm(p - np.asarray(light.position), axis=-1) < light.radius * 0.99)
        assert np.all(frame.rgb[inside] == 0.0)
        assert inside.sum() > 0 or light.position[2] > 0.0  # the centred sphere holds part of the plane
        assert np.any(frame.rgb[mask & ~inside] > 0.0)
    elif light.position[2] == 0.0:
        assert np.all(frame.rgb[mask] == 0.0)  # the plane is in the rectangle's: none of its light
    else:
        assert np.any(frame.rgb[mask] > 0.0)


def test_mixed_lights_add_up_with_shadows_by_rays_and_maps():
    shadowed, _ = shadow_scenes()
    sphere = pw.SphereLight(position=(1.0, 1.0, 1.5), radius=0.3, intensity=20.0)
    point = pw.PointLight(position=(-0.5, -1.0, 2.5), intensity=8.0)
    cam = pw.Camera.look_at(eye=(0, 0, 6), target=(0, 0, 0), fov_y=50.0)
    for shadows in (True, "map"):
        frames = []
        for lights in ([point], [sphere] + shadowed.lights, [point, sphere] + shadowed.lights):
            scene = pw.Scene()
            for prim in shadowed.primitives:
                scene.add_mesh(prim)
            for light in lights:
                scene.add_light(light)
            frames.append(render(scene, cam, size=(25, 25), shadows=shadows).rgb)
        np.testing.assert_allclose(frames[2], frames[0] + frames[1], rtol=1e-5, atol=1e-6)


def test_monte_carlo_images_do_not_depend_on_threads():
    scene = sphere_scene()
    one = render(scene, CAM, size=(17, 17), area_lighting=monte_carlo(SAMPLES), threads=1)
    two = render(scene, CAM, size=(17, 17), area_lighting=monte_carlo(SAMPLES), threads=2)
    np.testing.assert_array_equal(one.rgb, two.rgb)


def test_explain_and_features_say_what_area_lights_compile():
    bare = plane_under(pw.PointLight(position=(0, 0, 2)))
    features = scene_features(bare, upload(bare), shadows=True, spp=1)
    assert not (features.sphere_lights or features.rect_lights or features.area_lighting or features.area_shadows)
    assert "no area lights" in pw.explain(bare)
    source = generated_source(render_kernel(features))
    for absent in ("sphere_irradiance", "rect_irradiance", "sample_sphere_light", "sample_rect_light"):
        assert absent not in source, absent

    scene = sphere_scene()
    features = scene_features(scene, upload(scene), shadows=True, spp=1)
    assert features.sphere_lights and not features.rect_lights and features.area_shadows
    assert features.area_lighting == REPRESENTATIVE
    assert not features.point_lights and features.shadows is False
    source = generated_source(render_kernel(features))
    assert "sphere_irradiance" in source and "rect_irradiance" not in source and "sample_sphere_light" not in source
    text = pw.explain(scene)
    assert "1 sphere light" in text and "representative point" in text and "area-light shadow rays" in text
    assert "light buffers serve punctual lights only" in text
    assert "shadow maps serve punctual lights only" in pw.explain(scene, shadows="map")
    assert "no area-light shadow rays: shadows=False" in pw.explain(scene, shadows=False)
    reference = scene_features(scene, upload(scene), shadows=True, spp=1,
                               area_lighting=pw.lights.area_lighting_for_quality("reference", None))
    assert reference.area_lighting == monte_carlo(64)
    assert "64 points per light and hit" in pw.explain(scene, quality="reference")


def test_unspecialized_kernel_renders_area_lights_alike():
    scene = sphere_scene()
    fast = render(scene, CAM, size=(9, 9))
    full = render(scene, CAM, size=(9, 9), specialize=False)
    np.testing.assert_allclose(full.rgb, fast.rgb, rtol=1e-5, atol=1e-7)
