"""Hard lighting cases: lights on and inside surfaces, hard spot cones, tangent light, 1e30 and
1e-30 intensities. No NaN, no Inf, and tone mapping turns huge values into white."""

import math

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.diagnostics import MAX_PLAUSIBLE_RADIANCE

from scenes import head_on_camera, lambert_white, quad, render_checked as render


@pytest.mark.parametrize("height", [1e-3, 1e-12, 0.0])
@pytest.mark.parametrize("material", [lambert_white(), pw.Material(base_color=(1.0, 0.0, 0.0), metallic=1.0, roughness=0.0)])
def test_point_light_on_the_surface(height, material):
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, material=material))
    scene.add_light(pw.PointLight(position=(0.0, 0.0, height), intensity=10.0))
    render(scene, head_on_camera())


def test_point_light_inside_a_closed_mesh_lights_nothing_outside():
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), lambert_white())
    scene.add_light(pw.PointLight(position=(0.1, 0.2, 0.0), intensity=100.0))
    frame = render(scene, head_on_camera(distance=4.0))
    assert np.all(frame.rgb == 0.0)


@pytest.mark.parametrize("intensity", [1e30, 3e38])
@pytest.mark.parametrize("distance", [1.0, 1e-12])
def test_huge_intensities_stay_finite_and_tone_map_to_white(intensity, distance):
    scene = pw.Scene()
    # black in green and blue: an Inf irradiance times a zero BRDF channel would be NaN
    scene.add_mesh(quad(size=4.0, material=pw.Material(base_color=(1.0, 0.0, 0.0), roughness=0.3, specular=0.0)))
    scene.add_light(pw.PointLight(position=(0.0, 0.0, distance), intensity=intensity))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=intensity))
    frame = pw.render(scene, head_on_camera(), width=9, height=9, progress=False)
    report = pw.check(frame)
    assert (report.nan, report.inf, report.negative) == (0, 0, 0), report
    assert frame.rgb[4, 4, 0] > 1e20
    # a white Lambert surface lit head-on by E lux has radiance E/pi: where that is beyond
    # pw.check's bound (or float32's range, clamped), the check says so
    expected = intensity * (1.0 + 1.0 / distance**2) / math.pi
    assert report.ok == (expected <= MAX_PLAUSIBLE_RADIANCE), (report, expected)
    for tonemap in ("none", "reinhard", "aces"):
        assert np.all(frame.to_srgb8(tonemap=tonemap)[4, 4, 0] == 255)


def test_intensity_beyond_float32_is_rejected():
    scene = pw.Scene()
    scene.add_mesh(quad())
    scene.add_light(pw.PointLight(position=(0, 0, 1), intensity=1e39))
    with pytest.raises(pw.InputError, match="float32"):
        pw.render(scene, head_on_camera(), width=4, height=4, progress=False)


def test_tiny_intensities_give_tiny_non_negative_radiance():
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=1e-30))
    frame = render(scene, head_on_camera(), size=(5, 5))
    np.testing.assert_allclose(frame.rgb[2, 2], 1e-30 / math.pi, rtol=1e-5)
    assert np.all(frame.to_srgb8() == 0)


def test_spot_with_equal_inner_and_outer_cones_is_a_hard_cone():
    cone = math.radians(20.0)
    scene = pw.Scene()
    scene.add_mesh(quad(size=6.0))
    scene.add_light(pw.SpotLight(position=(0, 0, 2), direction=(0, 0, -1), intensity=10.0, inner_cone=cone, outer_cone=cone))
    cam = head_on_camera(distance=5.0, fov=50.0)
    frame = render(scene, cam, size=(61, 61))
    # pixel centre hit points: radius on the plane, angle to the spot axis
    h, w = frame.depth.shape
    tan_half = math.tan(math.radians(cam.fov_y) / 2)
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * tan_half * 5.0
    X, Y = np.meshgrid(xs, -xs)
    angle = np.arctan2(np.hypot(X, Y), 2.0)
    inside, outside = angle < cone - 0.01, angle > cone + 0.01
    d2 = X**2 + Y**2 + 4.0
    cos = 2.0 / np.sqrt(d2)
    np.testing.assert_allclose(frame.rgb[inside][:, 0], (10.0 * cos / d2 / math.pi)[inside], rtol=1e-4)
    assert np.all(frame.rgb[outside] == 0.0)


@pytest.mark.parametrize("tilt", [0.0, 1e-7, -1e-7])
def test_directional_light_tangent_to_the_surface(tilt):
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, material=pw.Material(roughness=0.0)))
    scene.add_light(pw.DirectionalLight(direction=(1.0, 0.0, -tilt), intensity=5.0))
    frame = render(scene, head_on_camera())
    assert frame.rgb.max() <= 5.0 * 1e-6  # at most what a 1e-7 grazing cosine lets through
