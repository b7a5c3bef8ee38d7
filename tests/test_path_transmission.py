"""Transmission with refraction in the path tracer (kernels/path_transmission.py): energy
conservation of a glass ball in a white furnace, Beer-Lambert absorption inside a volume, the
rough thin wall's lobe, the bare interface's sampler against its pdf, and finite output where
rays graze, reflect totally or start inside a volume."""

import math

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.features import path_features, scene_features
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.path_transmission import sample_dielectric_interface

import reference as ref
from goodness_of_fit import chi_square_ok
from scenes import head_on_camera, quad
from test_transmission import (binned, g1_ggx, glowing, histogram, rough_interface_pdfs, slab, sphere_grid,
                               visible_normals_pdf)

# Smith's separable masking-shadowing: its GGX reflection lobe at roughness 0 reflects F, as the
# refraction's 1 - F expects (the default Schlick-GGX darkens grazing reflections)
EXACT_GEOMETRY = pw.BRDF(geometry="smith_separable")


def render(scene, camera, size, **options):
    options.setdefault("progress", False)
    return pw.render(scene, camera, width=size, height=size, integrator="path", brdf=EXACT_GEOMETRY, **options)


def glass(**kwargs):
    return pw.Material(**{"base_color": (1.0, 1.0, 1.0), "metallic": 0.0, "roughness": 0.0, "transmission": 1.0,
                          "thickness": 1.0, "ior": 1.5, **kwargs})


def ball(material, radius=1.0):
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    return pw.Primitive(np.asarray(sphere.vertices), np.asarray(sphere.faces), material,
                        np.asarray(sphere.vertex_normals))


# ---------------------------------------------------------------------------- (a) white furnace
FURNACE_L = 0.7


def furnace(material):
    scene = pw.Scene()
    scene.add_mesh(ball(material))
    scene.environment = pw.Environment.uniform((FURNACE_L,) * 3)
    return scene


BALL_VIEW = pw.Camera.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0), fov_y=32.0)


def test_a_smooth_glass_ball_in_a_white_furnace_returns_what_it_receives():
    """A smooth, clear, non-absorbing dielectric ball (ior 1.5) in a uniform environment of
    radiance L: reflection (Fresnel F) and refraction (1 - F) at each interface, total internal
    reflection where it occurs, conserve energy, so every pixel shows L (Russian roulette and the
    choice between reflection and refraction make the noise; 24 bounces leave out less than
    0.04^12 of the light). Every pixel within 5% (the largest spread of the noise here), the
    image's mean within 0.5%."""
    frame = render(furnace(glass()), BALL_VIEW, 20, spp=64, max_bounces=24, seed=2)
    assert np.all(np.isfinite(frame.rgb))
    values = frame.rgb.astype(np.float64)
    np.testing.assert_allclose(values, FURNACE_L, rtol=0.05)
    assert abs(values.mean() / FURNACE_L - 1.0) < 0.005, values.mean()


@pytest.mark.parametrize("thickness", [1.0, 0.0])
def test_a_rough_glass_ball_in_a_white_furnace_returns_no_more_than_it_receives(thickness):
    """Rough (0.5) volume and rough thin-walled ball: single-scattering microfacet lobes lose the
    light that would scatter between facets, never gain any: no pixel above L (beyond noise:
    4 standard errors of its mean), and the ball visibly below it on average."""
    spp = 32
    frame = render(furnace(glass(roughness=0.5, thickness=thickness)), BALL_VIEW, 20, spp=spp, max_bounces=16, seed=3)
    assert np.all(np.isfinite(frame.rgb))
    values = frame.rgb[..., 0].astype(np.float64)
    error = values.std(ddof=1) / math.sqrt(spp)
    assert np.all(values <= FURNACE_L + 4 * error), (values.max(), error)
    assert values.mean() < FURNACE_L


# ---------------------------------------------------------------------------- (b) Beer-Lambert
BACKGROUND = np.array([0.8, 0.6, 0.4])
NARROW = head_on_camera(distance=3.0, fov=2.0)  # rays within 1 degree of the normal


@pytest.mark.parametrize("ior", [1.0, 1.5])
def test_a_volume_absorbs_by_beer_lambert_what_is_seen_through_it(ior):
    """A box 0.6 thick, seen head-on before a uniform background B: its absorption is
    exp(-sigma d) per crossing, sigma = -ln(attenuationColor) / attenuationDistance
    (KHR_materials_volume). With ior 1 nothing reflects: B exp(-sigma d). With ior 1.5 each
    interface transmits T = 0.96 and reflects R = 0.04 at normal incidence, and light reflected
    inside goes on crossing the box: B T^2 exp(-sigma d) / (1 - R exp(-sigma d)) (the sum over
    the number of reflections inside; what leaves by the top after an odd number is seen as the
    background too). The image's mean within 4 standard errors (plus the 1e-3 the 1 degree
    spread of the rays may add to the path inside)."""
    colour, distance, depth = np.array([0.5, 0.8, 0.95]), 1.0, 0.6
    scene = pw.Scene()
    scene.add_mesh(slab(depth, glass(ior=ior, attenuation_color=tuple(colour), attenuation_distance=distance)))
    spp = 32
    frame = render(scene, NARROW, 12, spp=spp, max_bounces=16, background=tuple(BACKGROUND), seed=4)
    absorbed = np.exp(np.log(colour) / distance * depth)
    if ior == 1.0:
        expected = BACKGROUND * absorbed
    else:
        reflected = ((ior - 1) / (ior + 1)) ** 2
        expected = BACKGROUND * (1 - reflected) ** 2 * absorbed / (1 - reflected * absorbed)
    values = frame.rgb.reshape(-1, 3).astype(np.float64)
    error = values.std(0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(0) - expected) < 4 * error + 1e-3 * expected), (values.mean(0), expected, error)
    np.testing.assert_array_equal(frame.alpha, 1.0)


# ---------------------------------------------------------------------------- (e) against the direct integrator
def test_two_bounces_through_a_volume_equal_the_direct_integrator():
    """A smooth absorbing box before an emitter, seen head-on: with two bounces (into the box, out
    of it, then the emitter) the path tracer follows what the direct integrator does, entering
    (1 - F), absorbed exp(-sigma d), leaving (1 - F), and drops what reflects inside (which needs
    more bounces), so the two agree: the path tracer's mean within 4 standard errors of the
    direct integrator's image (itself exact but for float32)."""
    colour, distance, depth, le = np.array([0.5, 0.8, 0.95]), 1.0, 0.6, np.array([0.2, 0.5, 0.9])
    scene = pw.Scene()
    scene.add_mesh(slab(depth, glass(attenuation_color=tuple(colour), attenuation_distance=distance)))
    scene.add_mesh(quad(size=4.0, z=-0.5, material=glowing(le)))
    direct = pw.render(scene, NARROW, width=12, height=12, progress=False).rgb.reshape(-1, 3).astype(np.float64)
    path = render(scene, NARROW, 12, spp=32, max_bounces=2, seed=9).rgb.reshape(-1, 3).astype(np.float64)
    error = path.std(0, ddof=1) / math.sqrt(len(path))
    expected = direct.mean(0)
    np.testing.assert_allclose(expected, 0.96**2 * np.exp(np.log(colour) / distance * depth) * le, rtol=2e-3)
    assert np.all(np.abs(path.mean(0) - expected) < 4 * error + 1e-3 * expected), (path.mean(0), expected, error)


# ---------------------------------------------------------------------------- (e) a rough thin wall
def test_a_rough_thin_wall_before_an_emitter_transmits_its_lobe_weighted_share():
    """A rough (0.5) thin wall seen head-on before an emitter of radiance Le that fills the
    half space behind it: what passes is the transmitted share (1 - F(1)) = 0.96 times the mean
    weight of the thin lobe's samples, E[G1(l)] over its density (the weight 0 where a reflection
    would leave below the surface), integrated in float64 from Heitz 2018's visible-normal
    density. Pixels' mean within 4 standard errors."""
    roughness, le = 0.5, np.array([2.0, 1.0, 0.5])
    scene = pw.Scene()
    scene.add_mesh(quad(size=2000.0, z=-1.0, material=pw.Material(base_color=(0.0, 0.0, 0.0), specular=0.0,
                                                                  emissive=tuple(le))))
    scene.add_mesh(quad(size=8.0, z=0.0, material=glass(roughness=roughness, thickness=0.0)))
    spp = 32
    frame = render(scene, NARROW, 12, spp=spp, max_bounces=2, seed=5)
    alpha = roughness**2  # transmission_roughness(0.5, 1.5) = 0.5: 2 ior - 2 >= 1
    v = np.array([0.0, 0.0, 1.0])
    grid, cell = sphere_grid()
    mirrored = grid * [1.0, 1.0, -1.0]
    m = ref.normalize(v + mirrored)
    density = np.where(grid[..., 2] < 0, visible_normals_pdf(m, v, alpha) / (4 * np.maximum(m @ v, 1e-300)), 0.0)
    mean_weight = (density * g1_ggx(np.abs(grid[..., 2]), alpha)).sum() * cell
    expected = 0.96 * mean_weight * le
    values = frame.rgb.reshape(-1, 3).astype(np.float64)
    error = values.std(0, ddof=1) / math.sqrt(len(values))
    assert 0.5 < mean_weight < 1.0
    assert np.all(np.abs(values.mean(0) - expected) < 4 * error + 2e-3 * expected), (values.mean(0), expected, error)


@pytest.mark.parametrize("angle", [20.0, 50.0])
def test_a_directional_light_behind_a_rough_thin_wall_is_lit_through_its_lobe(angle):
    """A rough (0.5) thin wall seen head-on, lit from behind by a directional light of E lux
    arriving at ``angle`` from the wall's normal: next-event estimation reaches it through the
    transmission lobe, so the wall shows 0.96 f_t E cos, f_t the lobe at l, the GGX specular lobe
    at the mirror image l' of l: D(m) G1(v) G1(l') / (4 n.v n.l'), m the half vector of v and l'
    (with separable Smith G; F = 1, the share 0.96 outside). Nothing else lights it. Pixels'
    mean within 4 standard errors (the choice between the lobe and reflection makes the noise)
    plus 1% for the 1 degree spread of the camera rays."""
    roughness, lux = 0.5, 3.0
    theta = math.radians(angle)
    travel = (math.sin(theta), 0.0, math.cos(theta))  # upwards, through the wall from behind
    scene = pw.Scene()
    scene.add_mesh(quad(size=8.0, z=0.0, material=glass(roughness=roughness, thickness=0.0)))
    scene.add_light(pw.DirectionalLight(direction=travel, intensity=lux))
    frame = render(scene, NARROW, 12, spp=16, max_bounces=1, seed=8)
    alpha = roughness**2
    v, l_mirror = np.array([0.0, 0.0, 1.0]), np.array([-travel[0], 0.0, travel[2]])
    m = ref.normalize(v + l_mirror)
    lobe = ref.d_ggx(m[2], alpha) * g1_ggx(v[2], alpha) * g1_ggx(l_mirror[2], alpha) / (4 * v[2] * l_mirror[2])
    expected = 0.96 * lobe * lux * math.cos(theta)
    values = frame.rgb[..., 0].astype(np.float64).ravel()
    error = values.std(ddof=1) / math.sqrt(len(values))
    assert abs(values.mean() - expected) < 4 * error + 0.01 * expected, (values.mean(), expected, error)


# ---------------------------------------------------------------------------- (c) the bare interface's sampler
@wp.kernel(enable_backward=False)
def draw_interface(d: wp.vec3, eta: float, roughness: float, seed: int, out: wp.array(dtype=wp.vec3),
                   weights: wp.array(dtype=float)):
    i = wp.tid()
    state = wp.rand_init(seed, i)
    n = wp.vec3(0.0, 0.0, 1.0)
    direction, weight = sample_dielectric_interface(d, n, n, eta, roughness, wp.randf(state),
                                                    wp.vec2(wp.randf(state), wp.randf(state)))
    out[i] = direction
    weights[i] = weight


def draw_interface_samples(v, eta, roughness, count=300_000, seed=7):
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    weights = wp.zeros(count, dtype=float, device="cpu")
    wp.launch(draw_interface, dim=count, device="cpu",
              inputs=[wp.vec3(*(-np.asarray(v))), eta, roughness, seed, out, weights])
    return out.numpy().astype(np.float64), weights.numpy().astype(np.float64)


def fresnel_reference(cos_i, eta):
    """Unpolarised Fresnel reflectance from the s and p amplitudes (Born & Wolf), relative IOR
    eta = n_t / n_i; 1 past the critical angle; float64."""
    cos_i = np.clip(cos_i, 0.0, 1.0)
    sin2_t = (1 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.maximum(1 - sin2_t, 0.0))
    r_s = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, 1e-300)
    r_p = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, 1e-300)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (r_s**2 + r_p**2))


def dielectric_interface_pdf(l, v, eta, alpha):
    """The density of sample_dielectric_interface's directions (normal +z): a visible GGX normal
    m reflects with probability F(v.m), F(v.m) G1(v) D(m) / (4 v.z) at the half vector
    (Heitz 2018, eq. 17), and refracts otherwise, (1 - F(v.m)) times Walter et al. 2007's density
    of the refracted direction; float64."""
    refracted, _ = rough_interface_pdfs(l, v, eta, alpha)
    half = v + eta * l
    m_t = half * np.where(half[..., 2:] < 0, -1.0, 1.0) / np.linalg.norm(half, axis=-1, keepdims=True)
    refracted = refracted * (1 - fresnel_reference(m_t @ v, eta))
    m_r = ref.normalize(v + l)
    v_m = m_r @ v
    reflected = np.where((v_m > 0) & (m_r[..., 2] > 0),
                         fresnel_reference(v_m, eta) * visible_normals_pdf(m_r, v, alpha)
                         / (4 * np.maximum(v_m, 1e-300)), 0.0)
    return refracted + reflected


INTERFACE_CASES = [(0.3, 1 / 1.5, 0.3), (0.6, 1 / 1.5, 0.9), (0.5, 1.5, 1.2), (0.8, 1 / 1.33, 1.3)]


@pytest.mark.parametrize("roughness, eta, theta", INTERFACE_CASES)
def test_dielectric_interface_samples_follow_their_pdf(roughness, eta, theta):
    """sample_dielectric_interface (a volume's inside): its directions against the density of
    reflecting off a visible GGX normal with probability F and refracting through it otherwise
    (chi-square over (cos theta, phi) bins of the whole sphere); the density integrates to 1;
    the weight is G1 of the new direction, 0 where it leaves on the wrong side (a reflection
    below the surface, a refraction above it)."""
    alpha = roughness**2
    v = np.array([np.sin(theta), 0.0, np.cos(theta)])
    l, weight = draw_interface_samples(v, eta, roughness)
    grid, cell = sphere_grid()
    density = dielectric_interface_pdf(grid, v, eta, alpha)
    assert abs(density.sum() * cell - 1.0) < 3e-3
    ok, stat, quantile = chi_square_ok(histogram(l).ravel(), binned(density, cell).ravel() * len(l))
    assert ok, (stat, quantile)
    kept = weight > 0
    assert kept.mean() > 0.5
    np.testing.assert_allclose(weight[kept], g1_ggx(np.abs(l[kept, 2]), alpha), rtol=1e-4)


@pytest.mark.parametrize("eta, theta", [(1 / 1.5, 0.3), (1 / 1.5, 0.8), (1 / 1.5, 1.2), (1.5, 1.4)])
def test_a_smooth_interface_reflects_with_the_fresnel_probability(eta, theta):
    """At roughness 0 the interface reflects (mirror direction) with probability F(cos theta)
    (1 past the critical angle, 41.8 degrees out of glass), refracts by Snell's law otherwise,
    weight 1. The share reflected within 4 binomial standard errors of F."""
    v = np.array([np.sin(theta), 0.0, np.cos(theta)])
    l, weight = draw_interface_samples(v, eta, 0.0, count=100_000)
    np.testing.assert_array_equal(weight, 1.0)
    reflects = l[:, 2] > 0
    np.testing.assert_allclose(l[reflects], np.broadcast_to(v * [-1, -1, 1], l[reflects].shape), atol=1e-5)
    f = float(fresnel_reference(np.cos(theta), eta))
    assert abs(reflects.mean() - f) <= 4 * math.sqrt(max(f * (1 - f), 1e-12) / len(l)) + 1e-9, (reflects.mean(), f)
    if f < 1:
        sin_t = np.sin(theta) / eta
        refracted = np.array([-sin_t, 0.0, -math.sqrt(1 - sin_t**2)])
        np.testing.assert_allclose(l[~reflects], np.broadcast_to(refracted, l[~reflects].shape), atol=1e-5)


# ---------------------------------------------------------------------------- (d) hard cases
def prism(material):
    """A right-angled glass prism: a ray entering its long face head-on meets a short face at
    45 degrees, past glass's critical angle (41.8): total internal reflection."""
    hull = trimesh.convex.convex_hull(
        np.array([[-1, 0, -1], [1, 0, -1], [0, 0, 0], [-1, 1, -1], [1, 1, -1], [0, 1, 0]], float))
    positions = hull.vertices[hull.faces].reshape(-1, 3)  # faces unshared: flat normals, wound outwards
    return pw.Primitive(positions, np.arange(len(positions)).reshape(-1, 3), material,
                        np.repeat(hull.face_normals, 3, axis=0))


HARD_VIEWS = [pw.Camera.look_at(eye=(0.0, 0.5, -3.0), target=(0.0, 0.5, -0.5), fov_y=40.0),  # into the prism
              pw.Camera.look_at(eye=(3.0, 0.5, -0.98), target=(0.0, 0.5, -1.0), fov_y=30.0),  # grazing
              pw.Camera.look_at(eye=(0.0, 0.5, -0.6), target=(1.0, 0.5, -0.6), fov_y=120.0)]  # from inside


@pytest.mark.parametrize("roughness", [0.0, 0.4])
@pytest.mark.parametrize("view", range(len(HARD_VIEWS)))
def test_no_nan_or_inf_at_grazing_angles_total_internal_reflection_and_inside(view, roughness):
    """A prism (total internal reflection), a thin ball and a thin pane whose shading normals face
    away from its geometry, smooth and rough, lit by a point light, a sphere light and the
    environment, seen from outside, at grazing angles and from inside the prism: a finite,
    checked frame."""
    scene = pw.Scene()
    scene.add_mesh(prism(glass(roughness=roughness, attenuation_color=(0.5, 0.7, 0.9), attenuation_distance=0.5)))
    scene.add_mesh(ball(glass(roughness=roughness, thickness=0.0), radius=0.3))
    pane = quad(size=1.0, z=-0.2, material=glass(roughness=roughness, thickness=0.0))
    scene.add_mesh(pw.Primitive(pane.positions + [0.0, 0.8, 0.0], pane.faces, pane.material, -pane.normals))
    scene.add_mesh(quad(size=20.0, z=-2.0))
    scene.add_light(pw.PointLight(position=(0.0, 3.0, 2.0), intensity=50.0))
    scene.add_light(pw.SphereLight(position=(1.0, 2.0, 1.0), radius=0.2, color=(1.0, 1.0, 1.0), intensity=5.0))
    scene.environment = pw.Environment.uniform((0.3, 0.3, 0.3))
    frame = render(scene, HARD_VIEWS[view], 12, spp=4, max_bounces=12, seed=view)
    report = pw.check(frame)
    assert report.ok, report
    assert np.all(np.isfinite(frame.rgb))


def test_total_internal_reflection_sends_the_ray_back_out_of_a_prism():
    """Seen head-on through its long face, a smooth prism's short faces reflect the ray totally
    (45 degrees, past glass's 41.8: F = 1) and send it back out through the long face, where it
    leaves with T = 0.96 or reflects R = 0.04 inside for another round: the camera sees the
    uniform background behind it B T^2 / (1 - R) = 0.96 B (the light reflected on entering
    sees nothing: no light). The mean within 4 standard errors."""
    scene = pw.Scene()
    scene.add_mesh(prism(glass(thickness=1.0)))
    camera = pw.Camera.look_at(eye=(0.0, 0.5, -4.0), target=(0.0, 0.5, 0.0), fov_y=2.0)
    frame = render(scene, camera, 8, spp=16, max_bounces=12, background=tuple(BACKGROUND), seed=6)
    values = frame.rgb.reshape(-1, 3).astype(np.float64)
    expected = 0.96**2 / (1 - 0.04) * BACKGROUND
    error = values.std(0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(0) - expected) < 4 * error + 1e-3 * expected), (values.mean(0), expected, error)


def test_an_alpha_blended_volume_is_passed_as_thin_walls():
    """An alpha-blended glass box (alpha 1) with thickness and attenuation is two thin walls, as in
    the direct kernel (paths passing blended surfaces by coverage cannot tell inside from out):
    no refraction, no absorption, each wall passing 0.96 of the background: 0.96^2 B, the mean
    within 4 standard errors."""
    scene = pw.Scene()
    scene.add_mesh(slab(0.6, glass(base_color=(1.0, 1.0, 1.0, 1.0), alpha_mode="BLEND",
                                   attenuation_color=(0.5, 0.8, 0.95), attenuation_distance=1.0)))
    frame = render(scene, NARROW, 8, spp=16, max_bounces=8, background=tuple(BACKGROUND), seed=10)
    values = frame.rgb.reshape(-1, 3).astype(np.float64)
    expected = 0.96**2 * BACKGROUND
    error = values.std(0, ddof=1) / math.sqrt(len(values))
    assert np.all(np.abs(values.mean(0) - expected) < 4 * error + 1e-3 * expected), (values.mean(0), expected, error)


# ---------------------------------------------------------------------------- what is compiled, what explain says
def test_transmission_lobes_are_compiled_in_only_where_a_scene_has_volumes_or_rough_walls():
    """A smooth thin wall keeps the path kernel's null events alone (no volume, no rough
    transmission flags: none of kernels/path_transmission.py's lobes compiled in); a volume sets
    ``volume``, a rough thin wall ``rough_transmission``; an opaque scene neither."""
    def flags(material):
        scene = pw.Scene()
        scene.add_mesh(quad(size=4.0, material=material))
        scene.add_light(pw.PointLight(position=(0.0, 0.0, 2.0)))
        f = path_features(scene_features(scene, upload(scene), shadows="rays", spp=1, integrator="path",
                                         max_bounces=4))
        return f.transmission, f.volume, f.rough_transmission

    assert flags(pw.Material()) == (False, False, False)
    assert flags(glass(thickness=0.0)) == (True, False, False)
    assert flags(glass(thickness=0.0, roughness=0.4, ior=1.0)) == (True, False, False)  # ior 1 bends nothing
    assert flags(glass(thickness=0.5)) == (True, True, False)
    assert flags(glass(thickness=0.0, roughness=0.4)) == (True, False, "sampled")


# ---------------------------------------------------------------------------- what explain says
def test_volumes_and_rough_walls_are_simulated_without_a_warning(recwarn):
    scene = furnace(glass(roughness=0.3))
    text = pw.explain(scene, integrator="path")
    assert "paths refract into and out of volumes" in text
    assert "not simulated by the path tracer yet" not in text
    thin = furnace(glass(roughness=0.3, thickness=0.0))
    assert "rough thin walls along the GGX transmission lobe" in pw.explain(thin, integrator="path")
    render(thin, BALL_VIEW, 4, spp=1)
    assert not [w for w in recwarn if "does not simulate" in str(w.message)]
