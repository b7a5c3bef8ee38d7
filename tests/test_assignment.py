"""Scene objects are checked whenever a field is set, not only when made: a bad value raises as
it would in the constructor, leaves the object as it was, and a good one is stored as the
constructor stores it. pw.check flags radiance that is not finite or absurdly high."""

import dataclasses
import math

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.diagnostics import MAX_PLAUSIBLE_RADIANCE

from scenes import head_on_camera, lambert_white, quad

NAN = math.nan


def camera():
    return pw.Camera.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov_y=40.0)


def texture():
    return pw.Texture(np.full((2, 2, 3), 0.5, np.float32))


MAKERS = {
    "camera": camera,
    "point": lambda: pw.PointLight(position=(1.0, 2.0, 3.0), intensity=5.0),
    "directional": lambda: pw.DirectionalLight(direction=(0.0, -1.0, -1.0), intensity=2.0),
    "spot": lambda: pw.SpotLight(position=(0.0, 2.0, 0.0), inner_cone=0.2, outer_cone=0.5),
    "material": lambda: pw.Material(base_color=(0.5, 0.4, 0.3), roughness=0.3),
    "texture": texture,
    "primitive": lambda: quad(),
}

# (object, field, value, what the error says): the cases first
BAD = [
    ("camera", "eye", (NAN, 0.0, 3.0), "Camera eye"),
    ("camera", "eye", (0.0, 0.0, 1e39), "float32"),
    ("camera", "fov_y", 180.0, "fov_y"),
    ("camera", "fov_y", 0.0, "fov_y"),
    ("camera", "fov_y", NAN, "fov_y"),
    ("camera", "forward", (0.0, 0.0, 0.0), "coincide"),
    ("camera", "forward", (0.0, math.inf, 0.0), "Camera forward"),
    ("camera", "up", (0.0, 0.0, 1.0), "parallel"),
    ("camera", "up", (NAN, 1.0, 0.0), "Camera up"),
    ("point", "position", (NAN, 0.0, 0.0), "PointLight.position"),
    ("point", "position", (0.0, 0.0, -1e39), "float32"),
    ("point", "intensity", -1.0, "PointLight.intensity"),
    ("point", "intensity", math.inf, "PointLight.intensity"),
    ("point", "color", (1.0, -1.0, 1.0), "PointLight.color"),
    ("directional", "direction", (0.0, 0.0, 0.0), "zero vector"),
    ("directional", "direction", (NAN, 1.0, 0.0), "DirectionalLight.direction"),
    ("spot", "position", (0.0, NAN, 0.0), "SpotLight.position"),
    ("spot", "inner_cone", 0.8, "inner_cone <= outer_cone"),
    ("spot", "outer_cone", 0.1, "inner_cone <= outer_cone"),
    ("spot", "outer_cone", 2.0, "pi/2"),
    ("spot", "inner_cone", NAN, "SpotLight.inner_cone"),
    ("material", "roughness", 7.0, "Material.roughness"),
    ("material", "base_color", (NAN, 0.5, 0.5), "Material.base_color"),
    ("material", "base_color", (0.5, 0.5, 0.5, 2.0), "alpha"),
    ("material", "metallic", -0.5, "Material.metallic"),
    ("material", "emissive", (0.0, math.inf, 0.0), "Material.emissive"),
    ("material", "alpha_mode", "GLASS", "alpha_mode"),
    ("material", "normal_scale", NAN, "Material.normal_scale"),
    ("material", "base_color_texture", np.full((2, 2), NAN), "Material.base_color_texture"),
    ("material", "complex_ior", ((1.0, 1.0, 1.0), (0.0, -1.0, 0.0)), "complex_ior"),
    ("texture", "wrap_s", "bogus", "wrap_s"),
    ("texture", "offset", (NAN, 0.0), "Texture offset"),
    ("texture", "rotation", math.inf, "Texture rotation"),
    ("texture", "image", np.zeros((0, 4, 3)), "empty"),
    ("primitive", "positions", np.full((4, 3), NAN), "NaN or Inf"),
    ("primitive", "positions", np.zeros((3, 3)), "valid: 0..2"),
    ("primitive", "faces", np.array([[0, 1, 9]]), "valid: 0..3"),
    ("primitive", "uvs", np.zeros((3, 2)), "4 vertices but 3 uvs"),
    ("primitive", "normals", np.full((4, 3), math.inf), "NaN or Inf"),
    ("primitive", "material", "red", "pbrwarp.Material"),
]


def fields(obj) -> dict:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)
    return a is b or a == b


@pytest.mark.parametrize("kind,field,value,match", BAD, ids=lambda v: v if isinstance(v, str) else None)
def test_a_bad_assignment_raises_and_changes_nothing(kind, field, value, match):
    obj = MAKERS[kind]()
    before = fields(obj)
    with pytest.raises((pw.InputError, pw.InputTypeError), match=match):
        setattr(obj, field, value)
    after = fields(obj)
    assert all(same(before[name], after[name]) for name in before), field
    # the constructor refuses the same value, with the same message
    with pytest.raises((pw.InputError, pw.InputTypeError), match=match):
        dataclasses.replace(MAKERS[kind](), **{field: value})


GOOD = [
    ("camera", "forward", (0.0, 0.0, -5.0)),
    ("camera", "forward", (1.0, 0.0, -1.0)),
    ("camera", "up", (0.3, 2.0, 0.1)),
    ("camera", "eye", [1, 2, 3]),
    ("camera", "fov_y", 90),
    ("point", "position", np.array([1.0, -2.0, 0.5])),
    ("point", "intensity", 7),
    ("directional", "direction", (3.0, -4.0, 0.0)),
    ("spot", "outer_cone", 1.2),
    ("spot", "inner_cone", 0.5),
    ("material", "base_color", (1.0, 0.0, 0.0)),
    ("material", "roughness", 1),
    ("material", "double_sided", 0),
    ("material", "base_color_texture", np.ones((2, 2, 3))),
    ("material", "complex_ior", ([0.2, 0.9, 1.1], [3.9, 2.4, 1.9])),
    ("texture", "wrap_t", "mirror"),
    ("texture", "scale", [2, 3]),
    ("texture", "image", np.zeros((3, 5), np.uint8)),
    ("primitive", "uvs", np.zeros((4, 2))),
    ("primitive", "positions", np.arange(12.0).reshape(4, 3)),
    ("primitive", "faces", [[2, 1, 0]]),
]


@pytest.mark.parametrize("kind,field,value", GOOD, ids=lambda v: v if isinstance(v, str) else None)
def test_a_good_assignment_stores_what_the_constructor_stores(kind, field, value):
    """One check for both: assigning a field leaves the object equal, field by field, to one
    made with that value (normalized vectors, RGBA colours, wrapped textures, ...)."""
    obj = MAKERS[kind]()
    setattr(obj, field, value)
    assert_same_fields(obj, dataclasses.replace(MAKERS[kind](), **{field: value}))


def assert_same_fields(obj, made):
    for name, stored in fields(obj).items():
        expected = getattr(made, name)
        if dataclasses.is_dataclass(stored):
            assert type(stored) is type(expected), name
            assert_same_fields(stored, expected)
        elif stored is None or isinstance(stored, (str, bool)):
            assert type(stored) is type(expected) and stored == expected, name
        else:
            np.testing.assert_allclose(np.asarray(stored, float), np.asarray(expected, float), rtol=0, atol=1e-15,
                                       err_msg=name)


def test_texture_image_assignment_updates_its_texels():
    tex = texture()
    tex.image = np.zeros((3, 5), np.uint8)
    assert tex.shape == (3, 5)
    np.testing.assert_array_equal(tex.texels(False)[..., :3], 0.0)


def test_camera_stays_orthonormal_when_its_axes_are_set():
    cam = camera()
    cam.forward = (1.0, 0.0, -1.0)
    forward, up, right = (np.asarray(v) for v in (cam.forward, cam.up, cam.right))
    np.testing.assert_allclose([forward @ forward, up @ up, right @ right], 1.0, rtol=1e-15)
    np.testing.assert_allclose([forward @ up, forward @ right, up @ right], 0.0, atol=1e-15)
    np.testing.assert_allclose(up, (0.0, 1.0, 0.0), atol=1e-15)  # the old up, still perpendicular
    cam.up = (1.0, 1.0, 1.0)
    up = np.asarray(cam.up)
    assert abs(up @ np.asarray(cam.forward)) < 1e-15 and abs(up @ up - 1.0) < 1e-15


def test_a_spot_cone_widens_outer_first():
    spot = pw.SpotLight(inner_cone=0.1, outer_cone=0.3)
    with pytest.raises(pw.InputError):
        spot.inner_cone = 0.6
    spot.outer_cone = 0.8
    spot.inner_cone = 0.6
    assert (spot.inner_cone, spot.outer_cone) == (0.6, 0.8)


def test_a_refused_assignment_leaves_renders_unchanged():
    """The issue's cases (a NaN eye, fov_y = 180, a NaN light position, roughness 7, a NaN base
    colour) raise; the scene renders as before and pw.check finds it sound."""
    material = pw.Material(base_color=(0.8, 0.8, 0.8), roughness=0.4)
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0, material=material))
    light = scene.add_light(pw.PointLight(position=(0.5, 0.5, 2.0), intensity=5.0))
    cam = head_on_camera()
    first = pw.render(scene, cam, width=16, height=16, progress=False)
    for obj, field, value in ((cam, "eye", (NAN, 0.0, 3.0)), (cam, "fov_y", 180.0), (light, "position", (NAN, 0, 0)),
                              (material, "roughness", 7.0), (material, "base_color", (NAN, 0.5, 0.5))):
        with pytest.raises(pw.InputError):
            setattr(obj, field, value)
    again = pw.render(scene, cam, width=16, height=16, progress=False)
    np.testing.assert_array_equal(again.rgb, first.rgb)
    assert pw.check(again).ok, pw.check(again)


def frame_of(rgb) -> pw.Frame:
    rgb = np.asarray(rgb, dtype=np.float32)
    h, w = rgb.shape[:2]
    return pw.Frame(rgb=rgb, depth=np.ones((h, w), np.float32), normal=np.zeros((h, w, 3), np.float32),
                    alpha=np.ones((h, w), np.float32))


def test_check_flags_absurd_and_clamped_radiance():
    """float32's maximum is where the render kernel clamps an overflow (and a NaN): such a pixel
    is finite but not sound, and neither is one above MAX_PLAUSIBLE_RADIANCE."""
    rgb = np.zeros((2, 3, 3))
    rgb[0, 0] = (np.finfo(np.float32).max, 0.0, 0.0)
    rgb[0, 1, 2] = 10 * MAX_PLAUSIBLE_RADIANCE
    rgb[1, 0] = MAX_PLAUSIBLE_RADIANCE  # at the bound: plausible still
    report = pw.check(frame_of(rgb))
    assert (report.nan, report.inf, report.negative, report.absurd) == (0, 0, 0, 2)
    assert not report.ok and "2 with radiance above 1e+30" in str(report)
    rgb[1, 1] = (NAN, 0.0, math.inf)
    report = pw.check(frame_of(rgb))
    assert (report.nan, report.inf, report.absurd) == (1, 1, 2)


def test_check_passes_extreme_but_sound_radiance():
    """A 1 cd light 1e-9 above a white Lambert surface: 1e18 / pi nits, finite and right."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0, material=lambert_white()))
    scene.add_light(pw.PointLight(position=(0.0, 0.0, 1e-9), intensity=1.0))
    frame = pw.render(scene, head_on_camera(), width=9, height=9, progress=False)
    assert frame.rgb.max() > 1e16
    assert pw.check(frame).ok, pw.check(frame)
