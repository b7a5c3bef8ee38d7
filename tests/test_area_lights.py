"""Area lights' kernels (kernels/area_lights.py): the samplers against their pdfs (chi-square),
the pdfs against float64 formulas and integrating to 1, the closed-form irradiances against
float64 references, and the lights' validation."""

import math

import numpy as np
import pytest
import warp as wp

import pbrwarp as pw
from pbrwarp.errors import InputError, InputTypeError
from pbrwarp.gpu_scene import _area_light_row
from pbrwarp.lights import SPHERE
from pbrwarp.kernels.area_lights import (AreaLightData, pdf_rect_light, pdf_sphere_light, rect_irradiance,
                                         representative_point_normalization, sample_rect_light, sample_sphere_light,
                                         sphere_irradiance)

from scenes import quad
from goodness_of_fit import chi_square_ok

wp.set_module_options({"enable_backward": False})


@wp.kernel
def draw(light: AreaLightData, p: wp.vec3, sphere: int, u: wp.array(dtype=wp.vec2),
         directions: wp.array(dtype=wp.vec3), distances: wp.array(dtype=float), pdfs: wp.array(dtype=float),
         pdfs_again: wp.array(dtype=float)):
    i = wp.tid()
    if sphere == 1:
        d, t, pdf = sample_sphere_light(light, p, u[i])
        directions[i] = d
        distances[i] = t
        pdfs[i] = pdf
        pdfs_again[i] = pdf_sphere_light(light, p, d)
    else:
        d, t, pdf = sample_rect_light(light, p, u[i])
        directions[i] = d
        distances[i] = t
        pdfs[i] = pdf
        pdfs_again[i] = pdf_rect_light(light, p, d)


@wp.kernel
def density(light: AreaLightData, p: wp.vec3, sphere: int, directions: wp.array(dtype=wp.vec3),
            out: wp.array(dtype=float)):
    i = wp.tid()
    if sphere == 1:
        out[i] = pdf_sphere_light(light, p, directions[i])
    else:
        out[i] = pdf_rect_light(light, p, directions[i])


@wp.kernel
def irradiance(light: AreaLightData, sphere: int, points: wp.array(dtype=wp.vec3), normals: wp.array(dtype=wp.vec3),
               mean: wp.array(dtype=wp.vec3), projected: wp.array(dtype=float), facing: wp.array(dtype=float)):
    i = wp.tid()
    if sphere == 1:
        m, e, f = sphere_irradiance(light, points[i], normals[i])
        mean[i] = m
        projected[i] = e
        facing[i] = f
    else:
        m, e, f = rect_irradiance(light, points[i], normals[i])
        mean[i] = m
        projected[i] = e
        facing[i] = f


@wp.kernel
def normalization(alpha: wp.array(dtype=float), radius: float, distance: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = representative_point_normalization(alpha[i], radius, distance)


def samples(light, p, n, seed=0):
    """(directions, distances, pdfs, pdfs re-evaluated at the directions) of n draws, float64."""
    u = np.random.default_rng(seed).random((n, 2)).astype(np.float32)
    out = [wp.empty(n, dtype=wp.vec3), wp.empty(n, dtype=float), wp.empty(n, dtype=float), wp.empty(n, dtype=float)]
    wp.launch(draw, dim=n, device="cpu", inputs=[_area_light_row(light), wp.vec3(*p), int(light.kind == SPHERE),
                                                  wp.array(u, dtype=wp.vec2)] + out)
    return [a.numpy().astype(np.float64) for a in out]


def pdf_at(light, p, directions):
    out = wp.empty(len(directions), dtype=float)
    wp.launch(density, dim=len(directions), device="cpu",
              inputs=[_area_light_row(light), wp.vec3(*p), int(light.kind == SPHERE),
                      wp.array(np.asarray(directions, np.float32), dtype=wp.vec3), out])
    return out.numpy().astype(np.float64)


def irradiances(light, points, normals):
    n = len(points)
    out = [wp.empty(n, dtype=wp.vec3), wp.empty(n, dtype=float), wp.empty(n, dtype=float)]
    wp.launch(irradiance, dim=n, device="cpu",
              inputs=[_area_light_row(light), int(light.kind == SPHERE), wp.array(np.asarray(points, np.float32), dtype=wp.vec3),
                      wp.array(np.asarray(normals, np.float32), dtype=wp.vec3)] + out)
    return [a.numpy().astype(np.float64) for a in out]


# lights and shading points: near and far, centred and off to the side, tilted, grazing
SPHERES = [
    (pw.SphereLight(position=(0.3, -0.2, 2.0), radius=1.2), (0.0, 0.0, 0.0)),
    (pw.SphereLight(position=(0.0, 0.0, 1.0), radius=0.99), (0.0, 0.0, 0.0)),  # from just outside
    (pw.SphereLight(position=(2.0, 1.0, 0.5), radius=0.25), (0.0, 0.0, 0.0)),
]
RECTS = [
    (pw.RectLight(position=(0.2, 0.1, 1.0), edge_u=(0.0, 1.0, 0.0), edge_v=(1.5, 0.0, 0.0)), (0.0, 0.0, 0.0)),
    (pw.RectLight(position=(0.0, 0.0, 0.3), edge_u=(0.0, 2.0, 0.0), edge_v=(2.0, 0.0, 0.0)), (0.0, 0.0, 0.0)),  # near
    # tilted, seen at a grazing angle from the side
    (pw.RectLight(position=(1.0, 0.0, 0.5), edge_u=(0.0, -1.0, 0.0), edge_v=(-0.6, 0.0, 0.8)), (0.0, 0.0, 0.0)),
    # subtending under 1e-3 sr: sampled by area
    (pw.RectLight(position=(3.0, 1.0, 4.0), edge_u=(0.0, 0.1, 0.0), edge_v=(0.1, 0.0, 0.0)), (0.0, 0.0, 0.0)),
]
CASES = [(light, p) for light, p in SPHERES + RECTS]
IDS = ["sphere", "sphere-near", "sphere-small", "rect", "rect-near", "rect-tilted", "rect-far"]


def bounding_cap(light, p):
    """(unit axis, 1 - cos of the half-angle) of a cap of directions from p holding the light,
    with a margin."""
    p = np.asarray(p, np.float64)
    c = np.asarray(light.position, np.float64)
    axis = (c - p) / np.linalg.norm(c - p)
    if isinstance(light, pw.SphereLight):
        sin2 = (light.radius / np.linalg.norm(c - p)) ** 2
        one_minus_cos = sin2 / (1.0 + math.sqrt(1.0 - sin2))
    else:
        u, v = np.asarray(light.edge_u), np.asarray(light.edge_v)
        corners = [c + a * u / 2 + b * v / 2 - p for a in (-1, 1) for b in (-1, 1)]
        one_minus_cos = max(1.0 - axis @ q / np.linalg.norm(q) for q in corners)
    return axis, min(1.2 * one_minus_cos, 2.0)


def cap_frame(axis):
    t = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    return t, np.cross(axis, t)


N_THETA, N_PHI, SUB = 24, 48, 16


def binned(directions, axis, one_minus_cos):
    """Counts of directions in N_THETA x N_PHI bins of the cap: uniform in 1 - cos(theta) about
    the axis and in phi."""
    t, b = cap_frame(axis)
    x = (1.0 - directions @ axis) / one_minus_cos
    phi = np.arctan2(directions @ b, directions @ t)
    assert np.all(x <= 1.0)
    counts, _, _ = np.histogram2d(x, phi, bins=[N_THETA, N_PHI], range=[[0, 1], [-np.pi, np.pi]])
    return counts


def expected_per_bin(light, p):
    """The pdf's integral over each bin of the light's cap: the midpoint rule on SUB x SUB
    cells per bin."""
    axis, one_minus_cos = bounding_cap(light, p)
    t, b = cap_frame(axis)
    x = (np.arange(N_THETA * SUB) + 0.5) / (N_THETA * SUB)
    phi = -np.pi + (np.arange(N_PHI * SUB) + 0.5) / (N_PHI * SUB) * 2 * np.pi
    X, P = np.meshgrid(x, phi, indexing="ij")
    cos = 1.0 - X * one_minus_cos
    sin = np.sqrt(np.maximum(1.0 - cos**2, 0.0))
    dirs = (sin[..., None] * (np.cos(P)[..., None] * t + np.sin(P)[..., None] * b) + cos[..., None] * axis)
    pdf = pdf_at(light, p, dirs.reshape(-1, 3)).reshape(N_THETA, SUB, N_PHI, SUB)
    d_omega = one_minus_cos / (N_THETA * SUB) * 2 * np.pi / (N_PHI * SUB)
    return pdf.sum(axis=(1, 3)) * d_omega


@pytest.mark.parametrize("light, p", CASES, ids=IDS)
def test_samplers_follow_their_pdfs(light, p):
    n = 100_000
    directions, distances, pdfs, pdfs_again = samples(light, p, n)
    valid = pdfs > 0.0
    assert valid.all()
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-5)
    # the density returned with a sample is the density pdf_* gives its direction (but for a
    # few directions that rounding puts just outside the light's silhouette)
    inside = pdfs_again > 0.0
    assert inside.mean() > 0.999
    np.testing.assert_allclose(pdfs_again[inside], pdfs[inside], rtol=1e-3)
    expected = expected_per_bin(light, p) * n
    ok, stat, quantile = chi_square_ok(binned(directions, *bounding_cap(light, p)).ravel(), expected.ravel())
    assert ok, (stat, quantile)


@pytest.mark.parametrize("light, p", CASES, ids=IDS)
def test_pdfs_integrate_to_one(light, p):
    assert expected_per_bin(light, p).sum() == pytest.approx(1.0, abs=3e-3)


@pytest.mark.parametrize("light, p", SPHERES, ids=IDS[:3])
def test_sphere_samples_against_the_float64_cone(light, p):
    directions, distances, pdfs, _ = samples(light, p, 20_000, seed=1)
    c, r = np.asarray(light.position), light.radius
    to_c = c - np.asarray(p)
    d = np.linalg.norm(to_c)
    cos_alpha = math.sqrt(1.0 - (r / d) ** 2)
    np.testing.assert_allclose(pdfs, 1.0 / (2.0 * math.pi * (1.0 - cos_alpha)), rtol=1e-4)
    # every direction inside the cone, and the distance reaching the near side of the sphere
    assert np.all(directions @ (to_c / d) >= cos_alpha - 1e-5)
    b = directions @ to_c
    t = b - np.sqrt(np.maximum(b**2 - (d**2 - r**2), 0.0))
    np.testing.assert_allclose(distances, t, rtol=2e-3, atol=2e-3 * r)
    points = np.asarray(p) + directions * distances[:, None]
    np.testing.assert_allclose(np.linalg.norm(points - c, axis=1), r, rtol=2e-3)


def rect_solid_angle(light, p):
    """Float64 solid angle of a rectangle seen from p: its two triangles' (Van Oosterom &
    Strackee 1983)."""
    c, u, v = (np.asarray(x, np.float64) for x in (light.position, light.edge_u, light.edge_v))
    corners = [c - u / 2 - v / 2 - p, c + u / 2 - v / 2 - p, c + u / 2 + v / 2 - p, c - u / 2 + v / 2 - p]

    def triangle(a, b, d):
        la, lb, ld = np.linalg.norm(a), np.linalg.norm(b), np.linalg.norm(d)
        return 2.0 * math.atan2(abs(a @ np.cross(b, d)), la * lb * ld + (a @ b) * ld + (a @ d) * lb + (b @ d) * la)

    return triangle(corners[0], corners[1], corners[2]) + triangle(corners[0], corners[2], corners[3])


@pytest.mark.parametrize("light, p", RECTS, ids=IDS[3:])
def test_rect_samples_against_the_float64_densities(light, p):
    directions, distances, pdfs, _ = samples(light, p, 20_000, seed=2)
    points = np.asarray(p) + directions * distances[:, None]
    local = points - np.asarray(light.position)
    for edge in (light.edge_u, light.edge_v):
        e = np.asarray(edge)
        assert np.all(np.abs(local @ e / (e @ e)) <= 0.5 + 1e-5)
    normal = np.asarray(light.normal)
    np.testing.assert_allclose(local @ normal, 0.0, atol=1e-5)
    cos_light = -(directions @ normal)
    solid_angle = rect_solid_angle(light, np.asarray(p, np.float64))
    if 1e-3 <= solid_angle <= 6.2:  # uniform in solid angle (Urena et al. 2013)
        np.testing.assert_allclose(pdfs, 1.0 / solid_angle, rtol=1e-4)
    else:  # uniform in area
        assert solid_angle < 1e-3
        np.testing.assert_allclose(pdfs, distances**2 / (light.area * cos_light), rtol=1e-4)


def test_no_light_inside_a_sphere_or_behind_a_rectangle():
    sphere = pw.SphereLight(position=(0.0, 0.0, 0.0), radius=1.0)
    rect = pw.RectLight(position=(0.0, 0.0, 0.0), edge_u=(0.0, 1.0, 0.0), edge_v=(1.0, 0.0, 0.0))  # emits along -z
    for light, points in ((sphere, [(0, 0, 0), (0.5, 0.2, 0.1), (1.0, 0.0, 0.0), (0.0, -1.0, 0.0)]),
                          (rect, [(0, 0, 1.0), (0, 0, 0), (0.3, 0.2, 0.0), (3.0, 0.0, 0.0), (0.1, 0.1, 1e-30)])):
        for p in points:
            directions, distances, pdfs, pdfs_again = samples(light, p, 64)
            assert np.all(pdfs == 0.0) and np.all(pdfs_again == 0.0), (light, p)
            assert np.all(np.isfinite(directions)) and np.all(np.isfinite(distances))
            assert np.all(pdf_at(light, p, [(0, 0, 1), (0, 0, -1), (1, 0, 0)]) == 0.0)
            mean, projected, facing = irradiances(light, [p], [(0.0, 0.0, 1.0)])
            assert np.isfinite(mean).all() and projected[0] == 0.0 and facing[0] == 0.0


def test_tiny_and_far_lights_give_finite_values():
    cases = [(pw.SphereLight(position=(0.0, 0.0, 1e30), radius=1e-18), (0.0, 0.0, 0.0)),
             (pw.SphereLight(position=(0.0, 0.0, 3e38), radius=1e18), (0.0, 0.0, -3e38)),
             (pw.RectLight(position=(0.0, 0.0, 1e30), edge_u=(0.0, 1e-18, 0.0), edge_v=(1e-18, 0.0, 0.0)), (0, 0, 0)),
             (pw.SphereLight(position=(0.0, 0.0, 1.0 + 1e-7), radius=1.0), (0.0, 0.0, 0.0))]
    for light, p in cases:
        directions, distances, pdfs, _ = samples(light, p, 256)
        for a in (directions, distances, pdfs):
            assert np.all(np.isfinite(a)), light
        assert np.all(pdfs >= 0.0)
        _, projected, facing = irradiances(light, [p], [(0.0, 0.0, 1.0)])
        assert np.isfinite(projected).all() and np.isfinite(facing).all()


def _sphere_cases(rng, n):
    """Shading points with normals under spheres wholly above their horizon."""
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    axis = rng.normal(size=(n, 3))
    axis -= np.sum(axis * normals, 1, keepdims=True) * normals
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    # the centre at elevation beta above the horizon, distance d, radius r < d sin(beta)
    beta = rng.uniform(0.2, np.pi / 2, n)
    d = rng.uniform(1.0, 5.0, n)
    r = d * np.sin(beta) * rng.uniform(0.05, 0.95, n)
    to_c = (np.cos(beta)[:, None] * axis + np.sin(beta)[:, None] * normals) * d[:, None]
    return normals, to_c, r, d, beta


def test_sphere_irradiance_is_pi_sin2_cos_above_the_horizon():
    rng = np.random.default_rng(3)
    normals, to_c, r, d, beta = _sphere_cases(rng, 200)
    for i in range(0, 200, 20):
        light = pw.SphereLight(position=tuple(to_c[i] + 1.0), radius=float(r[i]))
        mean, projected, facing = irradiances(light, [(1.0, 1.0, 1.0)], [normals[i]])
        sin2 = (r[i] / d[i]) ** 2
        assert projected[0] == pytest.approx(math.pi * sin2 * math.sin(beta[i]), rel=1e-4)
        assert facing[0] == pytest.approx(math.pi * sin2, rel=1e-4)
        np.testing.assert_allclose(mean[0], to_c[i] / d[i], atol=1e-5)


def parallel_rect_form_factor(x0, x1, y0, y1, h, px, py):
    """Float64 form factor from a point (px, py, 0) facing +z to the rectangle [x0, x1] x [y0, y1]
    at height h parallel to it: the corner formula of a differential area under a corner of a
    parallel rectangle (Howell's catalogue, B-3), superposed with signs."""
    def corner(a, b):
        A, B = abs(a) / h, abs(b) / h
        f = (A / math.sqrt(1 + A * A) * math.atan(B / math.sqrt(1 + A * A))
             + B / math.sqrt(1 + B * B) * math.atan(A / math.sqrt(1 + B * B))) / (2 * math.pi)
        return math.copysign(1.0, a) * math.copysign(1.0, b) * f

    X0, X1, Y0, Y1 = x0 - px, x1 - px, y0 - py, y1 - py
    return corner(X1, Y1) - corner(X0, Y1) - corner(X1, Y0) + corner(X0, Y0)


def brute_force_projected_solid_angle(light, p, n, m=600):
    """Float64 projected solid angle of a rectangle light over the surface (p, n): the midpoint
    rule over m x m cells of cos(theta)+ cos(theta_l)+ / r^2 dA."""
    s = (np.arange(m) + 0.5) / m - 0.5
    S, T = np.meshgrid(s, s, indexing="ij")
    q = (np.asarray(light.position) + S[..., None] * np.asarray(light.edge_u)
         + T[..., None] * np.asarray(light.edge_v)).reshape(-1, 3)
    v = q - np.asarray(p)
    r2 = np.sum(v * v, 1)
    w = v / np.sqrt(r2)[:, None]
    cos_p = np.maximum(w @ np.asarray(n), 0.0)
    cos_l = np.maximum(-(w @ np.asarray(light.normal)), 0.0)
    return float(np.sum(cos_p * cos_l / r2) * light.area / m**2)


def brute_force_sphere_projected_solid_angle(n, w, sin_alpha, m=800):
    """Float64 projected solid angle of the cone (axis w, half-angle alpha) over the surface with
    normal n: the midpoint rule in (theta, phi) of max(n.omega, 0) sin(theta)."""
    alpha = math.asin(sin_alpha)
    theta = (np.arange(m) + 0.5) / m * alpha
    phi = (np.arange(2 * m) + 0.5) / (2 * m) * 2 * np.pi
    T, P = np.meshgrid(theta, phi, indexing="ij")
    t = np.cross(w, [1.0, 0.0, 0.0] if abs(w[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(w, t)
    omega = (np.sin(T)[..., None] * (np.cos(P)[..., None] * t + np.sin(P)[..., None] * b)
             + np.cos(T)[..., None] * np.asarray(w))
    cosine = np.maximum(omega @ np.asarray(n), 0.0)
    return float(np.sum(cosine * np.sin(T)) * (alpha / m) * (2 * np.pi / (2 * m)))


@pytest.mark.parametrize("elevation", [-0.5, -0.2, 0.0, 0.1, 0.3, 0.6])
@pytest.mark.parametrize("sin_alpha", [0.1, 0.6, 0.95])
def test_sphere_irradiance_across_the_horizon_is_snyders(elevation, sin_alpha):
    # the centre at an elevation (radians) over the horizon of a surface facing +z, 2 away
    w = np.array([math.cos(elevation), 0.0, math.sin(elevation)])
    light = pw.SphereLight(position=tuple(2.0 * w), radius=2.0 * sin_alpha)
    _, projected, facing = irradiances(light, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 1.0)])
    expected = brute_force_sphere_projected_solid_angle((0.0, 0.0, 1.0), w, sin_alpha)
    assert projected[0] == pytest.approx(expected, rel=2e-3, abs=1e-5)
    assert facing[0] == pytest.approx(math.pi * sin_alpha**2, rel=1e-5)


def test_rect_irradiance_is_lamberts_polygon_formula():
    # parallel to the surface, points under it and beside it
    light = pw.RectLight(position=(0.25, -0.1, 0.8), edge_u=(0.0, 1.2, 0.0), edge_v=(2.0, 0.0, 0.0))
    xs = np.linspace(-2.5, 2.5, 11)
    points = np.array([(x, y, 0.0) for x in xs for y in xs])
    _, projected, _ = irradiances(light, points, np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    expected = [math.pi * parallel_rect_form_factor(-0.75, 1.25, -0.7, 0.5, 0.8, x, y) for x, y, _ in points]
    np.testing.assert_allclose(projected, expected, rtol=1e-4, atol=1e-7)


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.6, 0.0, 0.8), (1.0, 0.0, 0.0), (0.0, 0.8, -0.6)])
def test_rect_irradiance_is_clipped_to_the_horizon(normal):
    # a tilted rectangle that some of these surfaces see only in part above their horizon
    light = pw.RectLight(position=(0.3, 0.2, 0.7), edge_u=(0.0, -1.4, 0.0), edge_v=(-0.8, 0.0, 0.6))
    points = [(0.0, 0.0, 0.0), (-0.5, 0.4, 0.1), (0.9, -0.3, 0.0)]
    _, projected, facing = irradiances(light, points, [normal] * len(points))
    expected = [brute_force_projected_solid_angle(light, p, normal) for p in points]
    np.testing.assert_allclose(projected, expected, rtol=2e-3, atol=1e-5)
    assert np.all(facing >= projected - 1e-6)


def test_representative_point_normalization_is_karis_eq_14():
    alpha = np.array([1e-3, 0.01, 0.1, 0.5, 1.0], np.float32)
    out = wp.empty(len(alpha), dtype=float)
    wp.launch(normalization, dim=len(alpha), device="cpu", inputs=[wp.array(alpha, dtype=float), 0.2, 2.0, out])
    a = alpha.astype(np.float64)
    np.testing.assert_allclose(out.numpy(), (a / np.minimum(a + 0.2 / 4.0, 1.0)) ** 2, rtol=1e-5)


# ---------------------------------------------------------------------------------- validation


@pytest.mark.parametrize("make, message", [
    (lambda: pw.SphereLight(radius=0.0), "zero-size"),
    (lambda: pw.SphereLight(radius=-1.0), "must lie in"),
    (lambda: pw.SphereLight(radius=math.nan), "finite"),
    (lambda: pw.SphereLight(radius=1e30), "must lie in"),
    (lambda: pw.SphereLight(intensity=-1.0), ">= 0"),
    (lambda: pw.SphereLight(position=(0.0, math.inf, 0.0)), "finite"),
    (lambda: pw.RectLight(edge_u=(0.0, 0.0, 0.0)), "zero-size"),
    (lambda: pw.RectLight(edge_u=(1.0, 0.0, 0.0), edge_v=(1.0, 1.0, 0.0)), "perpendicular"),
    (lambda: pw.RectLight(edge_u=(1.0, 0.0, 0.0), edge_v=(2.0, 0.0, 0.0)), "perpendicular"),
    (lambda: pw.RectLight(edge_v=(0.0, 0.0, math.nan)), "finite"),
    (lambda: pw.RectLight(color=(1.0, -1.0, 0.0)), "non-negative"),
    (lambda: pw.AreaLighting(method="ltc"), "representative_point"),
    (lambda: pw.AreaLighting(method="monte_carlo", samples=0), "> 0"),
])
def test_bad_area_lights_are_refused_with_their_field(make, message):
    with pytest.raises(InputError, match=message):
        make()


def test_assignments_are_checked_and_undone():
    light = pw.RectLight()
    with pytest.raises(InputError):
        light.edge_v = (1.0, 0.0, 0.0)  # parallel to edge_u
    assert light.edge_v == (0.0, 0.0, 1.0)
    sphere = pw.SphereLight()
    with pytest.raises(InputError):
        sphere.radius = 0.0
    assert sphere.radius == 0.1
    scene = pw.Scene()
    scene.add_mesh(quad())
    with pytest.raises(InputTypeError, match="AreaLighting"):
        pw.explain(scene, area_lighting="monte_carlo")


def test_power_and_normal():
    sphere = pw.SphereLight(radius=0.5, intensity=3.0)
    assert sphere.power == pytest.approx(math.pi * 3.0 * 4.0 * math.pi * 0.25)
    rect = pw.RectLight(edge_u=(2.0, 0.0, 0.0), edge_v=(0.0, 0.0, 0.5), intensity=2.0)
    assert rect.area == pytest.approx(1.0)
    assert rect.power == pytest.approx(2.0 * math.pi)
    np.testing.assert_allclose(rect.normal, (0.0, -1.0, 0.0))


def test_scene_takes_area_lights_apart_from_punctual_ones():
    scene = pw.Scene()
    point = scene.add_light(pw.PointLight())
    sphere = scene.add_light(pw.SphereLight())
    rect = scene.add_light(pw.RectLight())
    assert scene.lights == [point, sphere, rect]
    assert scene.punctual_lights == [point]
    assert scene.area_lights == [sphere, rect]
    with pytest.raises(InputTypeError, match="SphereLight"):
        scene.add_light("sphere")


def test_cli_light_specs():
    import argparse

    from pbrwarp.cli import parse_light

    sphere = parse_light("sphere:0,3,0:0.25:800:1,0.5,0.5")
    assert isinstance(sphere, pw.SphereLight)
    assert (sphere.position, sphere.radius, sphere.intensity, sphere.color) == ((0, 3, 0), 0.25, 800, (1, 0.5, 0.5))
    rect = parse_light("rect:0,3,0:1,0,0:0,0,1:200")
    assert isinstance(rect, pw.RectLight) and rect.normal == (0.0, -1.0, 0.0) and rect.intensity == 200
    for spec, message in (("sphere:0,3,0:0:800", "zero-size"), ("sphere:0,3,0:0.1", "expected sphere"),
                          ("rect:0,0,0:1,0,0:1,1,0:5", "perpendicular"), ("rect:0,0,0:1,0,0:0,1:5", "edge"),
                          ("disc:0,0,0:1:1", "sphere or rect")):
        with pytest.raises(argparse.ArgumentTypeError, match=message):
            parse_light(spec)
