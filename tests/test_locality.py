"""Triangles and vertices stored in locality order (pbrwarp/locality.py, kernels/locality.py):
a permutation that keeps the scene, follows the Morton curve, and brings neighbours together."""

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels import locality as lk
from pbrwarp.locality import inverse_permutation, locality_order
from pbrwarp.meshes import icosphere


@wp.kernel(enable_backward=False)
def spread(values: wp.array(dtype=wp.uint64), out: wp.array(dtype=wp.uint64)):
    i = wp.tid()
    out[i] = lk.spread_bits(values[i])


def interleaved(cells):
    """Reference Morton code of (n, 3) integer cells: bit b of axis k goes to bit 3 b + k."""
    code = np.zeros(len(cells), dtype=object)
    for b in range(lk.MORTON_BITS):
        for k in range(3):
            code += ((cells[:, k].astype(object) >> b) & 1) << (3 * b + k)
    return code


def test_spread_bits_moves_bit_i_to_bit_3i():
    values = np.random.default_rng(0).integers(0, 2**lk.MORTON_BITS, 2000).astype(np.uint64)
    values[:3] = [0, 1, 2**lk.MORTON_BITS - 1]
    out = wp.empty(len(values), dtype=wp.uint64, device="cpu")
    wp.launch(spread, dim=len(values), inputs=[wp.array(values, dtype=wp.uint64, device="cpu"), out], device="cpu")
    # the reference interleave of one axis, the others zero
    alone = np.stack([values.astype(np.int64), np.zeros(len(values), np.int64), np.zeros(len(values), np.int64)], 1)
    np.testing.assert_array_equal(out.numpy().astype(object), interleaved(alone))


def test_centroid_codes_interleave_the_quantized_centroid():
    # centroids at the centres of grid cells, so that float32 rounding (at most an eighth of a
    # cell here) cannot move one across a cell boundary; the corners straddle the centroid
    rng = np.random.default_rng(1)
    cells = rng.integers(0, 2**(lk.MORTON_BITS - 1), (500, 3))
    cells[0] = 0
    scale = float(2**lk.MORTON_BITS - 1)
    centroids = (cells + 0.5) / scale
    offsets = np.array([[1, 0, 0], [0, 1, 0], [-1, -1, 0]]) * 0.05 / scale
    positions = (centroids[:, None, :] + offsets[None]).reshape(-1, 3)
    codes = wp.empty(len(cells), dtype=wp.uint64, device="cpu")
    wp.launch(lk.centroid_morton_codes, dim=len(cells),
              inputs=[wp.array(positions, dtype=wp.vec3, device="cpu"),
                      wp.array(np.arange(len(positions), dtype=np.int32), dtype=wp.int32, device="cpu"),
                      wp.vec3(0.0, 0.0, 0.0), scale, codes], device="cpu")
    np.testing.assert_array_equal(codes.numpy().astype(object), interleaved(cells))


def shuffled_sphere(seed=2):
    mesh = icosphere(4)
    rng = np.random.default_rng(seed)
    vertex_order = rng.permutation(len(mesh.vertices))
    faces = inverse_permutation(vertex_order)[mesh.faces[rng.permutation(len(mesh.faces))]]
    return mesh.vertices[vertex_order], faces


def ordered(positions, faces):
    face_order, vertex_order = locality_order(wp.array(positions, dtype=wp.vec3, device="cpu"),
                                              wp.array(np.asarray(faces, np.int32).reshape(-1), dtype=wp.int32,
                                                       device="cpu"))
    return face_order, vertex_order, inverse_permutation(vertex_order)[faces[face_order]]


def test_the_orders_are_permutations_that_keep_every_triangle_and_its_winding():
    positions, faces = shuffled_sphere()
    unused = np.random.default_rng(3).normal(size=(7, 3))
    positions = np.concatenate([positions, unused])
    face_order, vertex_order, renumbered = ordered(positions, faces)
    np.testing.assert_array_equal(np.sort(face_order), np.arange(len(faces)))
    np.testing.assert_array_equal(np.sort(vertex_order), np.arange(len(positions)))
    np.testing.assert_array_equal(positions[vertex_order][renumbered], positions[faces[face_order]])
    # vertices numbered by first use: each corner is a vertex seen before or the next new one
    seen = np.maximum.accumulate(renumbered.reshape(-1))
    assert renumbered.reshape(-1)[0] == 0 and np.all(np.diff(seen) <= 1)
    # the unused vertices last, in their own order
    np.testing.assert_array_equal(vertex_order[-len(unused):], np.arange(len(positions) - len(unused), len(positions)))


def test_triangles_follow_the_morton_curve_and_neighbours_come_together():
    positions, faces = shuffled_sphere()
    face_order, _, renumbered = ordered(positions, faces)
    centroids = positions[faces[face_order]].mean(axis=1)
    lo = positions.min(axis=0)
    cells = np.floor((centroids - lo) * ((2**lk.MORTON_BITS - 1) / np.ptp(positions, axis=0).max())).astype(np.int64)
    codes = interleaved(np.clip(cells, 0, 2**lk.MORTON_BITS - 1))
    # sorted, up to a cell of float32 rounding where a centroid sits on a cell boundary
    assert np.mean(codes[1:] >= codes[:-1]) > 0.999
    # consecutive triangles' centroids: on the shuffled sphere a random pair, after ordering
    # mostly adjacent triangles (edge ~0.08 on the unit icosphere of 5120 triangles)
    def median_step(f):
        c = positions[f].mean(axis=1)
        return np.median(np.linalg.norm(np.diff(c, axis=0), axis=1))
    assert median_step(faces) > 1.0
    assert median_step(faces[face_order]) < 0.1
    # and the vertices they read lie close in memory
    assert np.median(np.abs(np.diff(renumbered.min(axis=1)))) <= 4


def test_an_empty_or_flat_mesh_keeps_its_order():
    points = wp.array(np.zeros((3, 3)), dtype=wp.vec3, device="cpu")
    face_order, vertex_order = locality_order(points, wp.array([0, 1, 2, 2, 1, 0], dtype=wp.int32, device="cpu"))
    np.testing.assert_array_equal(face_order, [0, 1])
    np.testing.assert_array_equal(vertex_order, [0, 1, 2])
    face_order, vertex_order = locality_order(points, wp.empty(0, dtype=wp.int32, device="cpu"))
    assert len(face_order) == 0 and len(vertex_order) == 3


def test_upload_keeps_each_triangle_with_its_primitive_and_each_vertex_with_its_attributes():
    rng = np.random.default_rng(4)
    scene = pw.Scene()
    originals = []
    for k, mesh in enumerate((trimesh.creation.icosphere(subdivisions=2), trimesh.creation.box(),
                              trimesh.creation.annulus(0.2, 0.5, 0.3))):
        mesh.apply_translation(rng.normal(size=3))
        prim = scene.add_mesh(mesh, pw.Material(base_color=(0.1 * k, 0.5, 0.5, 1.0)))
        prim.uvs = rng.random((len(prim.positions), 2))
        originals.append(prim)
    data = upload(scene).data
    positions, indices = data.positions.numpy(), data.indices.numpy().reshape(-1, 3)
    face_material = data.face_material.numpy()
    normals, uvs = data.normals.numpy(), data.uvs.numpy()
    assert len(indices) == sum(len(p.faces) for p in originals)
    for k, prim in enumerate(originals):
        mine = indices[face_material == k]
        assert len(mine) == len(prim.faces)
        # the same triangles, corner for corner
        expected = prim.positions[prim.faces].astype(np.float32).reshape(len(prim.faces), -1)
        got = positions[mine].reshape(len(mine), -1)
        np.testing.assert_array_equal(got[np.lexsort(got.T)], expected[np.lexsort(expected.T)])
        # every uploaded vertex of the primitive carries that vertex's own position and normal
        # (found by its uv, random and so unique)
        by_uv = {tuple(uv): i for i, uv in enumerate(prim.uvs.astype(np.float32))}
        for v in np.unique(mine):
            i = by_uv[tuple(uvs[v])]
            np.testing.assert_array_equal(positions[v], prim.positions[i].astype(np.float32))
            np.testing.assert_allclose(normals[v], prim.normals[i] / np.linalg.norm(prim.normals[i]), atol=1e-6)


@pytest.mark.parametrize("seed", [5, 6])
def test_a_shuffled_mesh_renders_as_the_original(seed):
    mesh = icosphere(3)
    rng = np.random.default_rng(seed)
    shuffled = trimesh.Trimesh(mesh.vertices, mesh.faces[rng.permutation(len(mesh.faces))], process=False)
    images = []
    for m in (mesh, shuffled):
        scene = pw.Scene()
        scene.add_mesh(m, pw.Material(base_color=(0.8, 0.3, 0.2, 1.0), roughness=0.4))
        scene.add_light(pw.PointLight(position=(2.0, 3.0, 4.0), intensity=40.0))
        images.append(pw.render(scene, pw.Camera.frame(scene), width=64, height=64, progress=False).rgb)
    np.testing.assert_allclose(images[0], images[1], rtol=1e-5, atol=1e-6)
