"""The rasterized visibility buffer (pbrwarp/raster.py) against Warp's ray caster: same triangle
per sample but for depth ties and samples on edges, no cracks, no double coverage, clipping at
the camera plane and the guard band, the ray caster's sample positions, any thread count."""

import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
import warp as wp
from pbrwarp import parallel
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.camera import CameraData, camera_ray_direction
from pbrwarp.kernels import triangle_setup as ts
from pbrwarp.kernels.binning import triangles_to_count
from pbrwarp.kernels.coverage import covered_steps
from pbrwarp.kernels.projection import PIXEL, Projection
from pbrwarp.kernels.ray_triangle import ray_triangle_intersection
from pbrwarp.kernels.visibility_buffer import visible_triangle
from pbrwarp.kernels.robust import RAY_FAR
from pbrwarp.kernels.sampling import multi_jittered_sample
from pbrwarp.meshes import bunny, icosphere
from pbrwarp.raster import decode, projection, sample_positions, visibility_buffer
from pbrwarp.render import _camera_data, _stratification_grid

from assets import GLTF, asset_id

# A disagreement "on an edge" lies this close (pixels) to an edge of one of the two triangles:
# vertices and samples are snapped to 1/4096 pixel, and float32 rays err by ~1e-4 pixel.
EDGE_TOLERANCE_PX = 2e-3
# Relative difference of ray distances below which two hits are a depth tie.
DEPTH_TIE = 1e-5


@wp.kernel
def ray_cast(mesh: wp.uint64, cam: CameraData, spp: int, grid_m: int, grid_n: int, seed: int,
             out_face: wp.array2d(dtype=int), out_t: wp.array2d(dtype=float), out_xy: wp.array2d(dtype=wp.vec2)):
    """The ray caster's primary visibility, sample positions computed as render_tile does."""
    py, px, s = wp.tid()
    offset = wp.vec2(0.5, 0.5)
    if spp > 1:
        offset = multi_jittered_sample(s, grid_m, grid_n, seed + py * cam.width + px)
    x = float(px) + offset[0]
    y = float(py) + offset[1]
    out_xy[py, px * spp + s] = wp.vec2(x, y)
    q = wp.mesh_query_ray(mesh, cam.eye, camera_ray_direction(cam, x, y), RAY_FAR)
    out_face[py, px * spp + s] = wp.where(q.result, q.face, -1)
    out_t[py, px * spp + s] = wp.where(q.result, q.t, wp.inf)


@wp.kernel
def intersection_vs_mesh_query(mesh: wp.uint64, positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32),
                               cam: CameraData, xy: wp.array2d(dtype=wp.vec2), out: wp.array2d(dtype=wp.vec4)):
    """(t, u, v) of ray_triangle_intersection minus mesh_query_ray's for the triangle the query hit, and the hit flag."""
    py, col = wp.tid()
    d = camera_ray_direction(cam, xy[py, col][0], xy[py, col][1])
    q = wp.mesh_query_ray(mesh, cam.eye, d, RAY_FAR)
    out[py, col] = wp.vec4(0.0, 0.0, 0.0, 1.0)
    if q.result:
        f = q.face
        hit, t, u, v = ray_triangle_intersection(cam.eye, d, positions[indices[3 * f]], positions[indices[3 * f + 1]],
                                                 positions[indices[3 * f + 2]])
        out[py, col] = wp.vec4(t - q.t, u - q.u, v - q.v, wp.where(hit, 1.0, 0.0))


@wp.kernel
def parallel_ray_cast(mesh: wp.uint64, cam: CameraData, out_face: wp.array2d(dtype=int), out_t: wp.array2d(dtype=float)):
    """Rays along cam.forward (unit) from the plane through cam.eye, through pixel centres."""
    py, px = wp.tid()
    ndc_x = 2.0 * (float(px) + 0.5) / float(cam.width) - 1.0
    ndc_y = 1.0 - 2.0 * (float(py) + 0.5) / float(cam.height)
    q = wp.mesh_query_ray(mesh, cam.eye + cam.right * ndc_x + cam.up * ndc_y, cam.forward, RAY_FAR)
    out_face[py, px] = wp.where(q.result, q.face, -1)
    out_t[py, px] = wp.where(q.result, q.t, wp.inf)


@wp.kernel
def triangle_ids(buffer: wp.array2d(dtype=wp.uint64), out: wp.array2d(dtype=int)):
    row, col = wp.tid()
    out[row, col] = visible_triangle(buffer[row, col])


class Geometry:
    """A mesh's positions, indices and BVH: a scene's as the renderer uploads them, or those given."""

    def __init__(self, scene=None, positions=None, indices=None, mesh=None):
        if scene is not None:
            geometry = upload(scene)._keep[0]
            positions, indices, mesh = geometry.positions, geometry.indices, geometry.mesh
        self.positions, self.indices, self.mesh = positions, indices, mesh
        self.vertices = positions.numpy().astype(np.float64)
        self.faces = indices.numpy().reshape(-1, 3)


def mesh_geometry(vertices, faces):
    """Vertices and faces kept in the order given (upload would reorder them for locality), as
    tests name them."""
    positions = wp.array(np.asarray(vertices, np.float32), dtype=wp.vec3, device="cpu")
    indices = wp.array(np.asarray(faces, np.int32).reshape(-1), dtype=wp.int32, device="cpu")
    return Geometry(positions=positions, indices=indices, mesh=wp.Mesh(points=positions, indices=indices))


def raster(geom, cam, spp=1, seed=0, threads=None, faces=None):
    grid_m, grid_n = _stratification_grid(spp)
    indices = geom.indices if faces is None else wp.array(np.asarray(faces, np.int32).reshape(-1), dtype=wp.int32)
    return decode(visibility_buffer(geom.positions, indices, cam, spp, grid_m, grid_n, seed, threads))


def cast(geom, cam, spp=1, seed=0):
    grid_m, grid_n = _stratification_grid(spp)
    shape = (cam.height, cam.width * spp)
    face, t = wp.empty(shape, dtype=int), wp.empty(shape, dtype=float)
    xy = wp.empty(shape, dtype=wp.vec2)
    wp.launch(ray_cast, dim=(cam.height, cam.width, spp), inputs=[geom.mesh.id, cam, spp, grid_m, grid_n, seed, face, t, xy])
    return face.numpy(), t.numpy(), xy.numpy()


def camera_data(camera, width=64, height=48):
    return _camera_data(camera, width, height)


def random_cameras(scene, count, seed):
    """Cameras all around, some close to or inside the model, looking near its centre."""
    rng = np.random.default_rng(seed)
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    for _ in range(count):
        d = rng.normal(size=3)
        eye = centre + d / np.linalg.norm(d) * radius * rng.uniform(0.1, 3.0)
        target = centre + rng.normal(size=3) * radius * 0.3
        yield pw.Camera.look_at(tuple(eye), tuple(target), up=tuple(rng.normal(size=3)), fov_y=float(rng.uniform(20, 100)))


def camera_coordinates(cam, points):
    """float64 camera coordinates (a, b, z) of world points: point - eye = a right + b up + z forward."""
    axes = np.array([cam.right, cam.up, cam.forward], np.float64).T
    return (np.asarray(points, np.float64) - np.array(cam.eye, np.float64)) @ np.linalg.inv(axes).T


def screen_coordinates(cam, c, orthographic=False):
    """Pixel (x, y) of camera coordinates c, the inverse of camera_ray_direction."""
    if orthographic:
        return (c[:, 0] + 1) * cam.width / 2, (1 - c[:, 1]) * cam.height / 2
    return (c[:, 0] / c[:, 2] + 1) * cam.width / 2, (1 - c[:, 1] / c[:, 2]) * cam.height / 2


def screen_edge_distance(geom, cam, face, x, y):
    """Pixels from (x, y) to the nearest edge line of ``face``'s projection; inf when the triangle
    reaches behind the camera (then both paths cast the same ray at it)."""
    c = camera_coordinates(cam, geom.vertices[geom.faces[face]])
    if np.any(c[:, 2] <= 0):
        return math.inf
    sx, sy = screen_coordinates(cam, c)
    distances = []
    for i in range(3):
        j = (i + 1) % 3
        ex, ey = sx[j] - sx[i], sy[j] - sy[i]
        length = math.hypot(ex, ey)
        distances.append(abs(ex * (y - sy[i]) - ey * (x - sx[i])) / length if length > 0 else 0.0)
    return min(distances)


def ray_distance(geom, cam, face, x, y):
    """Distance along the sample's (float64) camera ray to ``face``'s plane."""
    d = (np.array(cam.forward, np.float64) + np.array(cam.right, np.float64) * (2 * x / cam.width - 1)
         + np.array(cam.up, np.float64) * (1 - 2 * y / cam.height))
    d /= np.linalg.norm(d)
    p0, p1, p2 = geom.vertices[geom.faces[face]]
    n = np.cross(p1 - p0, p2 - p0)
    return float(np.dot(p0 - np.array(cam.eye, np.float64), n) / np.dot(d, n))


def unexplained(geom, cam, raster_ids, cast_ids, xy):
    """Disagreeing samples that are neither a depth tie nor on an edge of either triangle."""
    bad = []
    for row, col in zip(*np.nonzero(raster_ids != cast_ids)):
        a, b = int(raster_ids[row, col]), int(cast_ids[row, col])
        x, y = (float(v) for v in xy[row, col])
        if a >= 0 and b >= 0:
            ta, tb = ray_distance(geom, cam, a, x, y), ray_distance(geom, cam, b, x, y)
            if abs(ta - tb) <= DEPTH_TIE * max(abs(ta), abs(tb)):
                continue
        if min(screen_edge_distance(geom, cam, f, x, y) for f in (a, b) if f >= 0) <= EDGE_TOLERANCE_PX:
            continue
        bad.append((row, col, a, b))
    return bad


def check_agreement(geom, cameras, spp=1, size=(64, 48)):
    samples = disagreements = 0
    for camera in cameras:
        cam = camera_data(camera, *size)
        ids, _ = raster(geom, cam, spp, seed=7)
        cast_ids, _, xy = cast(geom, cam, spp, seed=7)
        samples += ids.size
        disagreements += int((ids != cast_ids).sum())
        assert unexplained(geom, cam, ids, cast_ids, xy) == []
    assert disagreements <= 0.001 * samples, (disagreements, samples)


def scene_of(mesh):
    scene = pw.Scene()
    scene.add_mesh(mesh, pw.Material())
    return scene


SCENES = {
    "icosphere": lambda: scene_of(icosphere(4)),
    "bunny": lambda: scene_of(bunny()),
    **{asset_id(path): (lambda path=path: pw.Scene.load(path)) for path in GLTF},
}


@pytest.mark.parametrize("name", SCENES)
def test_same_triangle_as_the_ray_caster(name):
    scene = SCENES[name]()
    check_agreement(Geometry(scene), random_cameras(scene, 20, seed=len(name)))


@pytest.mark.parametrize("spp", [4, 6])
def test_supersampling_uses_the_ray_casters_sample_positions(spp):
    scene = scene_of(icosphere(3))
    geom = Geometry(scene)
    cam = camera_data(pw.Camera.frame(scene), 40, 30)
    grid_m, grid_n = _stratification_grid(spp)
    _, _, xy = cast(geom, cam, spp, seed=11)
    np.testing.assert_array_equal(sample_positions(40, 30, spp, grid_m, grid_n, 11).numpy(), xy)
    check_agreement(geom, random_cameras(scene, 20, seed=spp), spp=spp, size=(32, 24))


def test_intersection_is_bitwise_mesh_query_ray():
    """ray_triangle_intersection gives the very t, u, v mesh_query_ray reports for its hit."""
    scene = scene_of(bunny())
    geom = Geometry(scene)
    for camera in random_cameras(scene, 5, seed=1):
        cam = camera_data(camera)
        xy = sample_positions(cam.width, cam.height)
        out = wp.empty((cam.height, cam.width), dtype=wp.vec4)
        wp.launch(intersection_vs_mesh_query, dim=out.shape,
                  inputs=[geom.mesh.id, geom.positions, geom.indices, cam, xy, out])
        np.testing.assert_array_equal(out.numpy(), np.tile([0.0, 0.0, 0.0, 1.0], (*out.shape, 1)))


def test_closed_mesh_has_no_cracks():
    """Seen from inside, a closed mesh covers every sample; from outside, every sample a ray
    hits is covered (a missed sample inside the silhouette is a crack)."""
    geom = Geometry(scene_of(icosphere(5)))
    rng = np.random.default_rng(3)
    for k in range(12):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        inside = k % 2 == 0
        eye = d * (rng.uniform(0.0, 0.9) if inside else rng.uniform(1.05, 4.0))
        camera = pw.Camera.look_at(tuple(eye), tuple(rng.normal(size=3) * 0.2), up=tuple(rng.normal(size=3)), fov_y=70.0)
        cam = camera_data(camera, 128, 96)
        ids, _ = raster(geom, cam)
        cast_ids, _, xy = cast(geom, cam)
        if inside:
            assert (ids >= 0).all()
        missed = (ids < 0) & (cast_ids >= 0)
        for row, col in zip(*np.nonzero(missed)):
            assert screen_edge_distance(geom, cam, cast_ids[row, col], *xy[row, col]) <= EDGE_TOLERANCE_PX


def head_on(width=64, height=64):
    """Eye at the origin looking down -z with a 90 degree field of view: the plane z = -1 maps
    (x, y) to pixel ((x + 1) w/2, (1 - y) h/2) exactly, so vertices can sit on sample positions."""
    return camera_data(pw.Camera(eye=(0.0, 0.0, 0.0), forward=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), fov_y=90.0),
                       width, height)


def pixel_to_plane(px, py, width=64, height=64):
    return (2.0 * px / width - 1.0, 1.0 - 2.0 * py / height, -1.0)


def coverage_count(geom, cam, faces, spp=1):
    """How many of ``faces`` cover each sample, rasterizing them one at a time."""
    counts = 0
    for face in faces:
        ids, _ = raster(geom, cam, spp, faces=[face])
        counts = counts + (ids >= 0)
    return counts


@pytest.mark.parametrize("spp", [1, 4])
def test_rectangle_of_two_triangles_covers_every_sample_once(spp):
    """Corners and diagonal run through pixel centres (spp 1): every sample on the shared edge
    and at the shared corners goes to exactly one of the two triangles."""
    corners = [pixel_to_plane(x, y) for x, y in [(8.5, 6.5), (56.5, 6.5), (56.5, 54.5), (8.5, 54.5)]]
    geom = mesh_geometry(corners, [[0, 1, 2], [0, 2, 3]])
    cam = head_on()
    counts = coverage_count(geom, cam, geom.faces, spp)
    xy = sample_positions(64, 64, spp, *_stratification_grid(spp)).numpy()
    inside = (xy[..., 0] > 8.5) & (xy[..., 0] < 56.5) & (xy[..., 1] > 6.5) & (xy[..., 1] < 54.5)
    assert counts.max() == 1
    assert counts[inside].min() == 1
    ids, _ = raster(geom, cam, spp)
    np.testing.assert_array_equal(ids >= 0, counts == 1)


def test_fan_around_a_sample_covers_it_once():
    """Eight triangles meeting at a pixel centre, with edges along rows, columns and diagonals
    of pixel centres: every sample of the octagon, the centre included, is covered once."""
    centre = (32.5, 32.5)
    ring = [(centre[0] + 20 * math.cos(a), centre[1] + 20 * math.sin(a)) for a in np.arange(8) * math.pi / 4]
    ring = [(round(x), round(y)) for x, y in ring]
    ring = [(x + 0.5, y + 0.5) for x, y in ring]
    vertices = [pixel_to_plane(*centre)] + [pixel_to_plane(*p) for p in ring]
    faces = [[0, 1 + i, 1 + (i + 1) % 8] for i in range(8)]
    geom = mesh_geometry(vertices, faces)
    counts = coverage_count(geom, head_on(), faces)
    assert counts.max() == 1
    assert counts[32, 32] == 1
    ids, _ = raster(geom, head_on())
    assert (counts == (ids >= 0)).all()
    xy = sample_positions(64, 64).numpy()
    assert counts[strictly_inside_convex(xy, ring)].min() == 1


def strictly_inside_convex(xy, polygon):
    """Samples strictly inside a convex polygon given counter-clockwise on screen (y down)."""
    inside = np.ones(xy.shape[:-1], bool)
    for (x0, y0), (x1, y1) in zip(polygon, polygon[1:] + polygon[:1]):
        inside &= (x1 - x0) * (xy[..., 1] - y0) - (y1 - y0) * (xy[..., 0] - x0) > 0
    return inside


def grid_triangle_classes(n, rng):
    """The triangles of an n x n vertex grid (row-major vertex ids), each cell split along
    alternating diagonals, half of them wound backwards, grouped by (row % 3, column % 3, half):
    triangles of one class never touch, so a class can be rasterized at once and its coverage
    counts added to the others'."""
    classes = {}
    for r in range(n - 1):
        for c in range(n - 1):
            a, b, d, e = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
            halves = [[a, b, e], [a, e, d]] if (r + c) % 2 else [[a, b, d], [b, e, d]]
            for half, tri in enumerate(halves):
                classes.setdefault((r % 3, c % 3, half), []).append(tri[::-1] if rng.random() < 0.5 else tri)
    return classes


def test_tessellated_plane_filling_the_view_has_no_cracks_or_overlaps():
    """A 33 x 33 vertex grid, jittered, bent, both windings mixed, fills the view: every sample is
    covered by exactly one triangle. Triangles of cells 3 apart never touch, so each of the 18
    classes (row % 3, column % 3, half of the cell) is rasterized at once and the counts added."""
    rng = np.random.default_rng(5)
    u = np.linspace(-2.0, 2.0, 33)
    x, y = np.meshgrid(u, u)
    jitter = rng.uniform(-0.02, 0.02, size=(2, 33, 33))
    vertices = np.stack([x + jitter[0], y + jitter[1], -1.0 - 0.05 * (x * x + y * y) - 0.03 * x * y], axis=-1).reshape(-1, 3)
    classes = grid_triangle_classes(33, rng)
    faces = [tri for group in classes.values() for tri in group]
    geom = mesh_geometry(vertices, faces)
    cam = head_on(48, 48)
    counts = sum((raster(geom, cam, faces=group)[0] >= 0).astype(int) for group in classes.values())
    assert (counts == 1).all()
    assert (raster(geom, cam)[0] >= 0).all()


@pytest.mark.parametrize("spp", [1, 4])
def test_tessellated_ground_crossing_the_camera_plane_has_no_cracks_or_overlaps(spp):
    """A jittered 17 x 17 vertex ground grid, both windings mixed, spanning 1e3 around an eye 0.7
    above it: its triangles reach behind the camera or beyond the guard band, so all are
    rasterized homogeneously (at spp 1 with edge functions stepped along rows, decided directly
    near edges). Every sample is covered exactly once below the horizon, as the ray caster sees
    it; cells 3 apart never touch, so each class of cells is rasterized at once and the counts
    added."""
    rng = np.random.default_rng(11)
    u = 1e3 * np.sign(np.linspace(-1.0, 1.0, 17)) * np.linspace(-1.0, 1.0, 17) ** 2
    x, z = np.meshgrid(u, u)
    jitter = rng.uniform(-0.1, 0.1, size=(2, 17, 17)) * (1.0 + np.abs(x) + np.abs(z)) * 0.01
    vertices = np.stack([x + jitter[0], np.full_like(x, -0.7), z + jitter[1]], axis=-1).reshape(-1, 3)
    classes = grid_triangle_classes(17, rng)
    faces = [tri for group in classes.values() for tri in group]
    geom = mesh_geometry(vertices, faces)
    for forward in [(0.3, -0.4, -1.0), (-1.0, -0.1, 0.2), (0.1, -1.0, 0.05)]:
        cam = camera_data(pw.Camera(eye=(0.05, 0.0, -0.03), forward=forward, up=(0.0, 1.0, 0.0), fov_y=90.0), 96, 64)
        counts = sum((raster(geom, cam, spp=spp, faces=group)[0] >= 0).astype(int) for group in classes.values())
        cast_ids, _, _ = cast(geom, cam, spp)
        assert (counts <= 1).all()
        assert ((counts == 1) == (cast_ids >= 0)).mean() >= 0.999
        assert (counts[cast_ids >= 0] == 1).mean() >= 0.999


def test_camera_inside_a_box_sees_every_wall():
    geom = Geometry(scene_of(trimesh.creation.box(extents=(2.0, 2.0, 2.0))))
    rng = np.random.default_rng(8)
    for _ in range(8):
        eye = rng.uniform(-0.9, 0.9, size=3)
        camera = pw.Camera.look_at(tuple(eye), tuple(eye + rng.normal(size=3)), up=tuple(rng.normal(size=3)), fov_y=100.0)
        cam = camera_data(camera)
        ids, _ = raster(geom, cam)
        cast_ids, _, xy = cast(geom, cam)
        assert (ids >= 0).all()
        assert unexplained(geom, cam, ids, cast_ids, xy) == []


def test_triangles_behind_the_camera_are_dropped():
    geom = Geometry(scene_of(icosphere(3)))
    cam = camera_data(pw.Camera(eye=(0.0, 0.0, 1.5), forward=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0), fov_y=90.0))
    ids, _ = raster(geom, cam)
    assert (ids < 0).all()


@pytest.mark.parametrize("height", [0.0, 0.01, 1.0])
def test_ground_plane_crossing_the_camera_plane(height):
    """Two huge triangles pass under (height 1), just under (0.01) and through (0) the eye: they
    cross the camera plane, so each sample's ray is tested, and agree with the ray caster."""
    s = 1e4
    geom = mesh_geometry([(-s, -height, -s), (s, -height, -s), (s, -height, s), (-s, -height, s)], [[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(2)
    for _ in range(5):
        forward = (rng.normal(), rng.uniform(-0.5, 0.2), rng.normal())
        cam = camera_data(pw.Camera(eye=(0.0, 0.0, 0.0), forward=forward, up=(0.0, 1.0, 0.0), fov_y=80.0))
        ids, _ = raster(geom, cam)
        cast_ids, _, xy = cast(geom, cam)
        assert (ids >= 0).any()
        assert unexplained(geom, cam, ids, cast_ids, xy) == []


def test_triangle_crossing_the_camera_plane_beside_the_eye():
    """One vertex far in front, two behind: only the rays that really hit it see it."""
    geom = mesh_geometry([(0.3, 0.1, -5.0), (1.0, -1.0, 2.0), (-0.5, 0.8, 3.0)], [[0, 1, 2]])
    cam = head_on()
    ids, _ = raster(geom, cam)
    cast_ids, _, xy = cast(geom, cam)
    assert 0 < (ids >= 0).sum() < ids.size
    assert unexplained(geom, cam, ids, cast_ids, xy) == []


def test_triangle_beyond_the_guard_band():
    """Vertices in front of the camera but projecting millions of pixels away are ray-tested."""
    geom = mesh_geometry([(-1e4, -1e4, -0.5), (1e4, -1e3, -0.6), (0.0, 1e4, -0.7)], [[0, 1, 2]])
    cam = head_on()
    ids, _ = raster(geom, cam)
    cast_ids, _, xy = cast(geom, cam)
    assert (ids >= 0).all()
    assert unexplained(geom, cam, ids, cast_ids, xy) == []


def test_depth_is_camera_space_z():
    geom = mesh_geometry([pixel_to_plane(4, 4), pixel_to_plane(60, 4), pixel_to_plane(4, 60)], [[0, 1, 2]])
    ids, depth = raster(geom, head_on())
    np.testing.assert_allclose(depth[ids >= 0], 1.0, rtol=1e-6)
    assert np.isinf(depth[ids < 0]).all()


def test_both_facings_and_no_degenerate_coverage():
    corners = [pixel_to_plane(10, 10), pixel_to_plane(50, 12), pixel_to_plane(20, 50)]
    degenerate = [pixel_to_plane(5, 5), pixel_to_plane(30, 30), pixel_to_plane(60, 60)]
    geom = mesh_geometry(corners + degenerate + [corners[0]], [[0, 1, 2], [2, 1, 0], [3, 4, 5], [0, 6, 1], [1, 1, 1]])
    cam = head_on()
    front, back = (raster(geom, cam, faces=[f])[0] >= 0 for f in ([0, 1, 2], [2, 1, 0]))
    assert front.sum() > 500
    np.testing.assert_array_equal(front, back)
    for face in ([3, 4, 5], [0, 6, 1], [1, 1, 1]):
        assert (raster(geom, cam, faces=[face])[0] < 0).all()


def test_orthographic_view_sees_what_parallel_rays_hit():
    """Directional shadow maps: the parallel projection names the triangle a ray along the view
    direction from the view plane hits, at its distance from that plane."""
    scene = scene_of(bunny())
    geom = Geometry(scene)
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    rng = np.random.default_rng(2)
    samples = disagreements = 0
    for _ in range(10):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        helper = np.cross(d, rng.normal(size=3))
        right = helper / np.linalg.norm(helper) * radius
        up = np.cross(right, d)
        cam = CameraData()
        cam.eye, cam.forward = wp.vec3(*(centre - 2.0 * radius * d)), wp.vec3(*d)
        cam.right, cam.up = wp.vec3(*right), wp.vec3(*up)
        cam.width, cam.height = 96, 96
        ids, depth = decode(visibility_buffer(geom.positions, geom.indices, cam, orthographic=True))
        face, t = wp.empty((96, 96), dtype=int), wp.empty((96, 96), dtype=float)
        wp.launch(parallel_ray_cast, dim=(96, 96), inputs=[geom.mesh.id, cam, face, t])
        face, t = face.numpy(), t.numpy()
        assert 0.05 < (ids >= 0).mean() < 0.95
        samples += ids.size
        disagreements += int((ids != face).sum())
        same = (ids == face) & (ids >= 0)
        # depths differ by the slope times the snapping of vertices to 1/4096 pixel (here 3e-6 scene
        # radii), most on nearly edge-on triangles, and by float32 ray rounding
        error = np.abs(depth[same] - t[same]) / t[same]
        assert error.max() <= 1e-3 and np.mean(error <= 1e-4) >= 0.99
    assert disagreements <= 0.002 * samples


@pytest.mark.parametrize("spp", [1, 4])
def test_thread_count_does_not_change_the_buffer(spp):
    """Also where small triangles are drawn by several threads at once, with atomic minima."""
    scene = scene_of(bunny())
    geom = Geometry(scene)
    grid_m, grid_n = _stratification_grid(spp)
    for camera in random_cameras(scene, 3, seed=4):
        cam = camera_data(camera, 200, 150)
        reused = wp.empty((150, 200 * spp), dtype=wp.uint64)
        buffers = [visibility_buffer(geom.positions, geom.indices, cam, spp, grid_m, grid_n, 1, threads=t).numpy()
                   for t in (1, 2, 3)]
        buffers.append(visibility_buffer(geom.positions, geom.indices, cam, spp, grid_m, grid_n, 1, threads=2,
                                         out=reused).numpy())
        for other in buffers[1:]:
            np.testing.assert_array_equal(buffers[0], other)


def test_bins_too_short_for_a_frame_are_grown_and_the_frame_drawn_whole():
    """Large triangles touch many tiles: the bins kept from earlier calls (a thread's scratch) may
    be too short, and the call then resumes at filling them, drawing the very buffer it draws with
    long enough bins, the split into binning and raster (timings) changing nothing either."""
    import pbrwarp.raster as raster_module

    quad = [(1.5, 2.5), (190.5, 4.5), (180.5, 188.5), (3.5, 170.5)]
    geom = mesh_geometry([pixel_to_plane(x, y, 192, 192) for x, y in quad], [[0, 1, 2], [0, 2, 3]])
    cam = head_on(192, 192)
    for threads in (1, 2):
        raster_module._scratch.arrays.pop("bins", None)
        first = visibility_buffer(geom.positions, geom.indices, cam, threads=threads).numpy()
        # first made as long as max(triangles, tiles) = 36, grown for the triangle-tile pairs
        assert len(raster_module._scratch.arrays["bins"]) > 6 * 6
        timings = {}
        again = visibility_buffer(geom.positions, geom.indices, cam, threads=threads, timings=timings).numpy()
        np.testing.assert_array_equal(first, again)
        assert set(timings) == {"samples", "binning", "raster"} and min(timings.values()) >= 0.0
    ids, _ = decode(first)
    inside = strictly_inside_convex(sample_positions(192, 192).numpy(), quad)
    assert (ids[inside] >= 0).all() and (ids[~inside] < 0).mean() > 0.99 and inside.sum() > 30000


def test_a_launch_failing_to_start_releases_the_others(monkeypatch):
    """The launches of a call wait for each other at barriers in the kernel: one that fails
    before it starts sets the abort flag, and the others return instead of waiting forever."""
    import pbrwarp.raster as raster_module

    geom = Geometry(scene_of(icosphere(3)))
    cam = camera_data(pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0)), 64, 48)
    launch = wp.launch

    def failing_second_launch(kernel, dim, inputs, **kwargs):
        if inputs[0] == 1:
            raise RuntimeError("launch 1 failed")
        return launch(kernel, dim=dim, inputs=inputs, **kwargs)

    monkeypatch.setattr(raster_module.wp, "launch", failing_second_launch)
    with pytest.raises(RuntimeError, match="launch 1 failed"):
        visibility_buffer(geom.positions, geom.indices, cam, threads=2)
    monkeypatch.undo()
    ids, _ = decode(visibility_buffer(geom.positions, geom.indices, cam, threads=2))
    assert (ids >= 0).any()


def test_calls_from_several_python_threads_take_turns_and_agree():
    """Each call's launches wait for each other on the thread pool: calls made at once from
    several Python threads must neither deadlock (one call's launches queued behind another's)
    nor mix their work, and give each the buffer a lone call gives."""
    from concurrent.futures import ThreadPoolExecutor

    geom = Geometry(scene_of(icosphere(4)))
    cameras = [camera_data(camera, 96, 72) for camera in random_cameras(scene_of(icosphere(4)), 4, seed=9)]
    alone = [visibility_buffer(geom.positions, geom.indices, cam, threads=2).numpy().copy() for cam in cameras]

    def draw(k):
        return [visibility_buffer(geom.positions, geom.indices, cameras[(k + i) % 4], threads=2).numpy().copy()
                for i in range(6)]

    with ThreadPoolExecutor(3) as callers:
        results = list(callers.map(draw, range(3)))
    for k, buffers in enumerate(results):
        for i, buffer in enumerate(buffers):
            np.testing.assert_array_equal(buffer, alone[(k + i) % 4])


def test_a_call_does_not_depend_on_what_earlier_calls_left_in_the_threads_scratch():
    """visibility_buffer keeps its working arrays per calling thread: calls in turn on one thread,
    with meshes, image sizes, sample counts, thread counts and clusters changing from call to
    call (the arrays grow, shrink back and keep views; a call of the last call's shape reuses its
    layout), give the buffers that the same calls give each on a fresh thread, whose scratch is
    empty."""
    import threading
    from pbrwarp.raster import triangle_clusters

    small, large = Geometry(scene_of(icosphere(2))), Geometry(scene_of(icosphere(5)))
    calls = []
    for k, (geom, width, height, spp, threads, clustered) in enumerate([
            (large, 160, 120, 1, 2, True), (small, 48, 40, 4, 1, False), (large, 64, 200, 1, 3, False),
            (small, 200, 150, 1, 2, True), (large, 160, 120, 1, 2, True), (large, 160, 120, 1, 2, True),
            (small, 48, 40, 4, 2, True)]):
        camera = list(random_cameras(scene_of(icosphere(2)), 7, seed=11))[k]
        clusters = triangle_clusters(geom.positions, geom.indices) if clustered else None
        calls.append((geom, camera_data(camera, width, height), spp, threads, clusters))

    def draw(geom, cam, spp, threads, clusters):
        grid_m, grid_n = _stratification_grid(spp)
        return visibility_buffer(geom.positions, geom.indices, cam, spp, grid_m, grid_n, 3, threads,
                                 clusters=clusters).numpy().copy()

    in_turn = [draw(*call) for call in calls]
    for call, buffer in zip(calls, in_turn):
        fresh = []
        worker = threading.Thread(target=lambda call=call: fresh.append(draw(*call)))
        worker.start()
        worker.join()
        np.testing.assert_array_equal(buffer, fresh[0])


def test_back_to_back_calls_release_their_pool_launches():
    """The pool threads' launches of a call return only once its Python has released them
    (kernels/barriers.py wait_for_release), and the next call zeroes the shared slots at once: a
    pool launch that sees its release late, after the next call began, must still return, or
    the next call's launches would wait for it forever. Calls in quick succession, alternating
    thread counts and shapes (layouts sharing their scratch), must all finish, and match."""
    import faulthandler

    geom = Geometry(scene_of(icosphere(3)))
    cameras = [camera_data(camera, 48 + 16 * k, 40) for k, camera in
               enumerate(random_cameras(scene_of(icosphere(3)), 3, seed=21))]
    expected = [visibility_buffer(geom.positions, geom.indices, cam, threads=1).numpy().copy() for cam in cameras]
    faulthandler.dump_traceback_later(120, exit=True)  # a hang fails the run instead of stalling it
    try:
        for k in range(300):
            cam = k % 3
            buffer = visibility_buffer(geom.positions, geom.indices, cameras[cam], threads=(2, 3, 2, 4)[k % 4])
            np.testing.assert_array_equal(buffer.numpy(), expected[cam])
    finally:
        faulthandler.cancel_dump_traceback_later()


def test_a_replayed_call_sees_a_camera_and_positions_changed_in_place():
    """visibility_buffer replays its thread's last launch, packing again all but the arrays it
    already had: the same CameraData moved in place, the same positions array changed in place
    and the same out array give, call after call, the buffers a fresh thread draws."""
    import threading

    geom = Geometry(scene_of(icosphere(4)))
    first, second = list(random_cameras(scene_of(icosphere(4)), 2, seed=13))
    cam = camera_data(first, 120, 90)
    out = wp.empty((90, 120), dtype=wp.uint64)

    def on_a_fresh_thread(cam):
        result = []
        worker = threading.Thread(target=lambda: result.append(
            visibility_buffer(geom.positions, geom.indices, cam, threads=2).numpy().copy()))
        worker.start()
        worker.join()
        return result[0]

    seen = []
    for step in range(3):
        if step == 1:
            moved = camera_data(second, 120, 90)
            for field in ("eye", "forward", "right", "up"):
                setattr(cam, field, getattr(moved, field))
        if step == 2:
            geom.positions.numpy()[:] *= 0.8
        buffer = visibility_buffer(geom.positions, geom.indices, cam, threads=2, out=out).numpy().copy()
        np.testing.assert_array_equal(buffer, on_a_fresh_thread(cam))
        seen.append(buffer)
    assert not np.array_equal(seen[0], seen[1]) and not np.array_equal(seen[1], seen[2])


@wp.kernel(enable_backward=False)
def camera_sum(cam: CameraData, scale: float, values: wp.array(dtype=float), out: wp.array(dtype=float)):
    out[0] = (cam.eye[0] + float(cam.width) + values[0]) * scale


def test_replayed_launches_pack_again_all_but_the_same_arrays():
    """_replay_launch, the raster's way to skip packing unchanged arguments: a struct changed in
    place, a new scalar, an array changed in place and another array each show in the result;
    the same array and an equal number are not packed again."""
    from pbrwarp.raster import _replay_launch

    recorded = {}
    cam = CameraData()
    cam.eye, cam.width = wp.vec3(1.0, 0.0, 0.0), 10
    values, out = wp.array([100.0], dtype=float), wp.zeros(1, dtype=float)

    def result(scale, values_now):
        _replay_launch(recorded, "sum", camera_sum, [cam, scale, values_now, out])
        return float(out.numpy()[0])

    assert result(1.0, values) == 111.0
    cam.eye, cam.width = wp.vec3(2.0, 0.0, 0.0), 20
    assert result(1.0, values) == 122.0
    assert result(2.0, values) == 244.0
    values.numpy()[0] = 200.0
    assert result(1.0, values) == 222.0
    assert result(1.0, wp.array([300.0], dtype=float)) == 322.0
    # of the same arguments again, only the struct is packed (the same array, an equal number)
    command, _ = recorded[("sum", "launch")]
    packed = []
    original = command.set_param_at_index
    command.set_param_at_index = lambda index, value: (packed.append(index), original(index, value))
    last_values = recorded[("sum", "launch")][1][2]
    assert result(1.0, last_values) == 322.0 and packed == [0]


def test_back_face_culling_drops_exactly_the_faces_turned_away():
    corners = [pixel_to_plane(10, 10), pixel_to_plane(20, 50), pixel_to_plane(50, 12)]
    geom = mesh_geometry(corners, [[0, 1, 2]])
    cam = head_on()
    # (0, 1, 2) runs counter-clockwise seen from the eye at the origin: its normal points at it
    p = geom.vertices
    assert np.dot(np.cross(p[1] - p[0], p[2] - p[0]), -p[0]) > 0
    for face, facing_the_eye in (([0, 1, 2], True), ([2, 1, 0], False)):
        indices = wp.array(np.array(face, np.int32), dtype=wp.int32)
        for flag in (0, 1):
            cull = wp.array(np.array([flag], np.uint8), dtype=wp.uint8)
            covered = int((decode(visibility_buffer(geom.positions, indices, cam, cull_back_faces=cull))[0] >= 0).sum())
            if flag == 1 and not facing_the_eye:
                assert covered == 0
            else:
                assert covered > 500


def test_culling_a_closed_mesh_seen_from_outside_changes_no_visible_triangle():
    """Back faces of a closed surface are never nearest from outside: every sample keeps its
    triangle, but for depth ties and edges between a front and a back face at the silhouette."""
    geom = Geometry(scene_of(icosphere(5)))
    cull = wp.array(np.ones(len(geom.faces), np.uint8), dtype=wp.uint8)
    rng = np.random.default_rng(8)
    changed = samples = 0
    for _ in range(10):
        d = rng.normal(size=3)
        eye = d / np.linalg.norm(d) * rng.uniform(1.05, 4.0)
        cam = camera_data(pw.Camera.look_at(tuple(eye), tuple(rng.normal(size=3) * 0.2), fov_y=70.0), 128, 96)
        ids, _ = raster(geom, cam)
        culled, _ = decode(visibility_buffer(geom.positions, geom.indices, cam, cull_back_faces=cull))
        assert ((culled >= 0) == (ids >= 0)).all()
        changed += int((culled != ids).sum())
        samples += ids.size
    assert changed <= 1e-4 * samples


def test_shading_kernels_read_the_same_ids():
    """visible_triangle, what a shading kernel calls per sample, agrees with decode."""
    geom = Geometry(scene_of(icosphere(3)))
    cam = camera_data(pw.Camera.look_at((0.5, 0.3, 2.5), (0.0, 0.0, 0.0)))
    buffer = visibility_buffer(geom.positions, geom.indices, cam)
    ids = wp.empty(buffer.shape, dtype=int)
    wp.launch(triangle_ids, dim=buffer.shape, inputs=[buffer, ids])
    np.testing.assert_array_equal(ids.numpy(), decode(buffer)[0])
    assert 0 < (ids.numpy() >= 0).mean() < 1


def test_empty_mesh_covers_nothing():
    positions = wp.array(np.zeros((0, 3), np.float32), dtype=wp.vec3)
    ids, _ = decode(visibility_buffer(positions, wp.array(np.zeros(0, np.int32), dtype=wp.int32), head_on()))
    assert (ids < 0).all()


def test_bad_input_is_rejected_before_warp(monkeypatch):
    geom = mesh_geometry([(0, 0, -1), (1, 0, -1), (0, 1, -1)], [[0, 1, 2]])
    cam = head_on()
    for indices, error in (([0, 1, 3], pw.InputError), ([0, 1, -1], pw.InputError), ([0, 1], pw.InputError)):
        with pytest.raises(error):
            visibility_buffer(geom.positions, wp.array(np.array(indices, np.int32), dtype=wp.int32), cam)
    with pytest.raises(pw.InputTypeError):
        visibility_buffer(geom.positions, wp.array(np.array([0, 1, 2], np.int64), dtype=wp.int64), cam)
    with pytest.raises(pw.InputError):
        visibility_buffer(geom.positions, geom.indices, cam, spp=4, grid_m=1, grid_n=2)
    with pytest.raises(pw.InputError):
        visibility_buffer(geom.positions, geom.indices, cam, threads=0)
    with pytest.raises(pw.InputError):
        visibility_buffer(geom.positions, geom.indices, cam, out=wp.empty((64, 63), dtype=wp.uint64))
    with pytest.raises(pw.InputError):
        visibility_buffer(geom.positions, geom.indices, cam, cull_back_faces=wp.zeros(2, dtype=wp.uint8))
    with pytest.raises(pw.InputError, match="threads must be at most"):
        visibility_buffer(geom.positions, geom.indices, cam, threads=2**31)
    # each thread's list of triangles to bin has room for all of them, in int32 entries (a mesh of
    # 2^31 / threads triangles; here with the bound on threads lifted)
    monkeypatch.setattr(parallel, "MAX_THREADS_PER_CORE", 2**31)
    with pytest.raises(pw.InputError, match="use fewer threads"):
        visibility_buffer(geom.positions, geom.indices, cam, threads=2**31)


def test_calls_stopping_after_binning_leave_no_launch_waiting_for_the_next():
    """A call that stops after binning (an index out of range, or timings taken apart) returns only
    once every launch has left the kernel's barriers: the next call zeroes their counters, and
    a launch still waiting at one would spin forever, hanging that call (before the fix, 4
    threads on 2 cores hung within 50 such calls). Run in a process of its own, so that a
    regression fails here on the timeout rather than hanging the suite."""
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r})
        import numpy as np
        import warp as wp
        import pbrwarp as pw
        from pbrwarp.raster import decode, visibility_buffer
        from test_raster import head_on, mesh_geometry

        wp.config.quiet = True
        cam = head_on()
        geom = mesh_geometry([(-1, -1, -1), (1, -1, -1), (-1, 1, -1)], [[0, 1, 2]])
        bad = wp.array(np.array([0, 1, 3], np.int32), dtype=wp.int32)
        for _ in range(300):
            try:
                visibility_buffer(geom.positions, bad, cam, threads=4)
            except pw.InputError:
                pass
            else:
                raise SystemExit("an index out of range was accepted")
            visibility_buffer(geom.positions, geom.indices, cam, threads=4, timings={{}})
        ids, _ = decode(visibility_buffer(geom.positions, geom.indices, cam, threads=4))
        # the lower left half: pixel centres with x + y < 0, i.e. column < row (the diagonal is
        # the edge, where the fill rule decides)
        column, row = np.meshgrid(np.arange(64), np.arange(64))
        assert (ids[column < row] == 0).all() and (ids[column > row] == -1).all(), ids
        print("done")
        """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split()[-1:] == ["done"], run.stdout[-2000:]


@wp.kernel(enable_backward=False)
def busy_masks(indices: wp.array(dtype=wp.int32), screen: wp.array(dtype=wp.vec2i), vertex_count: int, spp: int,
               width: int, height: int, out: wp.array(dtype=wp.uint64)):
    k = wp.tid()
    out[k] = triangles_to_count(indices, screen, vertex_count, 64 * k, wp.min(64 * k + 64, indices.shape[0] / 3),
                                   spp, width, height)


@pytest.mark.parametrize("spp", [1, 4])
def test_triangles_to_count_skips_exactly_the_projected_ones_holding_no_sample(spp):
    """Against the definition: a projected triangle is skipped iff no pixel of the image has a
    sample within its rectangle (pixel centres for spp = 1, anywhere in the pixel otherwise);
    triangles with an index out of range or a vertex not projected are always counted."""
    rng = np.random.default_rng(spp)
    width, height, vertices, triangles = 40, 30, 500, 1000
    pixel = int(PIXEL)
    screen = np.stack([rng.integers(-3 * pixel, 43 * pixel, vertices), rng.integers(-3 * pixel, 33 * pixel, vertices)], 1)
    screen[::7] = [int(ts.BEHIND_CAMERA), 0]
    screen[3::11] = [int(ts.OUTSIDE_GUARD_BAND), 0]
    # small triangles (most hold no sample): three points within a pixel of a vertex, not
    # projected where that vertex is not
    centres = rng.integers(0, vertices, triangles)
    near = rng.integers(-pixel, pixel, (triangles, 3, 2))
    points = np.concatenate([screen, (screen[centres][:, None, :] + near).reshape(-1, 2)])
    points[vertices:][np.repeat(screen[centres, 0] <= int(ts.OUTSIDE_GUARD_BAND), 3)] = [int(ts.BEHIND_CAMERA), 0]
    faces = vertices + np.arange(3 * triangles).reshape(-1, 3)
    faces[5::97, 1] = len(points) + 3  # out of range
    faces[9::89, 2] = -1
    masks = wp.empty(-(-triangles // 64), dtype=wp.uint64)
    wp.launch(busy_masks, dim=len(masks), inputs=[wp.array(faces.reshape(-1).astype(np.int32), dtype=wp.int32),
                                                   wp.array(points.astype(np.int32), dtype=wp.vec2i), len(points), spp,
                                                   width, height, masks])
    busy = [(int(masks.numpy()[t // 64]) >> (t % 64)) & 1 for t in range(triangles)]
    for t, face in enumerate(faces):
        if face.min() < 0 or face.max() >= len(points):
            assert busy[t] == 1
            continue
        q = points[face].astype(np.int64)
        if np.any(q[:, 0] <= int(ts.OUTSIDE_GUARD_BAND)):
            assert busy[t] == 1
            continue
        lo, hi = q.min(axis=0), q.max(axis=0)
        if spp == 1:  # pixel k's sample at (k + 1/2) pixel
            first, last = np.ceil((lo - pixel / 2) / pixel), np.floor((hi - pixel / 2) / pixel)
        else:  # pixel k's samples anywhere in [k, k + 1] pixel
            first, last = np.ceil(lo / pixel) - 1, np.floor(hi / pixel)
        first, last = np.maximum(first, 0), np.minimum(last, [width - 1, height - 1])
        assert busy[t] == int(np.all(first <= last)), (t, q)


@wp.kernel(enable_backward=False)
def project_all(positions: wp.array(dtype=wp.vec3), proj: Projection, screen: wp.array(dtype=wp.vec2i),
                depth_weights: wp.array(dtype=wp.float64)):
    ts.project_vertices(positions, proj.to_camera, proj.eye, proj.half_width, proj.half_height, proj.orthographic,
                        0, positions.shape[0], screen, depth_weights)


@pytest.mark.parametrize("orthographic", [False, True])
def test_vertex_projection_against_float64(orthographic):
    """Snapped to the nearest 1/4096 pixel of the float64 projection, the codes for vertices behind
    the camera plane and beyond the guard band, 1/z (or z in parallel) as the depth weight; the
    same for positions read through a strided view."""
    rng = np.random.default_rng(5)
    cam = camera_data(pw.Camera.look_at((0.3, -0.2, 4.0), (0.0, 0.0, 0.0), up=(0.2, 1.0, 0.1), fov_y=60.0), 640, 480)
    axes = np.array([cam.right, cam.up, cam.forward], np.float64).T
    # beyond the guard band: near the camera plane in perspective, far to the side in parallel
    beyond = np.stack([rng.normal(size=300) * 3e3, rng.normal(size=300) * 3e3, rng.uniform(1e-4, 1e-2, 300)], 1)
    points = np.concatenate([rng.normal(size=(4000, 3)) * 3.0,  # some behind the camera plane
                             np.array(cam.eye, np.float64) + beyond @ axes.T,
                             [[0.3, -0.2, 4.0]]]).astype(np.float32)  # the eye itself
    proj = projection(cam, orthographic)
    c = camera_coordinates(cam, points)
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = screen_coordinates(cam, c, orthographic)
        weight = c[:, 2] if orthographic else 1 / c[:, 2]
    behind = c[:, 2] <= 0
    outside = ~behind & ~((np.abs(x) <= float(ts.GUARD_BAND)) & (np.abs(y) <= float(ts.GUARD_BAND)))
    assert behind.sum() > 100 and outside.sum() > 100
    doubled = np.zeros((2 * len(points), 3), np.float32)
    doubled[::2] = points
    for positions in (wp.array(points, dtype=wp.vec3), wp.array(doubled, dtype=wp.vec3)[::2]):
        screen = wp.empty(len(points), dtype=wp.vec2i)
        weights = wp.empty(len(points), dtype=wp.float64)
        wp.launch(project_all, dim=1, inputs=[positions, proj, screen, weights])
        q, w = screen.numpy(), weights.numpy()
        assert np.all(q[behind] == [int(ts.BEHIND_CAMERA), 0])
        assert np.all(q[outside] == [int(ts.OUTSIDE_GUARD_BAND), 0])
        shown = ~behind & ~outside
        pixels = 4096.0
        np.testing.assert_allclose(q[shown, 0] / pixels, x[shown], rtol=0, atol=0.5 / pixels + 1e-9 * np.abs(x[shown]).max())
        np.testing.assert_allclose(q[shown, 1] / pixels, y[shown], rtol=0, atol=0.5 / pixels + 1e-9 * np.abs(y[shown]).max())
        # (z near the camera plane is a difference of the coordinates' magnitude, ~5: 1e-15 of that)
        np.testing.assert_allclose(w[shown], weight[shown], rtol=1e-12, atol=1e-14)


def test_projection_inverts_the_camera_axes_and_rejects_degenerate_ones():
    """to_camera is the float64 inverse of the matrix of the camera's scaled axes (columns right,
    up, forward) for a tilted, non-square and a mirrored camera; the back-facing sign follows the
    handedness; axes that are not finite or not independent are refused with a clear error, by
    projection and by visibility_buffer; an eye out of float range draws nothing."""
    for camera, size, mirrored in ((pw.Camera.look_at((0.3, -0.2, 4.0), (0.0, 0.0, 0.0), up=(0.2, 1.0, 0.1),
                                                      fov_y=60.0), (640, 480), False),
                                   (pw.Camera.look_at((5.0, 1.0, -2.0), (0.0, 0.5, 0.0), fov_y=20.0), (31, 977), False)):
        cam = camera_data(camera, *size)
        axes = np.array([cam.right, cam.up, cam.forward], np.float64).T
        proj = projection(cam)
        to_camera = np.array(proj.to_camera, np.float64).reshape(3, 3)
        # float64 rounding, the axes' lengths differing (aspect ratio, field of view)
        tolerance = 4e-16 * np.linalg.cond(axes)
        np.testing.assert_allclose(to_camera @ axes, np.eye(3), rtol=0, atol=tolerance)
        np.testing.assert_allclose(to_camera, np.linalg.inv(axes), rtol=tolerance, atol=tolerance * np.abs(to_camera).max())
        assert proj.back_facing_sign == (1 if np.linalg.det(axes) < 0 else -1)
        assert (proj.width, proj.height, proj.half_width, proj.half_height) == (size[0], size[1], size[0] / 2,
                                                                                size[1] / 2)
        cam.right = -np.asarray(cam.right)  # a mirror image: the other handedness
        assert projection(cam).back_facing_sign == -proj.back_facing_sign
    for bad in ((1.0, 0.0, 0.0), (float("nan"), 0.0, 0.0), (float("inf"), 1.0, 0.0)):
        cam = camera_data(pw.Camera.look_at((0.0, 0.0, 4.0), (0.0, 0.0, 0.0)), 64, 64)
        cam.up = wp.vec3(*bad)  # along right, or not finite
        with pytest.raises(pw.InputError, match="camera axes must be finite and linearly independent"):
            projection(cam)
        # visibility_buffer's launches derive the projection themselves and refuse such a camera too
        geom = mesh_geometry([(0, 0, -1), (1, 0, -1), (0, 1, -1)], [[0, 1, 2]])
        for threads in (1, 2):
            with pytest.raises(pw.InputError, match="camera axes must be finite and linearly independent"):
                visibility_buffer(geom.positions, geom.indices, cam, threads=threads)
    # an eye out of float range (a camera framing a scene near float32's limit) draws nothing
    geom = Geometry(scene_of(icosphere(3)))
    for eye in ((float("inf"), 0.0, 0.0), (0.0, float("nan"), 0.0)):
        cam = camera_data(pw.Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0)), 64, 48)
        cam.eye = wp.vec3(*eye)
        for threads in (1, 2):
            assert (decode(visibility_buffer(geom.positions, geom.indices, cam, threads=threads))[0] < 0).all()


@wp.kernel
def covered_steps_of(e: wp.array(dtype=wp.int64), step: wp.array(dtype=wp.int64), span: wp.array(dtype=wp.vec2i),
                     out: wp.array(dtype=wp.vec2i)):
    i = wp.tid()
    out[i] = covered_steps(e[i], step[i], span[i])


def test_covered_steps_solve_the_edge_inequality_exactly():
    """Wide rows step only over the run of pixels where e + k step >= 0: the solved run is
    exactly the set of k a pixel-by-pixel test accepts (empty as first > last), for rising,
    falling and flat edges, values on the boundary included."""
    rng = np.random.default_rng(4)
    n = 20_000
    step = rng.integers(-5 * 4096, 5 * 4096, n, dtype=np.int64)
    step[:1000] = 0
    first = rng.integers(0, 40, n)
    last = first + rng.integers(-1, 40, n)
    e = rng.integers(-60 * 4096, 60 * 4096, n, dtype=np.int64)
    # boundary cases: the edge function exactly 0 at some step
    k0 = rng.integers(0, 60, n)
    e[1000:3000] = -k0[1000:3000] * step[1000:3000]
    out = wp.empty(n, dtype=wp.vec2i)
    wp.launch(covered_steps_of, dim=n, inputs=[wp.array(e, dtype=wp.int64), wp.array(step, dtype=wp.int64),
                                               wp.array(np.stack([first, last], 1).astype(np.int32), dtype=wp.vec2i), out])
    solved = out.numpy()
    for i in range(n):
        ks = [k for k in range(first[i], last[i] + 1) if e[i] + k * step[i] >= 0]
        if ks:
            assert tuple(solved[i]) == (ks[0], ks[-1]), (e[i], step[i], first[i], last[i])
        else:
            assert solved[i][0] > solved[i][1], (e[i], step[i], first[i], last[i])


def test_run_together_without_joining_returns_with_the_caller_and_reports_the_helpers():
    """pbrwarp.parallel.run_together(join=False) returns once fn(0) has, the pool threads' work
    still running; its callable waits for them and raises the first of their errors; an error of
    fn(0) is raised only once the others are done."""
    import threading
    from pbrwarp.parallel import run_together

    release, finished = threading.Event(), []

    def helper_waits(k):
        if k:
            release.wait(10)
            finished.append(k)

    join = run_together(helper_waits, 3, join=False)
    assert finished == []  # the helpers still wait
    release.set()
    join()
    assert sorted(finished) == [1, 2]

    def helper_fails(k):
        if k == 2:
            raise ValueError("helper 2 failed")

    join = run_together(helper_fails, 3, join=False)
    with pytest.raises(ValueError, match="helper 2 failed"):
        join()

    done, later = [], threading.Event()
    threading.Timer(0.2, later.set).start()

    def caller_fails(k):
        if k == 0:
            raise KeyError("caller failed")
        later.wait(10)
        done.append(k)

    with pytest.raises(KeyError, match="caller failed"):
        run_together(caller_fails, 2, join=False)
    assert done == [1]
