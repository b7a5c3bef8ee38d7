"""Whole images against analytic results: radiometry, falloff, cones, shadows, normal maps."""

import math

import numpy as np
import pytest
import trimesh

import pbrwarp as pw

from scenes import box, head_on_camera, lambert_white, quad, rotation_about_y, render_checked as render


def hit_points(frame, cam):
    """World positions of each pixel's centre hit, from the depth buffer (spp = 1)."""
    h, w = frame.depth.shape
    tan_half = math.tan(math.radians(cam.fov_y) / 2)
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * tan_half * w / h
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * tan_half
    X, Y = np.meshgrid(xs, ys)
    d = (np.asarray(cam.forward) + X[..., None] * np.asarray(cam.right) + Y[..., None] * np.asarray(cam.up))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.asarray(cam.eye) + d * frame.depth[..., None].astype(np.float64)


@pytest.mark.parametrize("lux", [1.0, 3.0, 120000.0])
def test_white_lambert_head_on_has_radiance_e_over_pi(lux):
    scene = pw.Scene()
    scene.add_mesh(quad(size=10.0))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=lux))
    frame = render(scene, head_on_camera())
    assert frame.alpha.min() == 1.0
    np.testing.assert_allclose(frame.rgb, lux / math.pi, rtol=1e-5)


def test_light_colour_scales_each_channel():
    scene = pw.Scene()
    scene.add_mesh(quad(size=10.0, material=pw.Material(base_color=(0.5, 0.25, 1.0), roughness=1.0, specular=0.0)))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), color=(1.0, 0.5, 0.2), intensity=2.0))
    frame = render(scene, head_on_camera(), size=(5, 5))
    np.testing.assert_allclose(frame.rgb[2, 2], np.array([0.5, 0.125, 0.2]) * 2.0 / math.pi, rtol=1e-5)


@pytest.mark.parametrize("distance", [0.5, 1.0, 2.0, 8.0])
def test_point_light_inverse_square(distance):
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0))
    scene.add_light(pw.PointLight(position=(0, 0, distance), intensity=50.0))
    frame = render(scene, head_on_camera(distance=20.0), size=(3, 3))
    # the centre pixel sees the foot of the light, where n.l = 1 and E = I / d^2
    np.testing.assert_allclose(frame.rgb[1, 1], 50.0 / distance**2 / math.pi, rtol=1e-5)


def test_point_light_falloff_over_the_whole_plane():
    scene = pw.Scene()
    scene.add_mesh(quad(size=6.0))
    light = np.array([0.3, -0.2, 1.5])
    scene.add_light(pw.PointLight(position=tuple(light), intensity=10.0))
    cam = head_on_camera(distance=5.0, fov=50.0)
    frame = render(scene, cam, size=(41, 41))
    p = hit_points(frame, cam)
    to_light = light - p
    d2 = np.sum(to_light**2, -1)
    cos = to_light[..., 2] / np.sqrt(d2)
    expected = 10.0 * cos / d2 / math.pi
    mask = frame.alpha == 1.0
    np.testing.assert_allclose(frame.rgb[mask][:, 0], expected[mask], rtol=1e-4)


def test_spot_cone_inner_outer():
    inner, outer = math.radians(15), math.radians(30)
    scene = pw.Scene()
    scene.add_mesh(quad(size=8.0))
    light = np.array([0.0, 0.0, 2.0])
    scene.add_light(pw.SpotLight(position=tuple(light), direction=(0, 0, -1), intensity=20.0,
                                 inner_cone=inner, outer_cone=outer))
    cam = head_on_camera(distance=6.0, fov=60.0)
    frame = render(scene, cam, size=(61, 61))
    p = hit_points(frame, cam)
    to_light = light - p
    d2 = np.sum(to_light**2, -1)
    cos_angle = to_light[..., 2] / np.sqrt(d2)  # angle to the spot axis = angle to the normal here
    # KHR_lights_punctual: smoothstep-free linear ramp in cos, squared
    t = np.clip((cos_angle - math.cos(outer)) / (math.cos(inner) - math.cos(outer)), 0, 1)
    expected = 20.0 * t**2 * cos_angle / d2 / math.pi
    mask = frame.alpha == 1.0
    np.testing.assert_allclose(frame.rgb[mask][:, 0], expected[mask], rtol=1e-4, atol=1e-6)
    inside = cos_angle > math.cos(inner) + 1e-3
    outside = cos_angle < math.cos(outer) - 1e-3
    assert inside.sum() > 10 and outside.sum() > 10
    assert np.all(frame.rgb[outside & mask] == 0.0)
    np.testing.assert_allclose(frame.rgb[inside][:, 0], (20.0 * cos_angle / d2 / math.pi)[inside], rtol=1e-4)


def shadow_scene(shadows_from_box=True):
    scene = pw.Scene()
    scene.add_mesh(quad(size=10.0))
    if shadows_from_box:
        # a thin slab between the light and the left half of the plane
        scene.add_mesh(box((2.0, 2.0, 0.001), (-1.5, 0.0, 1.0)), lambert_white())
    scene.add_light(pw.PointLight(position=(-1.5, 0.0, 2.0), intensity=10.0))
    return scene


def test_shadowed_and_unshadowed_points():
    cam = pw.Camera.look_at(eye=(0, 0, 6), target=(0, 0, 0), fov_y=50.0)
    lit = render(shadow_scene(False), cam, size=(41, 41))
    shadowed = render(shadow_scene(True), cam, size=(41, 41))
    p = hit_points(lit, cam)
    # a point right under the slab, seen past it: shadowed (black), lit without the slab
    under = np.linalg.norm(p[..., :2] - np.array([-0.3, 0.0]), axis=-1) < 0.15
    visible_under = under & (np.abs(shadowed.depth - lit.depth) < 1e-4)
    assert visible_under.sum() >= 1
    assert np.all(shadowed.rgb[visible_under] == 0.0)
    assert np.all(lit.rgb[visible_under] > 0.0)
    # far right is unshadowed in both and equals the analytic value
    far = (p[..., 0] > 2.0)
    d = np.array([-1.5, 0.0, 2.0]) - p
    d2 = np.sum(d**2, -1)
    expected = 10.0 * (d[..., 2] / np.sqrt(d2)) / d2 / math.pi
    np.testing.assert_allclose(shadowed.rgb[far][:, 0], expected[far], rtol=1e-4)


def test_shadows_false_removes_shadows():
    cam = pw.Camera.look_at(eye=(0, 0, 6), target=(0, 0, 0), fov_y=50.0)
    a = render(shadow_scene(True), cam, size=(41, 41), shadows=False)
    b = render(shadow_scene(False), cam, size=(41, 41))
    same = np.abs(a.depth - b.depth) < 1e-5
    np.testing.assert_allclose(a.rgb[same], b.rgb[same], rtol=1e-6)


def tangents_plus_x(n=4):
    return np.tile([1.0, 0.0, 0.0, 1.0], (n, 1))


@pytest.mark.parametrize("metallic,roughness", [(0.0, 1.0), (0.0, 0.4), (1.0, 0.3)])
def test_flat_normal_map_changes_nothing(metallic, roughness):
    flat = np.zeros((4, 4, 3), np.float32)
    flat[...] = (0.5, 0.5, 1.0)
    plain = pw.Material(base_color=(0.7, 0.5, 0.3), metallic=metallic, roughness=roughness)
    mapped = pw.Material(base_color=(0.7, 0.5, 0.3), metallic=metallic, roughness=roughness, normal_texture=flat)
    cam = pw.Camera.look_at(eye=(0.5, 1, 4), target=(0, 0, 0), fov_y=40.0)
    frames = []
    for mat, tangents in ((plain, None), (mapped, tangents_plus_x()), (mapped, None)):
        scene = pw.Scene()
        scene.add_mesh(quad(size=3.0, material=mat, tangents=tangents))
        scene.add_light(pw.PointLight(position=(1, 1, 2), intensity=5.0))
        frames.append(render(scene, cam, size=(31, 31)))
    np.testing.assert_allclose(frames[1].rgb, frames[0].rgb, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(frames[2].rgb, frames[0].rgb, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("angle_deg", [10.0, 25.0, -30.0])
def test_tilted_normal_map_shades_like_tilted_geometry(angle_deg):
    theta = math.radians(angle_deg)
    # tangent-space normal tilted towards +T (= +x) by theta
    n_ts = np.array([math.sin(theta), 0.0, math.cos(theta)])
    texture = np.empty((2, 2, 3), np.float32)
    texture[...] = (n_ts + 1.0) / 2.0
    mat_args = dict(base_color=(0.8, 0.6, 0.4), metallic=0.3, roughness=0.45)
    cam = head_on_camera(distance=4.0)
    light = pw.DirectionalLight(direction=(-0.3, 0.2, -1.0), intensity=3.0)

    mapped = pw.Scene()
    mapped.add_mesh(quad(size=2.0, material=pw.Material(normal_texture=texture, **mat_args), tangents=tangents_plus_x()))
    mapped.add_light(light)
    tilted = pw.Scene()
    # rotating +z towards +x by theta is a rotation about +y by theta
    tilted.add_mesh(quad(size=2.0, material=pw.Material(**mat_args)), transform=rotation_about_y(theta))
    tilted.add_light(light)
    a = render(mapped, cam, size=(3, 3))
    b = render(tilted, cam, size=(3, 3))
    np.testing.assert_allclose(a.normal[1, 1], b.normal[1, 1], atol=1e-6)
    np.testing.assert_allclose(a.rgb[1, 1], b.rgb[1, 1], rtol=1e-5)


def test_mirrored_tangent_handedness_flips_bitangent():
    """w = -1 flips the bitangent: a map tilted towards +B then tilts the normal towards -B."""
    n_ts = np.array([0.0, math.sin(0.3), math.cos(0.3)])
    texture = np.empty((2, 2, 3), np.float32)
    texture[...] = (n_ts + 1.0) / 2.0
    normals = []
    for w in (1.0, -1.0):
        scene = pw.Scene()
        tangents = np.tile([1.0, 0.0, 0.0, w], (4, 1))
        scene.add_mesh(quad(material=pw.Material(normal_texture=texture), tangents=tangents))
        normals.append(render(scene, head_on_camera(), size=(3, 3)).normal[1, 1])
    # B = cross(N, T) w = +y for w = 1
    np.testing.assert_allclose(normals[0], [0.0, math.sin(0.3), math.cos(0.3)], atol=1e-6)
    np.testing.assert_allclose(normals[1], [0.0, -math.sin(0.3), math.cos(0.3)], atol=1e-6)


def test_emission_adds_radiance_without_lights():
    scene = pw.Scene()
    scene.add_mesh(quad(material=pw.Material(base_color=(0, 0, 0), emissive=(0.25, 0.5, 2.0))))
    frame = render(scene, head_on_camera(), size=(3, 3))
    np.testing.assert_allclose(frame.rgb[1, 1], [0.25, 0.5, 2.0], rtol=1e-6)


def test_background_alpha_and_depth():
    scene = pw.Scene()
    scene.add_mesh(quad(size=1.0))
    frame = render(scene, head_on_camera(distance=3.0), size=(21, 21), background=(0.1, 0.2, 0.3))
    assert frame.alpha[0, 0] == 0.0 and np.isinf(frame.depth[0, 0])
    np.testing.assert_allclose(frame.rgb[0, 0], [0.1, 0.2, 0.3], rtol=1e-6)
    assert frame.alpha[10, 10] == 1.0
    np.testing.assert_allclose(frame.depth[10, 10], 3.0, rtol=1e-6)
    np.testing.assert_allclose(frame.normal[10, 10], [0, 0, 1], atol=1e-6)


def test_supersampled_coverage_is_area_fraction():
    """A quad edge through the middle of a column of pixels covers half of each of them."""
    scene = pw.Scene()
    positions = np.array([[0.0, -5, 0], [5, -5, 0], [5, 5, 0], [0.0, 5, 0]])
    scene.add_mesh(pw.Primitive(positions, np.array([[0, 1, 2], [0, 2, 3]]), lambert_white()))
    cam = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=30.0)
    frame = render(scene, cam, size=(21, 21), spp=64)
    # x = 0 passes through the centre of column 10: each of its pixels is half covered
    np.testing.assert_allclose(frame.alpha[:, 10], 0.5, atol=1.0 / 64 + 1e-6)
    assert np.all(frame.alpha[:, 11:] == 1.0) and np.all(frame.alpha[:, :10] == 0.0)


def test_threads_one_and_many_give_identical_images():
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), pw.Material(base_color=(0.9, 0.2, 0.1), roughness=0.3))
    scene.add_mesh(box((6, 0.2, 6), (0, -1.2, 0)), pw.Material(metallic=1.0, roughness=0.2))
    scene.add_light(pw.PointLight(position=(2, 3, 2), intensity=30.0))
    scene.add_light(pw.SpotLight(position=(-2, 3, 1), direction=(1, -1.5, -0.5), intensity=40.0, outer_cone=0.6))
    cam = pw.Camera.look_at(eye=(0, 1.5, 4.5), target=(0, -0.3, 0))
    one = render(scene, cam, size=(150, 130), spp=4, threads=1)
    many = render(scene, cam, size=(150, 130), spp=4, threads=4)
    for name in ("rgb", "depth", "normal", "alpha"):
        assert np.array_equal(getattr(one, name), getattr(many, name)), name


@pytest.mark.parametrize("threads", [1, 3])
def test_progress_bar_follows_every_row(threads, monkeypatch):
    """The threads take rows from one counter; the progress bar reads it while they render and
    ends at the image height (and is closed), whatever the thread count."""
    import sys

    bars = []

    class Bar:
        def __init__(self, total):
            self.total, self.n, self.closed = total, 0, False
            bars.append(self)

        def update(self, k):
            assert k >= 0
            self.n += k

        def close(self):
            self.closed = True

    render_module = sys.modules["pbrwarp.render"]
    monkeypatch.setattr(render_module, "progress_bar", lambda enabled, total, **options: Bar(total))
    monkeypatch.setattr(render_module, "PROGRESS_INTERVAL", 0.001)
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), pw.Material())
    scene.add_light(pw.PointLight(position=(2, 3, 2), intensity=30.0))
    frame = pw.render(scene, width=64, height=203, spp=16, threads=threads, progress=True)
    assert frame.rgb.shape == (203, 64, 3)
    (bar,) = bars
    assert bar.total == 203 and bar.closed
    assert bar.n == 203


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_no_shadow_acne_on_lit_curved_and_flat_surfaces(scale):
    """Every pixel whose geometric normal faces the light must be unshadowed (sphere on a floor
    lit from above: nothing occludes the lit side of either)."""
    scene = pw.Scene()
    sphere = trimesh.creation.icosphere(subdivisions=3)
    sphere.apply_scale(scale)
    floor = box((8 * scale, 0.2 * scale, 8 * scale), (0, -1.5 * scale, 0))
    scene.add_mesh(sphere)
    scene.add_mesh(floor)
    scene.add_light(pw.DirectionalLight(direction=(0.0, -1.0, 0.0), intensity=1.0))
    cam = pw.Camera.look_at(eye=(0, 2.5 * scale, 3.5 * scale), target=(0, -0.5 * scale, 0))
    with_shadows = render(scene, cam, size=(96, 96))
    without = render(scene, cam, size=(96, 96), shadows=False)
    lit_side = (with_shadows.normal[..., 1] > 0.05)
    # the floor under the sphere is legitimately shadowed
    p = hit_points(with_shadows, cam) / scale
    under_sphere = (np.hypot(p[..., 0], p[..., 2]) < 1.05) & (p[..., 1] < -1.0)
    check = lit_side & ~under_sphere & (with_shadows.alpha > 0)
    assert check.sum() > 1000
    assert np.array_equal(with_shadows.rgb[check], without.rgb[check])


def test_no_light_leaks_through_a_thin_wall():
    scene = pw.Scene()
    scene.add_mesh(quad(size=10.0))
    # a closed wall 1e-4 thick right above the plane, light above the wall
    scene.add_mesh(box((10.0, 10.0, 1e-4), (0.0, 0.0, 0.01)), lambert_white())
    scene.add_light(pw.PointLight(position=(0, 0, 1), intensity=10.0))
    scene.add_light(pw.DirectionalLight(direction=(0.2, 0.1, -1), intensity=10.0))
    # the camera sits in the 1 cm gap between plane and wall, looking down: every plane point it
    # sees is under the wall, so any light on it would have leaked through the wall
    cam = pw.Camera.look_at(eye=(0, 0, 0.005), target=(0, 0, 0), up=(0, 1, 0), fov_y=120.0)
    frame = render(scene, cam, size=(33, 33))
    assert frame.alpha.min() == 1.0
    assert np.all(frame.rgb == 0.0)


def test_material_slots_land_on_their_meshes_through_gltf(tmp_path):
    """Two meshes with their own glTF materials: each material's emission appears exactly on
    its own mesh after a round trip through a .glb file."""
    from trimesh.visual.material import PBRMaterial
    from trimesh.visual.texture import TextureVisuals

    glb = trimesh.Scene()
    for x, emission in ((-1.0, (1.0, 0.0, 0.0)), (1.0, (0.0, 0.0, 1.0))):
        cube = box((1.0, 1.0, 1.0), (x, 0.0, 0.0))
        cube.visual = TextureVisuals(material=PBRMaterial(baseColorFactor=(0, 0, 0, 255), emissiveFactor=emission,
                                                          metallicFactor=0.0, roughnessFactor=1.0))
        glb.add_geometry(cube)
    path = tmp_path / "two_cubes.glb"
    glb.export(path)
    scene = pw.Scene.load(path)
    frame = render(scene, head_on_camera(distance=6.0), size=(41, 21))
    left, right = frame.rgb[10, 13], frame.rgb[10, 27]
    np.testing.assert_allclose(left, [1.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(right, [0.0, 0.0, 1.0], atol=1e-6)
