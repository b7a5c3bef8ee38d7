"""The path tracer's sphere, rectangle and environment lights: one bounce against the direct
integrator's Monte Carlo rungs, a white Lambert plane under a uniform environment, the light choice
with the environment beside the table (chi-square), the power heuristic's weights of each light
kind, and the ray-light intersections against float64 NumPy references."""

import math

import numpy as np
import pytest
import warp as wp

import pbrwarp as pw
from pbrwarp.emitters import environment_probability, light_table
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.area_lights import AREA_RECT, AREA_SPHERE, AreaLightData, pdf_rect_light, pdf_sphere_light
from pbrwarp.kernels.area_lights import ray_rect, ray_sphere, sample_rect_light, sample_sphere_light
from pbrwarp.kernels.bsdf_sampling import power_heuristic
from pbrwarp.kernels.emitters import LightTable, choose_light_or_environment
from pbrwarp.kernels.random import sample_key, uniform

from goodness_of_fit import chi_square_ok
from scenes import box, quad
from test_path_sampling import table_of

DOWN = pw.Camera.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=50.0)


def floor_with_blocker() -> pw.Scene:
    """A white Lambert floor (z = 0, facing +z) with a box on it that casts shadows."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=6.0))
    scene.add_mesh(box((0.6, 0.6, 0.6), (0.4, 0.2, 0.3)), pw.Material(base_color=(0.8, 0.8, 0.8), specular=0.0))
    return scene


def blocks(x):
    """Means of 4 x 4 pixel blocks of (..., 16, 16, 3) images."""
    return x.reshape(*x.shape[:-3], 4, 4, 4, 4, 3).mean((-4, -2))


def assert_path_matches_direct(scene, direct_options, seeds=8, spp=8):
    """max_bounces=1 path renders (seeds independent images) against a well-sampled direct render,
    per 4 x 4 block, within 5 standard errors of the path images' mean (plus 1% for the direct
    render's own noise)."""
    direct = pw.render(scene, DOWN, width=16, height=16, progress=False, **direct_options).rgb.astype(np.float64)
    images = np.stack([pw.render(scene, DOWN, width=16, height=16, spp=spp, integrator="path", max_bounces=1,
                                 seed=s, progress=False).rgb for s in range(seeds)]).astype(np.float64)
    per_image = blocks(images)
    mean = per_image.mean(0)
    error = np.sqrt(per_image.var(0, ddof=1) / seeds) + 0.01 * blocks(direct)
    z = (mean - blocks(direct)) / np.maximum(error, 1e-12)
    assert np.all(np.abs(z) < 5.0), z
    assert blocks(direct).max() > 0.0


def test_one_bounce_equals_direct_monte_carlo_under_a_sphere_light():
    scene = floor_with_blocker()
    scene.add_light(pw.SphereLight(position=(-0.5, 0.6, 1.5), radius=0.4, intensity=8.0))
    assert_path_matches_direct(scene, dict(spp=4, area_lighting=pw.AreaLighting("monte_carlo", 64)))


def test_one_bounce_equals_direct_monte_carlo_under_a_rect_light():
    scene = floor_with_blocker()
    scene.add_light(pw.RectLight(position=(-0.3, 0.5, 1.5), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, -0.8, 0.0),
                                 intensity=8.0))
    assert_path_matches_direct(scene, dict(spp=4, area_lighting=pw.AreaLighting("monte_carlo", 64)))


def test_one_bounce_equals_direct_monte_carlo_under_an_environment():
    """A sky environment (bright zenith, dark ground) importance-sampled by next-event estimation."""
    scene = floor_with_blocker()
    scene.environment = pw.Environment.sky(zenith=(0.4, 0.6, 1.5), horizon=(1.0, 1.0, 1.0), ground=(0.1, 0.1, 0.1))
    assert_path_matches_direct(scene, dict(spp=4, ibl=pw.IBL(method="monte_carlo", samples=256, shadowed=True)))


def test_a_white_lambert_plane_under_a_uniform_environment_has_its_radiance():
    """A white Lambert plane under a uniform environment of radiance L (no other light) receives
    irradiance pi L from its hemisphere and reflects L: with one bounce, next-event estimation of
    the environment and BSDF sampling together give L within 1% (the estimate's standard error
    checked to be well below that)."""
    radiance = 0.7
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0))
    scene.environment = pw.Environment.uniform((radiance,) * 3)
    frame = pw.render(scene, DOWN, width=24, height=24, spp=16, integrator="path", max_bounces=1, seed=2,
                      progress=False)
    assert np.all(frame.alpha == 1.0)
    values = frame.rgb[..., 1].astype(np.float64).ravel()
    error = values.std(ddof=1) / math.sqrt(values.size)
    assert 3 * error < 0.01 * radiance, error
    assert abs(values.mean() / radiance - 1.0) < 0.01, (values.mean(), error)


def test_the_environment_is_chosen_by_its_share_of_power_and_only_where_it_lights():
    assert environment_probability(5.0, 0.0) == 1.0
    assert environment_probability(0.0, 3.0) == 0.0
    assert environment_probability(1.0, 3.0) == pytest.approx(0.25)
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0))  # bounding radius sqrt(2)
    scene.add_light(pw.SphereLight(position=(0.0, 0.0, 1.0), radius=0.1, intensity=2.0))
    scene.environment = pw.Environment.uniform((0.5, 0.5, 0.5))
    gpu = upload(scene)
    # the sphere light: pi Y(L) area; the environment: 4 pi^2 r^2 Y(L)
    sphere, env = math.pi * 2.0 * 4.0 * math.pi * 0.01, 4.0 * math.pi ** 2 * 2.0 * 0.5
    assert light_table(scene, gpu, environment_lights=True).environment == pytest.approx(env / (env + sphere), 1e-5)
    assert light_table(scene, gpu, environment_lights=False).environment == 0.0  # a background only
    # the texels' mean is kept, but a new intensity or another environment counts at once
    scene.environment.intensity = 3.0
    assert light_table(scene, gpu, environment_lights=True).environment == pytest.approx(
        3 * env / (3 * env + sphere), 1e-5)
    scene.environment = pw.Environment.uniform((0.25, 0.25, 0.25))
    assert light_table(scene, gpu, environment_lights=True).environment == pytest.approx(
        env / (env + 2 * sphere), 1e-5)


def test_punctual_lights_are_not_in_the_table_so_the_environment_lights_beside_them_alone():
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0))
    scene.add_light(pw.PointLight(position=(0.0, 0.0, 1.0), intensity=2.0))
    scene.add_light(pw.DirectionalLight(direction=(0.0, 0.0, -1.0), intensity=2.0))
    scene.environment = pw.Environment.uniform((0.5, 0.5, 0.5))
    table = light_table(scene, upload(scene), environment_lights=True)
    assert (table.count, table.environment) == (0, 1.0)


def test_every_punctual_light_is_sampled_at_every_vertex():
    """A floor under a sun and a lamp whose power estimates differ tenfold: a light chosen by power
    at each vertex would make the sun's share noise (drawn 1 time in 10 at 10 times its weight).
    Visited each, the lights leave only the spread over the pixel's footprint (about 1% at one
    sample; a light chosen by power gives over 30%): independent one-bounce images at 4 spp
    agree within 3% per pixel, and their mean equals the direct render."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0), pw.Material(base_color=(0.8, 0.8, 0.8), roughness=0.5))
    scene.add_light(pw.DirectionalLight(direction=(0.3, 0.0, -1.0), intensity=3.0))
    scene.add_light(pw.PointLight(position=(0.5, 0.5, 3.0), intensity=20.0))
    images = np.stack([pw.render(scene, DOWN, width=16, height=16, spp=4, integrator="path", max_bounces=1,
                                 seed=s, progress=False).rgb for s in range(4)]).astype(np.float64)
    covered = images.min(axis=0) > 0.0
    assert covered.mean() > 0.5
    spread = images.std(axis=0, ddof=1)[covered] / images.mean(axis=0)[covered]
    assert spread.max() < 0.03, spread.max()
    direct = pw.render(scene, DOWN, width=16, height=16, spp=16, progress=False).rgb.astype(np.float64)
    np.testing.assert_allclose(images.mean(axis=0)[covered], direct[covered], rtol=0.02)


# ---------------------------------------------------------------------------- light choice
@wp.kernel(enable_backward=False)
def choose(table: LightTable, seed: int, out: wp.array(dtype=int), probability: wp.array(dtype=float)):
    i = wp.tid()
    entry, p = choose_light_or_environment(table, uniform(sample_key(seed, i, 0), 0))
    out[i] = entry
    probability[i] = p


def test_light_choice_with_the_environment_follows_its_probabilities():
    environment = 0.3
    table, pmf = table_of([2.0, 0.0, 5.0, 1.0, 0.5])  # area lights and triangles alike
    table.area, table.environment = 3, environment
    count = 200_000
    out = wp.zeros(count, dtype=int, device="cpu")
    probability = wp.zeros(count, dtype=float, device="cpu")
    wp.launch(choose, dim=count, device="cpu", inputs=[table, 5, out, probability])
    chosen, p = out.numpy(), probability.numpy()
    expected = np.concatenate([[environment], (1.0 - environment) * pmf])
    counts = np.bincount(chosen + 1, minlength=len(expected)).astype(np.float64)
    assert counts[2] == 0  # the light of probability 0
    keep = expected > 0
    ok, stat, quantile = chi_square_ok(counts[keep], expected[keep] * count)
    assert ok, (stat, quantile)
    # the probability returned is the one the choice was made with
    np.testing.assert_allclose(p, expected[chosen + 1], rtol=1e-6)


# ---------------------------------------------------------------------------- MIS weights
def sphere_light(centre=(0.0, 0.0, 2.0), radius=0.5):
    light = AreaLightData()
    light.kind = AREA_SPHERE
    light.position = wp.vec3(*centre)
    light.radius = radius
    light.area = 4.0 * math.pi * radius * radius
    light.radiance = wp.vec3(1.0)
    return light


def rect_light(centre=(0.0, 0.0, 2.0), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, -0.6, 0.0)):
    light = AreaLightData()
    light.kind = AREA_RECT
    light.position = wp.vec3(*centre)
    light.edge_u = wp.vec3(*edge_u)
    light.edge_v = wp.vec3(*edge_v)
    normal = np.cross(edge_u, edge_v)
    light.normal = wp.vec3(*(normal / np.linalg.norm(normal)))
    light.area = float(np.linalg.norm(edge_u) * np.linalg.norm(edge_v))
    light.radiance = wp.vec3(1.0)
    return light


@wp.kernel(enable_backward=False)
def mis_weights(light: AreaLightData, selection: float, bsdf_pdf: float, seed: int, out: wp.array(dtype=wp.vec3)):
    """For a direction next-event estimation sampled from the origin: the NEE-side weight (with the
    pdf it sampled at), the BSDF-side weight (with the pdf the BSDF-sampled ray evaluates on hitting
    the light), and whether that ray hits it."""
    i = wp.tid()
    key = sample_key(seed, i, 0)
    u = wp.vec2(uniform(key, 0), uniform(key, 1))
    p = wp.vec3(0.1, -0.2, 0.0)
    d = wp.vec3(0.0)
    pdf = float(0.0)
    t = float(-1.0)
    evaluated = float(0.0)
    if light.kind == AREA_RECT:
        d, distance, pdf = sample_rect_light(light, p, u)
        t = ray_rect(light, p, d)
        evaluated = pdf_rect_light(light, p, d)
    else:
        d, distance, pdf = sample_sphere_light(light, p, u)
        t = ray_sphere(light, p, d)
        evaluated = pdf_sphere_light(light, p, d)
    nee = power_heuristic(selection * pdf, bsdf_pdf)
    bsdf = power_heuristic(bsdf_pdf, selection * evaluated)
    hit = float(0.0)
    if t > 0.0:
        hit = 1.0
    out[i] = wp.vec3(nee, bsdf, hit)


@pytest.mark.parametrize("light", [sphere_light(), rect_light()], ids=["sphere", "rect"])
@pytest.mark.parametrize("bsdf_pdf", [0.05, 0.8, 12.0])
def test_nee_and_bsdf_weights_of_area_lights_sum_to_one(light, bsdf_pdf):
    """For each direction next-event estimation samples on a light, the BSDF-sampled ray along it
    hits the light (ray_sphere / ray_rect) and evaluates the same density (pdf_*_light), so the two
    strategies' power-heuristic weights sum to 1."""
    count = 2000
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    wp.launch(mis_weights, dim=count, device="cpu", inputs=[light, 0.4, bsdf_pdf, 3, out])
    w = out.numpy().astype(np.float64)
    assert np.all(w[:, 2] == 1.0)
    np.testing.assert_allclose(w[:, 0] + w[:, 1], 1.0, atol=1e-5)


@wp.kernel(enable_backward=False)
def environment_weights(env_pdf: wp.array(dtype=float), bsdf_pdf: wp.array(dtype=float), selection: float,
                        out: wp.array(dtype=wp.vec2)):
    i = wp.tid()
    out[i] = wp.vec2(power_heuristic(selection * env_pdf[i], bsdf_pdf[i]),
                     power_heuristic(bsdf_pdf[i], selection * env_pdf[i]))


def test_nee_and_bsdf_weights_of_the_environment_sum_to_one():
    """The environment's density as sample_environment returns it and as pdf_environment evaluates
    it for the same direction agree (tests/test_environment_sampling.py), so both weights use one
    value: their sum is 1 for any pair of densities, selection probability included."""
    rng = np.random.default_rng(1)
    env_pdf = rng.uniform(1e-4, 50.0, 1000).astype(np.float32)
    bsdf_pdf = rng.uniform(1e-4, 50.0, 1000).astype(np.float32)
    out = wp.zeros(1000, dtype=wp.vec2, device="cpu")
    wp.launch(environment_weights, dim=1000, device="cpu",
              inputs=[wp.array(env_pdf, dtype=float), wp.array(bsdf_pdf, dtype=float), 0.3, out])
    w = out.numpy().astype(np.float64)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-6)


# ---------------------------------------------------------------------------- intersections
@wp.kernel(enable_backward=False)
def intersect(light: AreaLightData, origins: wp.array(dtype=wp.vec3), directions: wp.array(dtype=wp.vec3),
              out: wp.array(dtype=float)):
    i = wp.tid()
    if light.kind == AREA_RECT:
        out[i] = ray_rect(light, origins[i], directions[i])
    else:
        out[i] = ray_sphere(light, origins[i], directions[i])


def run_intersect(light, origins, directions):
    out = wp.zeros(len(origins), dtype=float, device="cpu")
    wp.launch(intersect, dim=len(origins), device="cpu",
              inputs=[light, wp.array(origins.astype(np.float32), dtype=wp.vec3),
                      wp.array(directions.astype(np.float32), dtype=wp.vec3), out])
    return out.numpy().astype(np.float64)


def unit_rows(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def sphere_reference(centre, radius, origins, directions):
    """Float64 near root of |o + t d - c| = r for origins outside, -1 otherwise."""
    f = origins - centre
    b = np.einsum("ij,ij->i", f, directions)
    c = np.einsum("ij,ij->i", f, f) - radius ** 2
    disc = b * b - c
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((c > 0) & (disc >= 0) & (b < 0), t, -1.0), disc


def test_ray_sphere_against_float64_including_grazing_and_inside():
    rng = np.random.default_rng(4)
    centre, radius = np.array([0.3, -0.2, 1.0]), 0.7
    light = sphere_light(centre, radius)
    n = 4000
    # outside, aimed at points around the sphere: hits, misses and near-grazing rays
    origins = centre + unit_rows(rng.normal(size=(n, 3))) * rng.uniform(0.75, 50.0, (n, 1))
    targets = centre + unit_rows(rng.normal(size=(n, 3))) * radius * rng.uniform(0.0, 1.3, (n, 1))
    directions = unit_rows(targets - origins)
    # exactly grazing: from 500 points at distances D, each along a tangent to the sphere (at the
    # angle asin(r / D) from the centre's direction, about a random axis); its tangent point lies
    # D cos(angle) away
    distances = rng.uniform(1.5, 50.0, 500)
    to_centre = unit_rows(rng.normal(size=(500, 3)))
    grazing = centre - to_centre * distances[:, None]
    across = unit_rows(np.cross(to_centre, rng.normal(size=(500, 3))))
    sin_angle = radius / distances
    cos_angle = np.sqrt(1.0 - sin_angle ** 2)
    tangent_dirs = to_centre * cos_angle[:, None] + across * sin_angle[:, None]
    # inside and on the sphere: no hit
    inside = centre + unit_rows(rng.normal(size=(500, 3))) * radius * rng.uniform(0.0, 0.999, (500, 1))
    origins = np.concatenate([origins, grazing, inside])
    directions = np.concatenate([directions, tangent_dirs, unit_rows(rng.normal(size=(500, 3)))])
    directions = unit_rows(directions.astype(np.float32).astype(np.float64))
    origins = origins.astype(np.float32).astype(np.float64)
    t = run_intersect(light, origins, directions)
    expected, disc = sphere_reference(centre, radius, origins, directions)
    assert np.all(np.isfinite(t))
    assert np.all(t[-500:] == -1.0)
    # a grazing ray that hits (rounding decides) hits at its tangent point
    touched = t[n:n + 500] > 0
    assert touched.sum() > 0, "no grazing ray hit: the check below would test nothing"
    np.testing.assert_allclose(t[n:n + 500][touched], (distances * cos_angle)[touched], rtol=2e-3)
    # hit or miss agree except within float32 rounding of the silhouette
    near_edge = np.abs(disc) < 1e-4 * radius ** 2 * (1 + np.linalg.norm(origins - centre, axis=1)) ** 2 * 1e-2
    agree = (t > 0) == (expected > 0)
    assert np.all(agree | near_edge)
    both = (t > 0) & (expected > 0)
    assert both.sum() > 1000
    np.testing.assert_allclose(t[both], expected[both], rtol=2e-4, atol=1e-5)
    # hit points lie on the sphere
    points = origins[both] + directions[both] * t[both, None]
    np.testing.assert_allclose(np.linalg.norm(points - centre, axis=1), radius, rtol=1e-3)
    # far away and huge: no NaN or Inf
    far = run_intersect(light, np.array([[1e30, 0.0, 1.0], [3e38, 3e38, 3e38]]),
                        unit_rows(np.array([[-1.0, 0.0, 0.0], [-1.0, -1.0, -1.0]])))
    assert np.all(np.isfinite(far))


def test_ray_rect_against_float64_including_grazing_and_behind():
    rng = np.random.default_rng(5)
    centre = np.array([0.2, 0.1, 2.0])
    edge_u, edge_v = np.array([1.2, 0.0, 0.0]), np.array([0.0, -0.5, 0.0])  # normal -z: lights downwards
    light = rect_light(centre, edge_u, edge_v)
    n = 4000
    origins = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(-2.0, 4.0, n)])
    targets = centre + rng.uniform(-0.7, 0.7, (n, 1)) * edge_u + rng.uniform(-0.7, 0.7, (n, 1)) * edge_v
    directions = unit_rows(targets - origins)
    # grazing: nearly in the plane, just below it
    grazing_origins = centre + np.array([-5.0, 0.0, -1e-3]) + np.zeros((200, 3))
    grazing_dirs = unit_rows(np.column_stack([np.ones(200), rng.uniform(-0.02, 0.02, 200), np.full(200, 1.9e-4)]))
    origins = np.concatenate([origins, grazing_origins]).astype(np.float32).astype(np.float64)
    directions = unit_rows(np.concatenate([directions, grazing_dirs]).astype(np.float32).astype(np.float64))
    t = run_intersect(light, origins, directions)
    normal = np.array([0.0, 0.0, -1.0])
    height = (origins - centre) @ normal
    cos_light = -(directions @ normal)
    t_plane = height / np.where(cos_light > 0, cos_light, 1.0)
    local = origins + directions * t_plane[:, None] - centre
    su, sv = local @ edge_u / (edge_u @ edge_u), local @ edge_v / (edge_v @ edge_v)
    inside = (np.abs(su) <= 0.5) & (np.abs(sv) <= 0.5)
    expected = np.where((height > 0) & (cos_light > 0) & inside, t_plane, -1.0)
    assert np.all(np.isfinite(t))
    near_edge = (np.abs(np.abs(su) - 0.5) < 1e-4) | (np.abs(np.abs(sv) - 0.5) < 1e-4)
    assert np.all(((t > 0) == (expected > 0)) | near_edge)
    both = (t > 0) & (expected > 0)
    assert both.sum() > 500 and np.any(both[-200:])
    np.testing.assert_allclose(t[both], expected[both], rtol=1e-4)
    assert np.all(t[height <= 0] == -1.0)  # behind the light: its back emits nothing


def test_area_lights_that_emit_nothing_leave_the_table_empty_and_the_image_black():
    """Lights of zero intensity get no table entry (the table is empty): BSDF-sampled rays that
    meet them must not read entries that do not exist."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0))
    for z in (1.0, 2.0, 3.0):
        scene.add_light(pw.SphereLight(position=(0.0, 0.0, z), radius=0.3, intensity=0.0))
    scene.add_light(pw.RectLight(position=(0.0, 0.0, 1.5), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, -1.0, 0.0),
                                 intensity=0.0))
    frame = pw.render(scene, DOWN, width=8, height=8, spp=4, integrator="path", max_bounces=2, progress=False)
    assert np.all(frame.rgb == 0.0)


def test_an_accumulator_keeps_the_light_table_of_the_scene_it_was_made_for():
    """An Accumulator renders the upload it was made with. Once the scene gains lights and another
    render has cached the new upload's table, the Accumulator's next pass must still choose among
    its own upload's lights (an entry past them would read outside the light array): the passes
    add up to one render of the original scene."""
    def lit_plane():
        scene = pw.Scene()
        scene.add_mesh(quad(size=4.0))
        scene.add_light(pw.PointLight(position=(0.3, 0.2, 1.0), intensity=2.0))
        return scene

    options = dict(width=8, height=8, max_bounces=1, seed=4, progress=False)
    scene = lit_plane()
    accumulator = pw.Accumulator(scene, DOWN, spp=2, **options)
    accumulator.add()
    for k in range(3):
        scene.add_light(pw.PointLight(position=(-0.5 + 0.5 * k, 0.0, 1.0), intensity=1e3))
    pw.render(scene, DOWN, spp=1, integrator="path", **options)
    frame = accumulator.add()
    expected = pw.render(lit_plane(), DOWN, spp=4, integrator="path", **options)
    np.testing.assert_allclose(frame.rgb, expected.rgb, rtol=1e-5, atol=1e-7)


def test_one_bounce_equals_direct_monte_carlo_under_every_light_kind_at_once():
    """A sphere light, a rectangle light and an environment together: next-event estimation
    chooses among them with probabilities below 1 (the environment beside the table), and each
    BSDF-sampled hit must weigh its light with the same selection probability the choice used;
    any mismatch biases the sum away from the direct integrator's."""
    scene = floor_with_blocker()
    scene.add_light(pw.SphereLight(position=(-0.6, 0.6, 1.2), radius=0.5, intensity=3.0))
    scene.add_light(pw.RectLight(position=(0.5, -0.4, 1.0), edge_u=(1.5, 0.0, 0.0), edge_v=(0.0, -1.2, 0.0),
                                 intensity=2.0))
    scene.environment = pw.Environment.uniform((0.6, 0.6, 0.6))
    assert 0.05 < light_table(scene, upload(scene), environment_lights=True).environment < 0.95
    assert_path_matches_direct(scene, dict(spp=4, area_lighting=pw.AreaLighting("monte_carlo", 64),
                                           ibl=pw.IBL(method="monte_carlo", samples=256, shadowed=True)))


def test_a_rect_light_flush_with_a_ceiling_lights_as_one_just_below_it():
    """BSDF-sampled rays reach the ceiling and the light in its plane at the same distance, up to
    rounding; they must count the light as next-event estimation's shadow rays (which stop short
    of it) do, or a glossy floor loses about half the light MIS gives that strategy."""

    def floor_lit_from(height):
        scene = pw.Scene()
        scene.add_mesh(quad(size=4.0, z=0.0, material=pw.Material(base_color=(1.0, 1.0, 1.0), metallic=1.0,
                                                                  roughness=0.15)))
        ceiling = quad(size=4.0, z=2.0)
        scene.primitives.append(pw.Primitive(ceiling.positions, ceiling.faces[:, ::-1], ceiling.material,
                                             -ceiling.normals, ceiling.uvs))
        scene.add_light(pw.RectLight(position=(0.0, 0.0, height), edge_u=(1.0, 0.0, 0.0), edge_v=(0.0, -1.0, 0.0),
                                     intensity=5.0))
        return scene

    camera = pw.Camera.look_at(eye=(0.0, 0.0, 1.5), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=50.0)
    flush, below = (pw.render(floor_lit_from(z), camera, width=24, height=24, spp=32, integrator="path",
                              max_bounces=1, seed=3, progress=False).rgb.mean() for z in (2.0, 1.999))
    assert flush == pytest.approx(below, rel=0.03)
