"""The path tracer's sampling routines against float64 NumPy references written from their
formulas: counter-based random numbers, the glTF BRDF's lobe-mixture sampler and its pdf, the
power heuristic, the light table's discrete distribution and uniform points on triangles, turned
into solid-angle pdfs (chi-square goodness-of-fit tests in the manner of Mitsuba 3's suite)."""

import math

import numpy as np
import pytest
import warp as wp

from pbrwarp.emitters import face_weights
from pbrwarp.kernels.bsdf_sampling import (pdf_brdf_direction, pdf_coated_direction, power_heuristic,
                                           sample_brdf_direction, sample_coated_direction, specular_lobe_probability)
from pbrwarp.kernels.emitters import LightTable, area_to_solid_angle, choose_light, sample_triangle
from pbrwarp.kernels.random import sample_key, uniform

from goodness_of_fit import chi_square_ok
from test_ibl import vndf_reflection_pdf


# ---------------------------------------------------------------------------- random numbers
@wp.kernel(enable_backward=False)
def uniforms(seed: int, samples: int, dimensions: int, out: wp.array2d(dtype=float)):
    i = wp.tid()  # (pixel, sample) pairs in order
    key = sample_key(seed, i / samples, i % samples)
    for d in range(dimensions):
        out[i, d] = uniform(key, d)


def draw_uniforms(seed, pixels=4000, samples=16, dimensions=4):
    out = wp.zeros((pixels * samples, dimensions), dtype=float, device="cpu")
    wp.launch(uniforms, dim=pixels * samples, device="cpu", inputs=[seed, samples, dimensions, out])
    return out.numpy().astype(np.float64)


def test_counter_based_numbers_are_uniform_independent_and_reproducible():
    u = draw_uniforms(seed=3)
    assert u.min() >= 0.0 and u.max() < 1.0
    n = len(u)
    for d in range(u.shape[1]):  # each dimension uniform: 100 bins
        counts = np.histogram(u[:, d], bins=100, range=(0, 1))[0]
        ok, stat, quantile = chi_square_ok(counts, np.full(100, n / 100))
        assert ok, (d, stat, quantile)
    # pairs of dimensions, and the same dimension of neighbouring samples and pixels, jointly uniform
    for a, b in ((u[:, 0], u[:, 1]), (u[:, 2], u[:, 3]), (u[:-1, 0], u[1:, 0]), (u[:-16, 1], u[16:, 1])):
        counts = np.histogram2d(a, b, bins=12, range=[[0, 1], [0, 1]])[0].ravel()
        ok, stat, quantile = chi_square_ok(counts, np.full(144, len(a) / 144))
        assert ok, (stat, quantile)
    np.testing.assert_array_equal(u, draw_uniforms(seed=3))
    other = draw_uniforms(seed=4)
    assert np.mean(other == u) < 1e-3
    assert abs(np.corrcoef(u[:, 0], other[:, 0])[0, 1]) < 0.02


# ---------------------------------------------------------------------------- the lobe mixture
@wp.kernel(enable_backward=False)
def draw_directions(n: wp.vec3, v: wp.vec3, alpha: float, p_specular: float, seed: int,
                    out: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float)):
    i = wp.tid()
    key = sample_key(seed, i, 0)
    l = sample_brdf_direction(n, v, alpha, p_specular, uniform(key, 0), wp.vec2(uniform(key, 1), uniform(key, 2)))
    out[i] = l
    pdf[i] = pdf_brdf_direction(n, v, l, alpha, p_specular)


@wp.kernel(enable_backward=False)
def evaluate_pdf(n: wp.vec3, v: wp.vec3, alpha: float, p_specular: float, directions: wp.array(dtype=wp.vec3),
                 pdf: wp.array(dtype=float)):
    i = wp.tid()
    pdf[i] = pdf_brdf_direction(n, v, directions[i], alpha, p_specular)


def mixture_pdf(l, v, alpha, p_specular):
    """(1 - P) max(cos, 0) / pi + P G1(v) D(h) / (4 n.v) in the frame where n = +z, float64."""
    with np.errstate(invalid="ignore", divide="ignore"):
        specular = np.nan_to_num(vndf_reflection_pdf(l, v, max(alpha, math.sqrt(1e-7))))
    return (1 - p_specular) * np.maximum(l[..., 2], 0) / np.pi + p_specular * specular


def sphere_grid(steps):
    """Midpoints of an equal-area (cos theta, phi) grid over the sphere and each cell's solid angle."""
    mu = -1 + (np.arange(2 * steps) + 0.5) / steps
    phi = -np.pi + (np.arange(2 * steps) + 0.5) * np.pi / steps
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m**2)
    return np.stack([s * np.cos(p), s * np.sin(p), m], -1), (1 / steps) * (np.pi / steps)


CASES = [(0.3, 0.5, 0.5), (1.2, 0.3, 0.7), (0.8, 0.9, 0.2), (1.5, 0.6, 1.0), (0.1, 1.0, 0.0)]


@pytest.mark.parametrize("theta_v, roughness, p_specular", CASES)
def test_lobe_mixture_samples_follow_their_pdf_which_integrates_to_one(theta_v, roughness, p_specular):
    v = np.array([math.sin(theta_v), 0.0, math.cos(theta_v)])
    alpha = roughness**2
    count = 200_000
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    pdf = wp.zeros(count, dtype=float, device="cpu")
    wp.launch(draw_directions, dim=count, device="cpu",
              inputs=[wp.vec3(0.0, 0.0, 1.0), wp.vec3(*v), alpha, p_specular, 17, out, pdf])
    l = out.numpy().astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(l, axis=1), 1.0, atol=1e-5)
    # the kernel's pdf at the samples is the mixture's
    np.testing.assert_allclose(pdf.numpy(), mixture_pdf(l, v, alpha, p_specular), rtol=3e-3, atol=1e-6)
    # the kernel's pdf integrates to 1 over the sphere (midpoint rule on an equal-area grid)
    steps = 600
    grid, cell = sphere_grid(steps)
    density = wp.zeros(grid.shape[0] * grid.shape[1], dtype=float, device="cpu")
    wp.launch(evaluate_pdf, dim=density.shape[0], device="cpu",
              inputs=[wp.vec3(0.0, 0.0, 1.0), wp.vec3(*v), alpha, p_specular,
                      wp.array(grid.reshape(-1, 3), dtype=wp.vec3, device="cpu"), density])
    density = density.numpy().astype(np.float64).reshape(grid.shape[:2])
    assert abs(density.sum() * cell - 1.0) < 3e-3
    # samples land in 12 x 12 (cos theta, phi) bins as often as the float64 pdf says
    fine, cell = sphere_grid(900)
    expected = mixture_pdf(fine, v, alpha, p_specular).reshape(12, 150, 12, 150).sum((1, 3)) * cell
    counts = np.histogram2d(l[:, 2], np.arctan2(l[:, 1], l[:, 0]), bins=12, range=[[-1, 1], [-np.pi, np.pi]])[0]
    ok, stat, quantile = chi_square_ok(counts.ravel(), expected.ravel() * count)
    assert ok, (stat, quantile)


@wp.kernel(enable_backward=False)
def draw_coated_directions(v: wp.vec3, alpha: float, p_specular: float, coat_normal: wp.vec3, coat_alpha: float,
                           p_coat: float, seed: int, out: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float)):
    i = wp.tid()
    key = sample_key(seed, i, 0)
    n = wp.vec3(0.0, 0.0, 1.0)
    l = sample_coated_direction(n, v, alpha, p_specular, coat_normal, coat_alpha, p_coat, uniform(key, 0),
                                wp.vec2(uniform(key, 1), uniform(key, 2)))
    out[i] = l
    pdf[i] = pdf_coated_direction(n, v, l, alpha, p_specular, coat_normal, coat_alpha, p_coat)


@wp.kernel(enable_backward=False)
def evaluate_coated_pdf(v: wp.vec3, alpha: float, p_specular: float, coat_normal: wp.vec3, coat_alpha: float,
                        p_coat: float, directions: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float)):
    i = wp.tid()
    pdf[i] = pdf_coated_direction(wp.vec3(0.0, 0.0, 1.0), v, directions[i], alpha, p_specular, coat_normal,
                                  coat_alpha, p_coat)


def in_frame_of(x, normal):
    """Directions ``x`` (..., 3) in an orthonormal frame whose z axis is ``normal`` (the lobes are
    isotropic about their normal, so any such frame does)."""
    t = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    return np.stack([x @ t, x @ np.cross(normal, t), x @ normal], -1)


def coated_pdf(l, v, alpha, p_specular, coat_normal, coat_alpha, p_coat):
    """p_coat times the coat's GGX visible-normal reflection pdf about its own normal, plus
    (1 - p_coat) times the base mixture about +z, float64."""
    coat = mixture_pdf(in_frame_of(l, coat_normal), in_frame_of(v, coat_normal), coat_alpha, 1.0)
    return (1 - p_coat) * mixture_pdf(l, v, alpha, p_specular) + p_coat * coat


# theta_v, base roughness, P_s, coat roughness, coat weight, coat normal's tilt from n (radians)
COATED_CASES = [(0.3, 0.8, 0.3, 0.4, 0.5, 0.0), (0.7, 0.6, 0.5, 0.5, 0.3, 0.35), (1.1, 1.0, 0.0, 0.4, 0.8, -0.25)]


@pytest.mark.parametrize("theta_v, roughness, p_specular, coat_roughness, p_coat, tilt", COATED_CASES)
def test_coated_lobe_mixture_samples_follow_their_pdf_which_integrates_to_one(theta_v, roughness, p_specular,
                                                                               coat_roughness, p_coat, tilt):
    """The path tracer's three-lobe sampler of a clear-coated surface (the coat's lobe about a
    coat normal tilted from the base's, then the base's two), as the two-lobe test above."""
    v = np.array([math.sin(theta_v), 0.0, math.cos(theta_v)])
    coat_normal = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    alpha, coat_alpha = roughness**2, coat_roughness**2
    lobes = (alpha, p_specular, wp.vec3(*coat_normal), coat_alpha, p_coat)
    count = 200_000
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    pdf = wp.zeros(count, dtype=float, device="cpu")
    wp.launch(draw_coated_directions, dim=count, device="cpu", inputs=[wp.vec3(*v), *lobes, 23, out, pdf])
    l = out.numpy().astype(np.float64)
    expected_pdf = coated_pdf(l, v, alpha, p_specular, coat_normal, coat_alpha, p_coat)
    np.testing.assert_allclose(pdf.numpy(), expected_pdf, rtol=3e-3, atol=1e-6)
    grid, cell = sphere_grid(600)
    density = wp.zeros(grid.shape[0] * grid.shape[1], dtype=float, device="cpu")
    wp.launch(evaluate_coated_pdf, dim=density.shape[0], device="cpu",
              inputs=[wp.vec3(*v), *lobes, wp.array(grid.reshape(-1, 3), dtype=wp.vec3, device="cpu"), density])
    assert abs(density.numpy().astype(np.float64).sum() * cell - 1.0) < 3e-3
    fine, cell = sphere_grid(900)
    expected = coated_pdf(fine, v, alpha, p_specular, coat_normal, coat_alpha, p_coat)
    expected = expected.reshape(12, 150, 12, 150).sum((1, 3)) * cell
    counts = np.histogram2d(l[:, 2], np.arctan2(l[:, 1], l[:, 0]), bins=12, range=[[-1, 1], [-np.pi, np.pi]])[0]
    ok, stat, quantile = chi_square_ok(counts.ravel(), expected.ravel() * count)
    assert ok, (stat, quantile)


@wp.kernel(enable_backward=False)
def pdfs_at(normals: wp.array(dtype=wp.vec3), views: wp.array(dtype=wp.vec3), lights: wp.array(dtype=wp.vec3),
            alpha: float, p_specular: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = pdf_brdf_direction(normals[i], views[i], lights[i], alpha, p_specular)


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_lobe_mixture_pdf_depends_on_the_directions_relative_to_the_normal_alone():
    rng = np.random.default_rng(5)
    n, v, l = (unit(rng.normal(size=(2000, 3))) for _ in range(3))
    v = np.where((v * n).sum(1, keepdims=True) < 0.05, -v, v)  # views above the surface
    keep = (v * n).sum(1) > 0.05
    n, v, l = n[keep], v[keep], l[keep]
    out = wp.zeros(len(n), dtype=float, device="cpu")
    alpha, p = 0.3, 0.6
    wp.launch(pdfs_at, dim=len(n), device="cpu", inputs=[wp.array(n, dtype=wp.vec3), wp.array(v, dtype=wp.vec3),
                                                          wp.array(l, dtype=wp.vec3), alpha, p, out])
    # the float64 formula in world space: cosines with n, the half vector's cosine
    h = unit(v + l)
    n_h, n_v, n_l = (h * n).sum(1), (v * n).sum(1), (l * n).sum(1)
    a2 = alpha**2
    d = np.where((n_h > 0) & ((v * h).sum(1) > 0), a2 / (np.pi * (n_h**2 * (a2 - 1) + 1) ** 2), 0.0)
    g1 = 2 * n_v / (n_v + np.sqrt(a2 + (1 - a2) * n_v**2))
    expected = (1 - p) * np.maximum(n_l, 0) / np.pi + p * g1 * d / (4 * n_v)
    np.testing.assert_allclose(out.numpy(), expected, rtol=3e-3, atol=1e-5)


def test_directions_and_pdfs_stay_finite_at_roughness_zero_grazing_and_behind_the_shading_normal():
    n = wp.vec3(0.0, 0.0, 1.0)
    count = 20_000
    for v in ((0.0, 0.0, 1.0), (1.0, 0.0, 1e-7), (0.6, 0.0, -0.8), (1.0, 0.0, 0.0)):
        v = unit(np.array(v))
        for alpha in (0.0, 1e-4, 1.0):
            out = wp.zeros(count, dtype=wp.vec3, device="cpu")
            pdf = wp.zeros(count, dtype=float, device="cpu")
            wp.launch(draw_directions, dim=count, device="cpu", inputs=[n, wp.vec3(*v), alpha, 0.5, 3, out, pdf])
            assert np.all(np.isfinite(out.numpy())) and np.all(np.isfinite(pdf.numpy())), (v, alpha)
            assert np.all(pdf.numpy() >= 0.0)
            np.testing.assert_allclose(np.linalg.norm(out.numpy(), axis=1), 1.0, atol=1e-4)


@wp.kernel(enable_backward=False)
def lobe_probabilities(base: wp.array(dtype=wp.vec3), metallic: wp.array(dtype=float), n_dot_v: float,
                       out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = specular_lobe_probability(base[i], metallic[i], 1.0, wp.vec3(0.04), n_dot_v)


def test_lobe_probability_is_the_specular_share_of_the_estimated_albedo():
    base = np.array([[0.8, 0.8, 0.8], [0.8, 0.8, 0.8], [0.0, 0.0, 0.0], [0.5, 0.2, 0.1]])
    metallic = np.array([0.0, 1.0, 0.0, 0.5])
    out = wp.zeros(4, dtype=float, device="cpu")
    wp.launch(lobe_probabilities, dim=4, device="cpu",
              inputs=[wp.array(base, dtype=wp.vec3), wp.array(metallic, dtype=float), 1.0, out])
    f0 = 0.04 * (1 - metallic[:, None]) + base * metallic[:, None]  # Schlick at normal incidence: f0
    spec = f0.max(1)
    diffuse = (1 - metallic) * base.max(1) * (1 - 0.04)
    np.testing.assert_allclose(out.numpy(), spec / (spec + diffuse), rtol=1e-5)


@wp.kernel(enable_backward=False)
def weights(a: wp.array(dtype=float), b: wp.array(dtype=float), out: wp.array(dtype=wp.vec2)):
    i = wp.tid()
    out[i] = wp.vec2(power_heuristic(a[i], b[i]), power_heuristic(b[i], a[i]))


def test_power_heuristic_weights_sum_to_one_and_match_the_formula():
    rng = np.random.default_rng(2)
    a = np.concatenate([10 ** rng.uniform(-20, 20, 1000), [0.0, 1.0, 1e30, 1e-30, 3e38]])
    b = np.concatenate([10 ** rng.uniform(-20, 20, 1000), [1.0, 0.0, 1e-30, 1e30, 1.0]])
    out = wp.zeros(len(a), dtype=wp.vec2, device="cpu")
    wp.launch(weights, dim=len(a), device="cpu", inputs=[wp.array(a, dtype=float), wp.array(b, dtype=float), out])
    w = out.numpy().astype(np.float64)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-6)
    a32, b32 = a.astype(np.float32).astype(np.float64), b.astype(np.float32).astype(np.float64)
    ratio = np.minimum(a32, b32) / np.maximum(a32, b32)
    expected = np.where(a32 >= b32, 1 / (1 + ratio**2), ratio**2 / (1 + ratio**2))
    np.testing.assert_allclose(w[:, 0], expected, atol=1e-6)


# ---------------------------------------------------------------------------- lights
@wp.kernel(enable_backward=False)
def choose(table: LightTable, seed: int, out: wp.array(dtype=int)):
    i = wp.tid()
    out[i] = choose_light(table, uniform(sample_key(seed, i, 0), 0))


def table_of(weights):
    pmf = np.asarray(weights, dtype=np.float64) / np.sum(weights)
    cdf = np.cumsum(pmf)
    cdf[-1] = 1.0
    table = LightTable()
    table.cdf = wp.array(cdf.astype(np.float32), dtype=float, device="cpu")
    table.pmf = wp.array(pmf.astype(np.float32), dtype=float, device="cpu")
    table.face = wp.zeros(1, dtype=wp.int32, device="cpu")
    table.face_pmf = wp.zeros(1, dtype=float, device="cpu")
    table.count, table.area = len(pmf), len(pmf)
    return table, pmf


def test_light_choice_follows_the_table_and_never_picks_a_light_of_probability_zero():
    weights = [5.0, 0.0, 1.0, 0.0, 30.0, 2.5, 0.0, 0.5, 11.0, 0.0]
    table, pmf = table_of(weights)
    count = 300_000
    out = wp.zeros(count, dtype=int, device="cpu")
    wp.launch(choose, dim=count, device="cpu", inputs=[table, 9, out])
    chosen = np.bincount(out.numpy(), minlength=len(weights))
    assert len(chosen) == len(weights)
    assert np.all(chosen[pmf == 0] == 0)
    ok, stat, quantile = chi_square_ok(chosen[pmf > 0].astype(np.float64), pmf[pmf > 0] * count)
    assert ok, (stat, quantile)


@wp.kernel(enable_backward=False)
def triangle_points(seed: int, p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, shading: wp.vec3, out: wp.array(dtype=wp.vec3),
                    barycentrics: wp.array(dtype=wp.vec2), pdf: wp.array(dtype=float)):
    i = wp.tid()
    key = sample_key(seed, i, 0)
    b = sample_triangle(wp.vec2(uniform(key, 0), uniform(key, 1)))
    q = p0 * b[0] + p1 * b[1] + p2 * (1.0 - b[0] - b[1])
    barycentrics[i] = b
    to = q - shading
    d = wp.normalize(to)
    out[i] = d
    ng = wp.normalize(wp.cross(p1 - p0, p2 - p0))
    area = 0.5 * wp.length(wp.cross(p1 - p0, p2 - p0))
    pdf[i] = area_to_solid_angle(1.0 / area, wp.dot(to, to), wp.dot(ng, -d))


def test_triangle_points_are_uniform_in_area():
    count = 200_000
    out, bary, pdf = (wp.zeros(count, dtype=t, device="cpu") for t in (wp.vec3, wp.vec2, float))
    corners = [wp.vec3(0.0, 0.0, 0.0), wp.vec3(2.0, 0.0, 0.0), wp.vec3(0.3, 1.5, 0.0)]
    wp.launch(triangle_points, dim=count, device="cpu", inputs=[1, *corners, wp.vec3(0.0, 0.0, 1.0), out, bary, pdf])
    b = bary.numpy().astype(np.float64)
    b = np.column_stack([b, 1 - b.sum(1)])
    assert np.all(b >= -1e-6)
    # the 8^2 congruent sub-triangles of an 8-fold subdivision are equally likely
    k = 8
    cell = np.floor(np.clip(b, 0, 1 - 1e-9) * k).astype(int)
    upward = cell.sum(1) == k - 1
    index = (cell[:, 0] * k + cell[:, 1]) * 2 + upward
    counts = np.bincount(index, minlength=2 * k * k).astype(np.float64)
    used = np.zeros(2 * k * k, bool)
    for i in range(k):
        for j in range(k - i):
            used[(i * k + j) * 2 + 1] = True  # upward: i + j + l = k - 1
            if i + j <= k - 2:
                used[(i * k + j) * 2] = True  # downward: i + j + l = k - 2
    assert used.sum() == k * k and counts[~used].sum() <= 5  # (rounding on a sub-triangle's edge)
    ok, stat, quantile = chi_square_ok(counts[used], np.full(k * k, count / (k * k)))
    assert ok, (stat, quantile)


def test_emitter_directions_follow_their_solid_angle_pdf():
    """Directions towards uniform points of a triangle, binned on the sphere around the shading
    point, against the solid-angle pdf d^2 / (A |cos theta_light|) integrated over the bins by a
    float64 ray-triangle test; and that pdf integrates to 1 over the directions."""
    count = 200_000
    p = np.array([[0.5, -0.4, 1.0], [1.8, -0.2, 1.3], [1.1, 0.9, 0.7]])
    shading = np.zeros(3)
    out, bary, pdf = (wp.zeros(count, dtype=t, device="cpu") for t in (wp.vec3, wp.vec2, float))
    wp.launch(triangle_points, dim=count, device="cpu",
              inputs=[5, *(wp.vec3(*c) for c in p), wp.vec3(*shading), out, bary, pdf])
    d = out.numpy().astype(np.float64)
    e1, e2 = p[1] - p[0], p[2] - p[0]
    normal = np.cross(e1, e2)
    area = 0.5 * np.linalg.norm(normal)
    normal /= 2 * area
    # the kernel's pdf at its samples is the formula's
    q = shading + d * (((p[0] - shading) @ normal) / (d @ normal))[:, None]
    np.testing.assert_allclose(pdf.numpy(), ((q - shading) ** 2).sum(1) / (area * np.abs(d @ normal)), rtol=1e-3)
    # a (cos theta, phi) grid over the directions the triangle covers (its edges bound them)
    s = np.linspace(0, 1, 1000)[:, None]
    edges = unit(np.concatenate([p[0] + s * e1, p[0] + s * e2, p[1] + s * (p[2] - p[1])]) - shading)
    margin = 1e-3
    mu_range = [edges[:, 2].min() - margin, edges[:, 2].max() + margin]
    phi_edges = np.arctan2(edges[:, 1], edges[:, 0])
    phi_range = [phi_edges.min() - margin, phi_edges.max() + margin]
    steps = 600
    mu = mu_range[0] + (np.arange(steps) + 0.5) * (mu_range[1] - mu_range[0]) / steps
    phi = phi_range[0] + (np.arange(steps) + 0.5) * (phi_range[1] - phi_range[0]) / steps
    m, f = np.meshgrid(mu, phi, indexing="ij")
    w = np.stack([np.sqrt(1 - m**2) * np.cos(f), np.sqrt(1 - m**2) * np.sin(f), m], -1).reshape(-1, 3)
    cell = (mu_range[1] - mu_range[0]) / steps * (phi_range[1] - phi_range[0]) / steps
    pvec = np.cross(w, e2)
    det = pvec @ e1
    tvec = shading - p[0]
    qvec = np.cross(tvec, e1)
    with np.errstate(divide="ignore", invalid="ignore"):  # Möller & Trumbore 1997
        u, v, t = (pvec @ tvec) / det, (w @ qvec) / det, np.full(len(w), qvec @ e2) / det
        inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        density = np.where(inside, t**2 / (area * np.abs(w @ normal)), 0.0)
    assert abs(density.sum() * cell - 1.0) < 5e-3
    expected = (density * cell).reshape(6, steps // 6, 6, steps // 6).sum((1, 3))
    counts = np.histogram2d(d[:, 2], np.arctan2(d[:, 1], d[:, 0]), bins=6, range=[mu_range, phi_range])[0]
    ok, stat, quantile = chi_square_ok(counts.ravel(), expected.ravel() * count)
    assert ok, (stat, quantile)


def test_face_weights_are_luminous_power_by_area():
    positions = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 3]], float)
    indices = np.array([0, 1, 2, 0, 1, 3, 0, 2, 3])
    face_primitive = np.array([0, 1, 1])
    emissive = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    w = face_weights(positions, indices, face_primitive, emissive, np.array([True, False]))
    luminance = 0.2126 * 1 + 0.7152 * 2 + 0.0722 * 3
    np.testing.assert_allclose(w, [2 * math.pi * luminance * 1.0, 0.0, 0.0])
