"""Pixel footprints from ray differentials against float64 references and analytic cases."""

import numpy as np
import pytest
import warp as wp

from pbrwarp.kernels.footprint import tangent_plane_offset, triangle_dp_duv, uv_derivative


@wp.kernel(enable_backward=False)
def footprint_of(tri: wp.array(dtype=wp.vec3), uvs: wp.array(dtype=wp.vec2), p: wp.vec3, n: wp.vec3,
                 origin: wp.array(dtype=wp.vec3), direction: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec2)):
    i = wp.tid()
    dpdu, dpdv = triangle_dp_duv(tri[0], tri[1], tri[2], uvs[0], uvs[1], uvs[2])
    dp = tangent_plane_offset(p, n, origin[i], direction[i])
    out[i] = uv_derivative(dpdu, dpdv, dp)


def run(tri, uvs, p, n, origins, directions):
    out = wp.zeros(len(origins), dtype=wp.vec2)
    wp.launch(footprint_of, dim=len(origins), inputs=[
        wp.array(np.asarray(tri, np.float32), dtype=wp.vec3), wp.array(np.asarray(uvs, np.float32), dtype=wp.vec2),
        wp.vec3(*p), wp.vec3(*n), wp.array(np.asarray(origins, np.float32), dtype=wp.vec3),
        wp.array(np.asarray(directions, np.float32), dtype=wp.vec3), out])
    return out.numpy().astype(np.float64)


def reference(tri, uvs, p, n, origin, direction):
    """float64: dp/du, dp/dv by solving the triangle's uv map, the tangent-plane hit, then
    least squares (numpy.linalg.lstsq)."""
    tri, uvs = np.asarray(tri, float), np.asarray(uvs, float)
    duv = np.array([uvs[0] - uvs[2], uvs[1] - uvs[2]])  # rows: (du, dv) of the two edges
    dpe = np.array([tri[0] - tri[2], tri[1] - tri[2]])
    dpduv = np.linalg.solve(duv, dpe)  # rows: dp/du, dp/dv
    t = np.dot(n, np.subtract(p, origin)) / np.dot(n, direction)
    dp = np.asarray(origin) + t * np.asarray(direction) - p
    return np.linalg.lstsq(dpduv.T, dp, rcond=None)[0]


def test_matches_reference_on_random_triangles():
    rng = np.random.default_rng(11)
    for _ in range(20):
        tri = rng.normal(size=(3, 3))
        uvs = rng.uniform(-2, 2, (3, 2))
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n /= np.linalg.norm(n)
        p = tri.mean(axis=0)
        origin = p + 3 * n + rng.normal(size=3) * 0.3
        direction = p - origin + rng.normal(size=3) * 0.01
        got = run(tri, uvs, p, n, [origin], [direction])[0]
        np.testing.assert_allclose(got, reference(tri, uvs, p, n, origin, direction), rtol=2e-3, atol=1e-5)


@pytest.mark.parametrize("pixels_per_texel", [4.0, 1.0, 0.25, 1 / 16])
def test_head_on_quad_footprint_is_analytic(pixels_per_texel):
    """A quad in z = 0 with uv = (x, y) / L seen head-on from distance D: the neighbouring pixel's
    ray, at angle tan = s, meets the plane s D further, so du/dx = s D / L exactly."""
    L, D, texels = 2.0, 5.0, 64
    s = (L / texels) / pixels_per_texel / D  # one texel spans pixels_per_texel pixels
    tri = [[0, 0, 0], [L, 0, 0], [0, L, 0]]
    uvs = [[0, 0], [1, 0], [0, 1]]
    p = (0.3, 0.4, 0.0)
    origin = np.array([0.3, 0.4, D])
    got = run(tri, uvs, p, (0, 0, 1), [origin, origin], [[s, 0, -1], [0, s, -1]])
    np.testing.assert_allclose(got[0], [s * D / L, 0], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(got[1], [0, s * D / L], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(got[0, 0] * texels, 1 / pixels_per_texel, rtol=1e-5)


def test_degenerate_uvs_and_grazing_rays_stay_finite():
    tri = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    origin, ray = [0.2, 0.2, 1.0], [0.01, 0, -1]
    for uvs in ([[0.5, 0.5]] * 3, [[0, 0], [1, 1], [2, 2]], [[0, 0], [1e-30, 0], [0, 1e-30]]):
        got = run(tri, uvs, (0.2, 0.2, 0), (0, 0, 1), [origin], [ray])
        np.testing.assert_array_equal(got, [[0, 0]])
    # rays parallel to the plane or pointing away: the largest footprint, finite
    uvs = [[0, 0], [1, 0], [0, 1]]
    got = run(tri, uvs, (0.2, 0.2, 0), (0, 0, 1), [origin, origin, origin],
              [[1, 0, 0], [1, 0, 1e-20], [0, 0, 1]])
    assert np.all(np.isfinite(got)) and np.all(np.abs(got).max(axis=1) >= 1e7)
    # a degenerate (zero-area) triangle in space
    got = run([[0, 0, 0], [1, 0, 0], [2, 0, 0]], uvs, (0.5, 0, 0), (0, 0, 1), [origin], [ray])
    assert np.all(np.isfinite(got))
