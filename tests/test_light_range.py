"""KHR_lights_punctual's range: the inverse-square falloff windowed by clamp(1 - (d/range)^4, 0, 1),
checked against the analytic irradiance of a white Lambert plane."""

import math
import warnings

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.errors import InputError

from scenes import quad, render_checked
from test_gltf_unhonoured import add_light, quad_file

HEIGHT = 1.5  # of the light above the plane
INTENSITY = 9.0  # candela


def plane_under(light):
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0))
    scene.add_light(light)
    camera = pw.Camera(eye=(0, 0, 4.0), forward=(0, 0, -1), up=(0, 1, 0), fov_y=90.0)
    return render_checked(scene, camera, size=(65, 65), shadows=False).rgb[..., 0].astype(np.float64)


def expected_radiance(distance, cosine, reach):
    """A white Lambert surface: E / pi, E = I cos / d^2 times the window (1 if no range)."""
    window = 1.0 if reach is None else np.clip(1 - (distance / reach) ** 4, 0, 1)
    return INTENSITY * cosine / distance**2 * window / math.pi


@pytest.mark.parametrize("reach", [None, 3.0, 1.6, 1.0])
@pytest.mark.parametrize("kind", ["point", "spot"])
def test_range_windows_the_inverse_square_law(reach, kind):
    if kind == "point":
        light = pw.PointLight(position=(0, 0, HEIGHT), intensity=INTENSITY, range=reach)
    else:
        light = pw.SpotLight(position=(0, 0, HEIGHT), direction=(0, 0, -1), intensity=INTENSITY, range=reach,
                             inner_cone=1.5, outer_cone=1.55)
    image = plane_under(light)
    # the pixel under the light and one off to the side, where the plane point is (x, 0, 0)
    centre = image[32, 32]
    assert centre == pytest.approx(expected_radiance(HEIGHT, 1.0, reach), rel=1e-4, abs=1e-7)
    x = 4.0 * math.tan(math.radians(45.0)) * (40 - 32) / 32.5  # the plane point seen at column 40
    d = math.hypot(x, HEIGHT)
    assert image[32, 40] == pytest.approx(expected_radiance(d, HEIGHT / d, reach), rel=2e-3, abs=1e-7)


def test_nothing_beyond_the_range():
    image = plane_under(pw.PointLight(position=(0, 0, HEIGHT), intensity=INTENSITY, range=2.0))
    ys, xs = np.mgrid[:65, :65]
    # plane coordinates of each pixel centre; the distance to the light
    scale = 4.0 / 32.5
    distance = np.hypot(np.hypot((xs - 32) * scale, (ys - 32) * scale), HEIGHT)
    assert np.all(image[distance > 2.0 * 1.01] == 0.0)
    assert np.all(image[distance < 2.0 * 0.99] > 0.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan"), 1e39])
def test_range_must_be_a_positive_distance(bad):
    with pytest.raises(InputError, match="range"):
        pw.PointLight(range=bad)
    light = pw.SpotLight()
    with pytest.raises(InputError, match="range"):
        light.range = bad
    assert light.range is None


def test_gltf_range_is_read_without_a_warning(tmp_path):
    path = quad_file(tmp_path, lambda b: add_light(b, range=5.0, intensity=2.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = pw.Scene.load(path)
    (light,) = scene.lights
    assert isinstance(light, pw.PointLight) and light.range == 5.0 and light.intensity == 2.0
