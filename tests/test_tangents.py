"""Tangent generation: analytic frames on procedural meshes, handedness, degenerate input."""

import numpy as np
import pytest

from pbrwarp.errors import InputError
from pbrwarp.tangents import generate_tangents


def grid(nu, nv):
    """Faces of an (nu+1) x (nv+1) vertex grid, counter-clockwise when u runs along +x and the
    row index along +y."""
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nv + 1, nu + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def plane(nu=4, nv=3):
    """A unit plane in z = 0 facing +z, u along +x; the image's top (glTF v = 0) at +y."""
    x, y = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1))
    positions = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    normals = np.tile([0.0, 0.0, 1.0], (len(positions), 1))
    uvs = np.column_stack([x.ravel(), 1.0 - y.ravel()])
    return positions, normals, uvs, grid(nu, nv)


def uv_sphere(nu=48, nv=24):
    """A unit sphere with u = longitude / 2 pi, glTF v = polar angle / pi (v = 0 at the +y pole)
    and P = (sin t cos p, cos t, -sin t sin p), outward normals, counter-clockwise from outside."""
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1))
    phi, theta = 2 * np.pi * u.ravel(), np.pi * v.ravel()
    positions = np.column_stack([np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)])
    uvs = np.column_stack([u.ravel(), v.ravel()])
    dp_du = np.column_stack([-np.sin(phi), np.zeros_like(phi), -np.cos(phi)])
    faces = grid(nu, nv)[:, ::-1]  # rows grow downwards (+theta), so flip to face outwards
    return positions, positions.copy(), uvs, faces, dp_du


def check_frame(t, normals):
    assert t.shape == (len(normals), 4) and t.dtype == np.float64
    assert np.all(np.isfinite(t))
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(t[:, 3]), 1.0)
    n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    assert np.max(np.abs(np.sum(t[:, :3] * n, axis=1))) < 1e-9


def test_plane_tangent_is_du_direction_and_right_handed():
    p, n, uv, f = plane()
    t = generate_tangents(p, n, uv, f)
    check_frame(t, n)
    np.testing.assert_allclose(t[:, :3], np.tile([1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)
    assert np.all(t[:, 3] == 1.0)
    # glTF's bitangent cross(n, t) * w points to the top of the image (decreasing glTF v).
    b = np.cross(n, t[:, :3]) * t[:, 3:]
    np.testing.assert_allclose(b, np.tile([0.0, 1.0, 0.0], (len(p), 1)), atol=1e-12)


def test_plane_mirrored_u_gives_negative_handedness():
    p, n, uv, f = plane()
    uv[:, 0] = 1.0 - uv[:, 0]
    t = generate_tangents(p, n, uv, f)
    np.testing.assert_allclose(t[:, :3], np.tile([-1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)
    assert np.all(t[:, 3] == -1.0)
    b = np.cross(n, t[:, :3]) * t[:, 3:]  # still towards the image top
    np.testing.assert_allclose(b, np.tile([0.0, 1.0, 0.0], (len(p), 1)), atol=1e-12)


def test_plane_mirrored_v_gives_negative_handedness():
    p, n, uv, f = plane()
    uv[:, 1] = 1.0 - uv[:, 1]
    t = generate_tangents(p, n, uv, f)
    np.testing.assert_allclose(t[:, :3], np.tile([1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)
    assert np.all(t[:, 3] == -1.0)


def test_rotated_uvs_rotate_the_tangent():
    p, n, uv, f = plane()
    a = 0.7  # the texture turned by a about the plane normal
    centred = uv - 0.5
    uv = 0.5 + centred @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
    t = generate_tangents(p, n, uv, f)
    # u' = c (x - .5) + s (y - .5) + .5 (v = 1 - y), so dP/du' is (c, s) in the plane.
    np.testing.assert_allclose(t[:, :3], np.tile([np.cos(a), np.sin(a), 0.0], (len(p), 1)), atol=1e-9)
    assert np.all(t[:, 3] == 1.0)


def test_sphere_tangents_match_analytic_dp_du():
    p, n, uv, f, dp_du = uv_sphere()
    t = generate_tangents(p, n, uv, f)
    check_frame(t, n)
    away_from_poles = np.abs(p[:, 1]) < 0.99
    dots = np.sum(t[away_from_poles, :3] * dp_du[away_from_poles], axis=1)
    # Exact where faces surround the vertex symmetrically; at the UV seam only one side's chord
    # counts, which is off by half a segment (pi / 48).
    assert np.median(dots) > 1 - 1e-12
    assert dots.min() > np.cos(np.pi / 48) - 1e-9
    assert np.all(t[away_from_poles, 3] == 1.0)


def test_sphere_mirrored_uvs_flip_tangent_and_handedness():
    p, n, uv, f, dp_du = uv_sphere()
    uv[:, 0] = 1.0 - uv[:, 0]
    t = generate_tangents(p, n, uv, f)
    check_frame(t, n)
    away_from_poles = np.abs(p[:, 1]) < 0.99
    assert np.sum(t[away_from_poles, :3] * dp_du[away_from_poles], axis=1).max() < -np.cos(np.pi / 48) + 1e-9
    assert np.all(t[away_from_poles, 3] == -1.0)


def test_non_uniform_uv_scale_keeps_du_direction():
    p, n, uv, f = plane()
    uv = uv * [5.0, 0.1]
    t = generate_tangents(p, n, uv, f)
    np.testing.assert_allclose(t[:, :3], np.tile([1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)


def test_welds_identical_vertices_like_mikktspace():
    """Two triangles meeting at bit-identical (position, normal, uv) vertices get one tangent
    there, as if the vertices were shared."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [0.5, 1.5, 1.0]], float)
    n = np.tile([0.0, 0.0, 1.0], (6, 1))
    uv = np.array([[0, 1], [1, 1], [0, 0], [1, 1], [0, 0], [1, 0]], float)
    split = generate_tangents(p, n, uv, np.array([[0, 1, 2], [3, 5, 4]]))
    shared = generate_tangents(p, n, uv, np.array([[0, 1, 2], [1, 5, 2]]))
    np.testing.assert_allclose(split, shared, atol=1e-12)


def test_zero_normals_use_face_normal():
    p, n, uv, f = plane()
    tilt = np.array([[1, 0, 0], [0, np.cos(0.5), -np.sin(0.5)], [0, np.sin(0.5), np.cos(0.5)]])
    p = p @ tilt.T
    t = generate_tangents(p, np.zeros_like(n), uv, f)
    face_normal = tilt @ [0.0, 0.0, 1.0]
    check_frame(t, np.tile(face_normal, (len(p), 1)))
    np.testing.assert_allclose(t[:, :3], np.tile([1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)


@pytest.mark.parametrize("case", ["zero_uv_area", "all_uvs_equal", "tangent_parallel_to_normal",
                                  "zero_area_faces", "unreferenced_vertex", "zero_normals_degenerate"])
def test_degenerate_input_gives_finite_unit_perpendicular_tangents(case):
    p, n, uv, f = plane(2, 2)
    if case == "zero_uv_area":
        uv[:, 1] = 0.3  # every triangle is a line in UV space
    elif case == "all_uvs_equal":
        uv[:] = 0.5
    elif case == "tangent_parallel_to_normal":
        n = np.tile([1.0, 0.0, 0.0], (len(p), 1))  # normals along dP/du
    elif case == "zero_area_faces":
        p[:] = p[0]
    elif case == "unreferenced_vertex":
        p, n, uv = np.vstack([p, [[5, 5, 5]]]), np.vstack([n, [[0, 1, 0]]]), np.vstack([uv, [[0, 0]]])
    elif case == "zero_normals_degenerate":
        p[:] = p[0]
        n[:] = 0.0
    t = generate_tangents(p, n, uv, f)
    check_frame(t, n)


def test_random_soup_is_finite():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(60, 3))
    n = rng.normal(size=(60, 3))
    n[::7] = 0.0
    uv = rng.random((60, 2))
    uv[::5] = uv[0]
    f = rng.integers(0, 60, size=(90, 3))
    t = generate_tangents(p, n, uv, f)
    assert np.all(np.isfinite(t))
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-9)
    has_n = np.linalg.norm(n, axis=1) > 0
    unit_n = n[has_n] / np.linalg.norm(n[has_n], axis=1, keepdims=True)
    assert np.max(np.abs(np.sum(t[has_n, :3] * unit_n, axis=1))) < 1e-9


def test_bad_input_raises_input_error():
    p, n, uv, f = plane(1, 1)
    with pytest.raises(InputError, match="faces index"):
        generate_tangents(p, n, uv, f + 10)
    with pytest.raises(InputError, match="uvs"):
        generate_tangents(p, n, uv[:, :1], f)
    bad = p.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        generate_tangents(bad, n, uv, f)
    with pytest.raises(InputError, match="differ in count"):
        generate_tangents(p, n[:-1], uv, f)
