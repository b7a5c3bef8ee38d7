"""The path tracer (render(..., integrator="path")) against analytic results: the furnace through
all bounces, the direct integrator where both compute the same thing, reproducibility and
continuation, unbiasedness, stable output in hard cases, and its options."""

import math
import warnings

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp import cli
from pbrwarp.meshes import CORNELL_LIGHT, cornell_box

from scenes import head_on_camera, quad


def render(scene, camera, size=16, **options):
    options.setdefault("progress", False)
    return pw.render(scene, camera, width=size, height=size, integrator="path", **options)


def furnace(albedo: float, emission: float, subdivisions: int = 2) -> pw.Scene:
    """A closed sphere, flat-shaded (no shading normals, so the Lambert BRDF conserves energy
    exactly), of Lambert albedo ``albedo`` and uniform emission ``emission``, seen from inside."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    material = pw.Material(base_color=(albedo,) * 3, metallic=0.0, specular=0.0, emissive=(emission,) * 3)
    scene = pw.Scene()
    scene.add_mesh(pw.Primitive(np.asarray(sphere.vertices), np.asarray(sphere.faces), material))
    return scene


@pytest.mark.parametrize("albedo", [0.5, 0.8])
def test_furnace_radiance_is_emission_over_one_minus_albedo(albedo):
    """Inside a closed surface of Lambert albedo rho emitting Le everywhere, radiance is the same
    everywhere and in every direction, L = Le + rho L, so L = Le / (1 - rho). Paths of at most B
    bounces sum the series to Le (1 - rho^(B+1)) / (1 - rho): B = 60 leaves rho^61 < 1.2e-6 of it
    out. The estimate's standard error, from the pixels (independent paths), is checked to be
    below a third of the 1% bound, so that the test tells a 1% error from noise (Russian
    roulette's noise dominates: 64 x 64 pixels of 32 paths)."""
    emission = 0.25
    camera = pw.Camera.look_at(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fov_y=60.0)
    frame = render(furnace(albedo, emission), camera, size=64, spp=32, max_bounces=60, seed=1)
    expected = emission / (1.0 - albedo)
    values = frame.rgb[..., 0].astype(np.float64).ravel()
    mean, error = values.mean(), values.std(ddof=1) / math.sqrt(values.size)
    assert 3 * error < 0.01 * expected, (error, expected)
    assert abs(mean / expected - 1.0) < 0.01, (mean, expected, error)
    np.testing.assert_array_equal(frame.rgb[..., 0], frame.rgb[..., 2])  # grey in, grey out
    assert np.all(frame.alpha == 1.0)


def lit_plane(material=None):
    """A large plane filling the view, lit by a point light: a smooth image."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0, material=material))
    scene.add_light(pw.PointLight(position=(1.0, 2.0, 3.0), intensity=40.0))
    return scene


@pytest.mark.parametrize("material", [pw.Material(base_color=(0.7, 0.5, 0.3), roughness=0.4),
                                      pw.Material(base_color=(0.9, 0.6, 0.2), metallic=1.0, roughness=0.3)])
def test_one_bounce_equals_direct_lighting_under_a_point_light(material):
    """With one bounce the path tracer is direct lighting: a delta light is sampled by next-event
    estimation alone, with the same BRDF, so only the sample positions in each pixel differ
    (stratified against uniform: the highlight's pixels differ by a few percent at 64 samples)."""
    scene = lit_plane(material)
    camera = pw.Camera.look_at(eye=(0.0, -2.0, 4.0), target=(0.0, 0.5, 0.0), fov_y=40.0)
    direct = pw.render(scene, camera, width=24, height=24, spp=64, progress=False)
    path = render(scene, camera, size=24, spp=64, max_bounces=1)
    np.testing.assert_allclose(path.rgb, direct.rgb, rtol=0.05, atol=0.01 * direct.rgb.max())
    np.testing.assert_allclose(path.rgb.mean((0, 1)), direct.rgb.mean((0, 1)), rtol=0.002)


def test_one_bounce_equals_direct_lighting_under_a_uniform_environment():
    """A Lambert sphere under a uniform environment of radiance L: the direct integrator's
    irradiance (pi L, exact for a uniform environment) gives rho L; the path tracer's estimate,
    next-event estimation of the environment weighted against cosine-sampled directions that all
    escape (a convex object), averages to it within 5 standard errors."""
    scene = pw.Scene()
    sphere = trimesh.creation.icosphere(subdivisions=3)
    # flat-shaded: every cosine-weighted direction about the normal leaves the surface
    scene.add_mesh(pw.Primitive(np.asarray(sphere.vertices), np.asarray(sphere.faces),
                                pw.Material(base_color=(0.6, 0.4, 0.2), specular=0.0)))
    scene.environment = pw.Environment.uniform((0.5, 1.0, 2.0))
    camera = head_on_camera(distance=4.0)
    direct = pw.render(scene, camera, width=16, height=16, spp=4, progress=False)
    path = render(scene, camera, spp=16, max_bounces=1)
    covered = (direct.alpha == 1.0) & (path.alpha == 1.0)
    assert covered.sum() > 50
    expected = np.array([0.3, 0.4, 0.4])
    np.testing.assert_allclose(direct.rgb[covered], np.broadcast_to(expected, direct.rgb[covered].shape), rtol=1e-3)
    values = path.rgb[covered].astype(np.float64)
    error = values.std(axis=0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(axis=0) - expected) < 5 * error + 1e-6), (values.mean(axis=0), error)
    # misses show the environment, as the direct integrator's do
    np.testing.assert_allclose(path.rgb[path.alpha == 0.0], np.broadcast_to([0.5, 1.0, 2.0],
                                                                           path.rgb[path.alpha == 0.0].shape))


@pytest.fixture(scope="module")
def box():
    return cornell_box()


def test_images_do_not_depend_on_threads_and_follow_the_seed(box):
    scene, camera = box
    options = dict(size=12, spp=2, max_bounces=4)
    one = render(scene, camera, threads=1, seed=7, **options)
    two = render(scene, camera, threads=2, seed=7, **options)
    np.testing.assert_array_equal(one.rgb, two.rgb)
    np.testing.assert_array_equal(one.normal, two.normal)
    np.testing.assert_array_equal(render(scene, camera, seed=7, **options).rgb, one.rgb)
    other = render(scene, camera, seed=8, **options)
    assert np.mean(other.rgb != one.rgb) > 0.5


def test_a_render_continues_with_first_sample(box):
    scene, camera = box
    whole = render(scene, camera, size=8, spp=6, max_bounces=3, seed=3)
    first = render(scene, camera, size=8, spp=2, max_bounces=3, seed=3)
    rest = render(scene, camera, size=8, spp=4, max_bounces=3, seed=3, first_sample=2)
    np.testing.assert_allclose((2 * first.rgb + 4 * rest.rgb) / 6, whole.rgb, rtol=1e-5, atol=1e-6)


def test_low_sample_images_average_to_the_high_sample_image(box):
    """Unbiasedness: the mean of K independent 4-spp images (seeds 1..K) against a 128-spp image
    (another seed), per 4 x 4 block of pixels, within 5 standard errors of their difference
    (the K images' spread gives both errors: the high-spp image's variance is 4/128 of one
    low-spp image's)."""
    scene, camera = box
    k, low, high = 16, 4, 128
    images = np.stack([render(scene, camera, size=12, spp=low, max_bounces=5, seed=s).rgb for s in range(1, k + 1)])
    reference = render(scene, camera, size=12, spp=high, max_bounces=5, seed=100).rgb.astype(np.float64)

    def blocks(x):
        return x.reshape(*x.shape[:-3], 3, 4, 3, 4, 3).mean((-4, -2))

    per_image = blocks(images.astype(np.float64))  # (k, 3, 3, rgb)
    mean = per_image.mean(0)
    variance = per_image.var(0, ddof=1)
    error = np.sqrt(variance / k + variance * low / high)
    z = (mean - blocks(reference)) / np.maximum(error, 1e-12)
    assert np.all(np.abs(z) < 5.0), z


def test_the_cornell_box_is_lit_by_its_emitter_alone(box):
    scene, camera = box
    assert not scene.lights
    frame = render(scene, camera, size=32, spp=32, max_bounces=3)
    assert pw.check(frame).ok
    # the red wall on the left, the green one on the right
    left, right = frame.rgb[8:24, 1:4].mean((0, 1)), frame.rgb[8:24, 28:31].mean((0, 1))
    assert left[0] > 3 * left[1] and right[1] > 1.5 * right[0]
    # the direct integrator shows the light's emission and nothing it lights
    direct = pw.render(scene, camera, width=32, height=32, progress=False)
    dark = direct.rgb.max(-1) == 0.0
    assert dark.mean() > 0.9 and np.mean(frame.rgb[dark & (frame.alpha == 1.0)].max(-1) > 0.0) > 0.98
    # looking up at the light: its emission (seen directly, at full weight) plus the little it reflects
    up = pw.Camera.look_at(eye=(0.278, 0.1, 0.27), target=(0.278, 0.5488, 0.27), up=(0.0, 0.0, 1.0), fov_y=5.0)
    light = render(scene, up, size=8, spp=4, max_bounces=3).rgb
    assert np.all(light >= np.array(CORNELL_LIGHT, np.float32)) and np.all(light < 1.5 * np.array(CORNELL_LIGHT))


def hostile_scene():
    """Roughness 0 metal and dielectric, shading normals facing away from the geometry, an
    emitter, a point light almost on a surface, a glass pane, and an environment."""
    scene = pw.Scene()
    mirror = pw.Material(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
    glossy = pw.Material(base_color=(0.5, 0.5, 0.5), roughness=0.0)
    floor = quad(size=6.0, material=glossy)
    flipped = pw.Primitive(floor.positions + [0.0, 0.0, 0.5], floor.faces, mirror, -floor.normals)
    scene.add_mesh(floor)
    scene.add_mesh(flipped)
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    scene.add_mesh(sphere, pw.Material(emissive=(5.0, 5.0, 5.0), roughness=0.0), transform=np.array(
        [[1, 0, 0, 0.5], [0, 1, 0, 0.0], [0, 0, 1, 1.2], [0, 0, 0, 1.0]]))
    scene.add_light(pw.PointLight(position=(0.0, 0.0, 1e-6), intensity=100.0))
    pane = quad(size=1.0, material=pw.Material(base_color=(0.9, 0.5, 0.2), roughness=0.0, transmission=1.0))
    scene.add_mesh(pw.Primitive(pane.positions + [0.2, 0.0, 0.9], pane.faces, pane.material))
    scene.environment = pw.Environment.uniform((0.2, 0.2, 0.2))
    return scene


@pytest.mark.parametrize("eye", [(0.0, -3.0, 3.0), (0.0, -6.0, 0.51), (0.0, 0.0, 3.0)])
def test_no_nan_or_inf_at_roughness_zero_grazing_angles_and_back_facing_normals(eye):
    camera = pw.Camera.look_at(eye=eye, target=(0.0, 0.0, 0.5), fov_y=50.0)
    frame = render(hostile_scene(), camera, size=16, spp=4, max_bounces=6)
    report = pw.check(frame)
    assert report.ok, report
    assert np.all(np.isfinite(frame.rgb))


def test_options_are_checked():
    scene, camera = lit_plane(), head_on_camera()
    for bad, error in ((dict(integrator="bidirectional"), pw.InputError), (dict(integrator=1), pw.InputTypeError),
                       (dict(integrator="path", max_bounces=-1), pw.InputError),
                       (dict(integrator="path", max_bounces=2000), pw.InputError),
                       (dict(integrator="path", max_bounces=2.5), pw.InputTypeError),
                       (dict(integrator="path", max_bounces=True), pw.InputTypeError),
                       (dict(max_bounces=3), pw.InputError), (dict(first_sample=4), pw.InputError),
                       (dict(integrator="path", first_sample=-1), pw.InputError),
                       (dict(integrator="path", shadows="map"), pw.InputError),
                       (dict(integrator="path", shadows=False), pw.InputError)):
        with pytest.raises(error):
            pw.render(scene, camera, width=4, height=4, progress=False, **bad)
        with pytest.raises(error):
            pw.explain(scene, **bad)


def test_explain_describes_either_integrator(box):
    scene, _ = box
    direct = pw.explain(scene)
    assert "direct lighting (integrator='direct')" in direct
    path = pw.explain(scene, integrator="path", max_bounces=3)
    assert "path tracing (integrator='path'): light bouncing up to 3 times" in path
    assert "emissive material" in path
    assert "primary visibility ray cast" in path
    glass = lit_plane(GLASS)
    assert "pass straight through smooth thin transmissive walls" in pw.explain(glass, integrator="path")


def test_clear_coat_and_sheen_are_simulated_without_a_warning(recwarn):
    scene = lit_plane(pw.Material(clearcoat=1.0, sheen_color=(0.5, 0.5, 0.5)))
    frame = render(scene, head_on_camera(), size=4, spp=1)
    assert pw.check(frame).ok
    assert not [w for w in recwarn if "does not simulate" in str(w.message)]
    text = pw.explain(scene, integrator="path")
    assert "clear coat (KHR_materials_clearcoat): 1 material" in text and "sheen (KHR_materials_sheen): 1" in text
    assert "simulated by the path tracer yet" not in text


GLASS = pw.Material(base_color=(1.0, 1.0, 1.0), roughness=0.0, transmission=1.0)


def test_a_thin_glass_wall_passes_one_minus_its_fresnel_reflectance():
    """A smooth thin wall of transmission 1 seen head-on in front of an emitter of radiance Le:
    glTF's transmitted share is (1 - F(1)) Le = 0.96 Le (f0 = 0.04), the reflected rest sees
    nothing. Paths pass the wall with probability 0.95, so the pixels are noisy: their mean within
    4 standard errors."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=8.0, z=-1.0, material=pw.Material(base_color=(0.0, 0.0, 0.0), specular=0.0,
                                                               emissive=(2.0, 1.0, 0.5))))
    scene.add_mesh(quad(size=8.0, z=0.0, material=GLASS))
    frame = render(scene, head_on_camera(distance=2.0, fov=20.0), size=16, spp=16, max_bounces=2)
    values = frame.rgb.reshape(-1, 3).astype(np.float64)
    expected = 0.96 * np.array([2.0, 1.0, 0.5])
    error = values.std(0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(0) - expected) < 4 * error + 1e-3 * expected), (values.mean(0), expected)


def test_shadow_rays_pass_thin_glass_walls_as_the_direct_integrators_do():
    """A Lambert floor lit by a directional light through a thin glass pane: with one bounce, the
    path tracer's shadow rays pass the share the direct integrator's tinted shadow rays pass."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=20.0, z=0.0))
    scene.add_mesh(quad(size=20.0, z=2.0, material=GLASS))
    scene.add_light(pw.DirectionalLight(direction=(0.3, 0.2, -1.0), intensity=3.0))
    camera = pw.Camera.look_at(eye=(0.0, -1.0, 1.0), target=(0.0, 1.0, 0.0), fov_y=50.0)
    direct = pw.render(scene, camera, width=16, height=16, spp=4, progress=False)
    path = render(scene, camera, spp=4, max_bounces=1)
    covered = (direct.alpha == 1.0) & (path.alpha == 1.0)  # (the floor's far edge: sample positions differ)
    assert covered.sum() > 150
    np.testing.assert_allclose(path.rgb[covered], direct.rgb[covered], rtol=2e-3, atol=1e-6)
    bare = pw.Scene()
    bare.primitives.append(scene.primitives[0])
    bare.lights = scene.lights
    ratio = path.rgb[covered] / render(bare, camera, spp=4, max_bounces=1).rgb[covered]
    assert np.all((ratio > 0.9) & (ratio < 0.97))  # 1 - F at the pane, 0.96 head-on


def test_command_line_path_integrator(tmp_path):
    mesh = tmp_path / "box.obj"
    trimesh.creation.box().export(mesh)
    out = tmp_path / "out.npy"
    assert cli.main(["render", str(mesh), "-o", str(out), "--size", "8x6", "--integrator", "path",
                     "--bounces", "2", "--spp", "2"]) == 0
    assert np.load(out).shape == (6, 8, 4)
    assert cli.main(["render", str(mesh), "-o", str(out), "--bounces", "2"]) == cli.EXIT_USAGE
    assert cli.main(["render", str(mesh), "-o", str(out), "--integrator", "path", "--bounces", "-1"]) == cli.EXIT_USAGE


def test_area_lights_are_simulated_by_the_path_tracer():
    """Sphere and rectangle lights light the path tracer's scenes: no warning names them, and
    explain counts them among the lights next-event estimation chooses from."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0))
    scene.add_light(pw.SphereLight(position=(0.0, 0.0, 1.0), radius=0.2, intensity=10.0))
    scene.add_light(pw.RectLight(position=(0.0, 0.0, 2.0), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, -1.0, 0.0),
                                 intensity=10.0))
    cam = pw.Camera.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov_y=40.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frame = pw.render(scene, cam, 16, 16, spp=4, integrator="path", progress=False)
    assert frame.rgb.min() > 0.0 and np.all(np.isfinite(frame.rgb))
    text = pw.explain(scene, integrator="path")
    assert "not simulated by the path tracer" not in text and "2 area lights" in text
