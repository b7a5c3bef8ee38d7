"""Occlusion culling of clusters (kernels/occlusion.py): the bounds it keeps hold what they
bound, each test it makes is conservative against a float64 NumPy reference, and the visibility
buffer it draws is the one drawn without it, bit for bit."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
import warp as wp
from pbrwarp.errors import InputError
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.camera import CameraData
from pbrwarp.kernels import occlusion as ok
from pbrwarp.meshes import bunny, icosphere
from pbrwarp.raster import NO_TRIANGLE, CLUSTER_SIZE, projection, triangle_clusters, visibility_buffer
from test_raster import (GLTF, camera_coordinates, camera_data, mesh_geometry, random_cameras, scene_of,
                         screen_coordinates)


def uploaded(scene):
    geometry = upload(scene)._keep[0]
    return geometry.positions, geometry.indices, geometry.clusters


def triangles_of(positions, indices):
    return positions.numpy().astype(np.float64)[indices.numpy().reshape(-1, 3)]


def test_cluster_bounds_hold_their_triangles_and_normals():
    positions, indices, clusters = uploaded(scene_of(bunny()))
    corners = triangles_of(positions, indices)
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    lower, upper = clusters.lower.numpy(), clusters.upper.numpy()
    axis, spread = clusters.axis.numpy().astype(np.float64), clusters.spread.numpy()
    assert len(clusters) == -(-len(corners) // CLUSTER_SIZE)
    for k in range(len(clusters)):
        part = slice(k * CLUSTER_SIZE, (k + 1) * CLUSTER_SIZE)
        points = corners[part].reshape(-1, 3)
        # exact: the box is made of the float32 coordinates themselves
        np.testing.assert_array_equal(lower[k], points.min(axis=0))
        np.testing.assert_array_equal(upper[k], points.max(axis=0))
        normals = n[part]
        total = normals.sum(axis=0)
        np.testing.assert_allclose(axis[k], total / np.linalg.norm(total), atol=1e-6)
        lengths = np.linalg.norm(normals, axis=1)
        cosines = (normals[lengths > 0] @ axis[k]) / lengths[lengths > 0]
        assert cosines.min() >= spread[k] - 1e-6


def test_clusters_leave_out_degenerate_triangles_and_opposed_normals():
    # a flat cluster of two triangles and a degenerate one: the cone is the plane's normal
    flat = mesh_geometry([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 2, 0]], [[0, 1, 2], [1, 3, 2], [0, 3, 4]])
    clusters = triangle_clusters(flat.positions, flat.indices)
    np.testing.assert_allclose(clusters.axis.numpy()[0], [0, 0, 1], atol=1e-7)
    assert clusters.spread.numpy()[0] == pytest.approx(1.0, abs=1e-7)
    # two faces of opposite normals fit in no cone
    folded = mesh_geometry([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 1]])
    assert triangle_clusters(folded.positions, folded.indices).spread.numpy()[0] == -1.0


@wp.kernel(enable_backward=False)
def cluster_tests(proj: ok.Projection, lower: wp.array(dtype=wp.vec3), upper: wp.array(dtype=wp.vec3),
                  axis: wp.array(dtype=wp.vec3), spread: wp.array(dtype=float), away: wp.array(dtype=int),
                  outside: wp.array(dtype=int), spp: int, rect: wp.array(dtype=wp.vec4i),
                  nearest: wp.array(dtype=wp.float64)):
    k = wp.tid()
    away[k] = int(ok.faces_away(proj, lower[k], upper[k], axis[k], spread[k]))
    outside[k] = int(ok.outside_view(proj, lower[k], upper[k]))
    r, z = ok.cluster_view(proj, lower[k], upper[k], spp)
    rect[k] = r
    nearest[k] = z


def run_cluster_tests(clusters, cam, orthographic=False, spp=1):
    count = len(clusters)
    away, outside = wp.empty(count, dtype=int), wp.empty(count, dtype=int)
    rect, nearest = wp.empty(count, dtype=wp.vec4i), wp.empty(count, dtype=wp.float64)
    wp.launch(cluster_tests, dim=count, inputs=[projection(cam, orthographic), clusters.lower, clusters.upper,
                                                clusters.axis, clusters.spread, away, outside, spp, rect, nearest])
    return away.numpy().astype(bool), outside.numpy().astype(bool), rect.numpy(), nearest.numpy()


def parallel_camera(direction, distance, half_extent, size, rng):
    """A parallel projection along ``direction`` whose plane z = 0 lies ``distance`` before the
    origin, spanning +-half_extent."""
    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    helper = np.cross(d, rng.normal(size=3))
    right = helper / np.linalg.norm(helper) * half_extent
    cam = CameraData()
    cam.eye, cam.forward = wp.vec3(*(-distance * d)), wp.vec3(*d)
    cam.right, cam.up = wp.vec3(*right), wp.vec3(*np.cross(right, d))
    cam.width = cam.height = size
    return cam


def sampled_pixels(lo, hi, spp):
    """First and last pixel with a sample the rasterizer may find in [lo, hi] (float64 screen
    coordinates of vertices, widened by their snapping to 1/4096 pixel): pixel centres for spp =
    1, anywhere in [p, p + 1] for more."""
    lo, hi = lo - 1.0 / 8192, hi + 1.0 / 8192
    if spp == 1:
        return np.ceil(lo - 0.5), np.floor(hi - 0.5)
    return np.ceil(lo - 1.0), np.floor(hi)


def test_cluster_tests_are_conservative_against_float64_geometry():
    """Over random cameras: a cluster said to face away has every triangle facing away from the
    eye; one said to lie outside the view has every vertex behind the camera or projecting beyond
    the image; one given a rectangle and nearest depth has every vertex no nearer and every
    sample its vertices' screen bounds hold in that rectangle; one given an empty rectangle
    holds no sample of the image."""
    scene = scene_of(bunny())
    positions, indices, clusters = uploaded(scene)
    corners = triangles_of(positions, indices)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    seen = {"away": 0, "outside": 0, "rect": 0, "no sample": 0}
    for i, camera in enumerate(random_cameras(scene, 12, seed=21)):
        cam = camera_data(camera, 96, 64)
        spp = 4 if i % 2 else 1
        away, outside, rect, nearest = run_cluster_tests(clusters, cam, spp=spp)
        eye = np.array(cam.eye, np.float64)
        for k in range(len(clusters)):
            part = slice(k * CLUSTER_SIZE, (k + 1) * CLUSTER_SIZE)
            points = corners[part].reshape(-1, 3)
            c = camera_coordinates(cam, points)
            if away[k]:
                seen["away"] += 1
                assert np.all(np.einsum("ij,ij->i", normals[part], corners[part, 0] - eye) > 0)
            front = c[:, 2] > 0
            x, y = screen_coordinates(cam, c[front])
            on_screen = (x >= 0) & (x <= cam.width) & (y >= 0) & (y <= cam.height)
            if outside[k]:
                seen["outside"] += 1
                assert not on_screen.any()
            r = rect[k]
            if nearest[k] > 0 or (r[0] > r[2] and front.all()):
                px0, px1 = sampled_pixels(x.min(), x.max(), spp)
                py0, py1 = sampled_pixels(y.min(), y.max(), spp)
                px0, py0 = max(px0, 0), max(py0, 0)
                px1, py1 = min(px1, cam.width - 1), min(py1, cam.height - 1)
            if nearest[k] > 0:
                seen["rect"] += 1
                assert front.all() and c[:, 2].min() > nearest[k]
                if px0 <= px1 and py0 <= py1:
                    assert r[0] <= px0 and px1 <= r[2] and r[1] <= py0 and py1 <= r[3]
            elif r[0] > r[2]:
                if front.all():
                    seen["no sample"] += 1
                    assert px0 > px1 or py0 > py1
                else:
                    assert not on_screen.any()
    assert min(seen.values()) > 0, seen


def test_parallel_projection_cluster_tests_are_conservative():
    positions, indices, clusters = uploaded(scene_of(icosphere(5)))
    corners = triangles_of(positions, indices)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    rng = np.random.default_rng(4)
    seen_away = seen_outside = 0
    for _ in range(6):
        cam = parallel_camera(rng.normal(size=3), 2.0, 0.6, 64, rng)
        away, outside, _, _ = run_cluster_tests(clusters, cam, orthographic=True)
        forward = np.array(cam.forward, np.float64)
        for k in np.nonzero(away)[0]:
            seen_away += 1
            assert np.all(normals[k * CLUSTER_SIZE:(k + 1) * CLUSTER_SIZE] @ forward > 0)
        for k in np.nonzero(outside)[0]:
            seen_outside += 1
            c = camera_coordinates(cam, corners[k * CLUSTER_SIZE:(k + 1) * CLUSTER_SIZE].reshape(-1, 3))
            x, y = screen_coordinates(cam, c, orthographic=True)
            assert not np.any((c[:, 2] > 0) & (x >= 0) & (x <= cam.width) & (y >= 0) & (y <= cam.height))
    assert seen_away > 0 and seen_outside > 0


@wp.kernel(enable_backward=False)
def occlusion_verdicts(out: wp.array2d(dtype=wp.uint64), spp: int, rects: wp.array(dtype=wp.vec4i),
                       bounds: wp.array(dtype=wp.uint64), verdicts: wp.array(dtype=int)):
    k = wp.tid()
    verdicts[k] = int(ok.is_occluded(out, rects[k], spp, bounds[k]))


@pytest.mark.parametrize("spp, width, height", [(1, 37, 21), (4, 16, 9)])
def test_occlusion_verdict_is_every_sample_below_the_bound(spp, width, height):
    """Against NumPy over random buffers, rectangles and bounds: occluded exactly where every
    entry over the rectangle's samples is below the bound (empty samples, all ones, never are),
    whatever the entries' top bits, as the kernel compares them signed with the top bit flipped."""
    rng = np.random.default_rng(spp)
    depths = rng.uniform(0.1, 100.0, size=(height, width * spp)).astype(np.float32)
    entries = (depths.view(np.uint32).astype(np.uint64) << np.uint64(32)) | rng.integers(0, 1000, depths.shape,
                                                                                           dtype=np.uint64)
    entries[rng.random(entries.shape) < 0.003] = NO_TRIANGLE
    count = 4000
    x = np.sort(rng.integers(0, width, (count, 2)), axis=1)
    y = np.sort(rng.integers(0, height, (count, 2)), axis=1)
    rects = np.stack([x[:, 0], y[:, 0], x[:, 1], y[:, 1]], axis=1).astype(np.int32)
    # bounds near each rectangle's largest entry, on either side of it, and some with the top bit set
    largest = np.array([entries[r[1]:r[3] + 1, r[0] * spp:(r[2] + 1) * spp].max() for r in rects])
    bounds = largest + rng.integers(-2, 3, count).astype(np.uint64)
    bounds[::7] = rng.integers(0, 2**63, len(bounds[::7]), dtype=np.uint64) + np.uint64(2**63)
    verdicts = wp.empty(count, dtype=int)
    wp.launch(occlusion_verdicts, dim=count, inputs=[wp.array(entries, dtype=wp.uint64), spp,
                                                      wp.array(rects, dtype=wp.vec4i),
                                                      wp.array(bounds, dtype=wp.uint64), verdicts])
    expected = largest < bounds
    np.testing.assert_array_equal(verdicts.numpy().astype(bool), expected)
    assert 0.2 < expected.mean() < 0.8


def buffers_with_and_without_clusters(positions, indices, clusters, cam, spp=1, cull=None, orthographic=False):
    counts = {}
    grid = {1: (1, 1), 4: (2, 2)}[spp]
    plain = visibility_buffer(positions, indices, cam, spp, *grid, seed=3, cull_back_faces=cull,
                              orthographic=orthographic).numpy()
    culled = visibility_buffer(positions, indices, cam, spp, *grid, seed=3, cull_back_faces=cull,
                               orthographic=orthographic, clusters=clusters, counts=counts).numpy()
    return plain, culled, counts


OCCLUDING_SCENES = {
    "icosphere": lambda: scene_of(icosphere(6)),
    "bunny": lambda: scene_of(bunny()),
    **{path.name: (lambda path=path: pw.Scene.load(path)) for path in GLTF},
}


def culled_buffers_equal_unculled(scene, cameras, width, height):
    """Asserts, camera after camera, the buffer drawn with the scene's clusters equal to the one
    drawn without, bit for bit: 4 samples per pixel for every fourth camera, 1 for the others,
    every other with back faces flagged for culling. Returns how many clusters were culled."""
    positions, indices, clusters = uploaded(scene)
    every_face = wp.array(np.ones(len(indices) // 3, np.uint8), dtype=wp.uint8)
    totals = {"off_screen": 0, "occluded": 0, "facing_away": 0}
    for i, camera in enumerate(cameras):
        plain, culled, counts = buffers_with_and_without_clusters(positions, indices, clusters,
                                                                  camera_data(camera, width, height),
                                                                  spp=4 if i % 4 == 0 else 1,
                                                                  cull=every_face if i % 2 else None)
        np.testing.assert_array_equal(culled, plain)
        for key in totals:
            totals[key] += counts[key]
    return totals


@pytest.mark.parametrize("name", OCCLUDING_SCENES)
def test_culling_clusters_leaves_the_buffer_unchanged(name):
    """Bit for bit, over random cameras (some inside the model), one and four samples per pixel,
    with and without back faces flagged for culling; and culling happened."""
    scene = OCCLUDING_SCENES[name]()
    # few samples for the triangles, so that the occlusion pass pays even for the small models
    totals = culled_buffers_equal_unculled(scene, random_cameras(scene, 20, seed=5), 112, 84)
    if name in ("icosphere", "bunny"):  # dense enough for every kind of culling
        assert min(totals.values()) > 0, totals


def test_culling_clusters_in_parallel_projection_leaves_the_buffer_unchanged():
    scene = scene_of(icosphere(6))
    positions, indices, clusters = uploaded(scene)
    rng = np.random.default_rng(9)
    occluded = 0
    for _ in range(6):
        # the plane z = 0 of the projection through the sphere, for some: the triangles behind it
        # are dropped
        cam = parallel_camera(rng.normal(size=3), rng.uniform(0.5, 3.0), rng.uniform(0.3, 1.5), 128, rng)
        plain, culled, counts = buffers_with_and_without_clusters(positions, indices, clusters, cam, orthographic=True)
        np.testing.assert_array_equal(culled, plain)
        occluded += counts["occluded"]
    assert occluded > 0


def test_closed_mesh_seen_from_outside_culls_its_far_side():
    positions, indices, clusters = uploaded(scene_of(icosphere(7)))
    cam = camera_data(pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), fov_y=50.0), 512, 512)
    plain, culled, counts = buffers_with_and_without_clusters(positions, indices, clusters, cam)
    np.testing.assert_array_equal(culled, plain)
    # about half the sphere faces away; all but its rim lies behind the near half
    assert counts["occluded"] > 0.3 * counts["clusters"], counts
    every_face = wp.array(np.ones(len(indices) // 3, np.uint8), dtype=wp.uint8)
    plain, culled, counts = buffers_with_and_without_clusters(positions, indices, clusters, cam, cull=every_face)
    np.testing.assert_array_equal(culled, plain)
    assert counts["facing_away"] > 0.3 * counts["clusters"], counts


def test_a_camera_looking_away_culls_every_cluster():
    positions, indices, clusters = uploaded(scene_of(icosphere(5)))
    cam = camera_data(pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 6.0), fov_y=50.0), 64, 64)
    counts = {}
    buffer = visibility_buffer(positions, indices, cam, clusters=clusters, counts=counts).numpy()
    assert (buffer == np.uint64(NO_TRIANGLE)).all()
    assert counts["off_screen"] == counts["clusters"] == len(clusters)


def test_thread_count_does_not_change_the_culled_buffer():
    scene = scene_of(icosphere(6))
    positions, indices, clusters = uploaded(scene)
    for camera in random_cameras(scene, 3, seed=2):
        cam = camera_data(camera, 128, 96)
        buffers = [visibility_buffer(positions, indices, cam, threads=t, clusters=clusters).numpy() for t in (1, 2, 3)]
        np.testing.assert_array_equal(buffers[1], buffers[0])
        np.testing.assert_array_equal(buffers[2], buffers[0])


def test_clusters_of_other_arrays_or_bad_indices_are_rejected():
    positions, indices, clusters = uploaded(scene_of(icosphere(2)))
    cam = camera_data(pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0)), 32, 32)
    copy = wp.array(indices.numpy(), dtype=wp.int32)
    with pytest.raises(InputError, match="triangle_clusters"):
        visibility_buffer(positions, copy, cam, clusters=clusters)
    with pytest.raises(InputError, match="triangle_clusters"):
        visibility_buffer(positions, indices, cam, clusters="clusters")
    bad = wp.array(np.array([0, 1, len(positions)], np.int32), dtype=wp.int32)
    with pytest.raises(InputError, match="out of range"):
        triangle_clusters(positions, bad)


def test_occlusion_pass_only_where_enough_clusters_face_away():
    """A height field seen from above faces the eye all over: drawn in one pass, nothing
    deferred; a closed mesh defers the half facing away."""
    n = 100
    x, z = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    y = 0.05 * np.sin(3 * x) * np.cos(2 * z)
    corner = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    faces = np.concatenate([np.stack([corner, corner + n + 1, corner + n + 2], 1),
                            np.stack([corner, corner + n + 2, corner + 1], 1)])
    field = trimesh.Trimesh(np.stack([x, y, z], -1).reshape(-1, 3), faces, process=False)
    above = pw.Camera.look_at((0.0, 3.0, 0.5), (0.0, 0.0, 0.0), fov_y=50.0)
    outside = pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    for mesh, camera, two_passes in ((field, above, False), (icosphere(6), outside, True)):
        positions, indices, clusters = uploaded(scene_of(mesh))
        counts = {}
        visibility_buffer(positions, indices, camera_data(camera, 64, 64), clusters=clusters, counts=counts)
        assert (counts["deferred"] > 0.3 * counts["clusters"]) == two_passes, counts


@pytest.mark.parametrize("scale, offset", [(1e-4, 0.0), (1e4, 0.0), (1.0, 3e3), (1e-3, 1e2)])
def test_culling_clusters_of_tiny_huge_and_far_meshes_leaves_the_buffer_unchanged(scale, offset):
    """The culling margins are relative to the coordinates' magnitudes: a sphere of radius 1e-4
    or 1e4, or one far from the origin for its size (float32 positions then a few 1e-7 of its
    radius apart), culls clusters off screen, facing away and hidden, and draws the buffer drawn
    without them, bit for bit, from random cameras outside and inside it."""
    mesh = icosphere(6)
    mesh.apply_scale(scale)
    mesh.apply_translation([offset, -0.5 * offset, 0.25 * offset])
    scene = scene_of(mesh)
    totals = culled_buffers_equal_unculled(scene, random_cameras(scene, 8, seed=17), 128, 96)
    assert min(totals.values()) > 0, totals
