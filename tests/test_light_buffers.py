"""Light buffers (pbrwarp/light_buffers.py), the shadow rays' acceleration structure: every verdict
they give is the BVH's for the same ray, they give one for nearly every ray, and the rendered
shadows do not depend on them."""

import dataclasses
import sys

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.lights import light_sampler
from pbrwarp.kernels.light_buffer import (CLEAR, INTERIOR_CLEAR, INTERIOR_SHRINKS, MAX_REGION_TRIANGLES, REGIONS_CLEAR,
                                          LightBuffers)
from pbrwarp.kernels.light_buffer_interiors import solid_separated, swept_solid
from pbrwarp.kernels.light_buffer_query import UNDECIDED, light_buffer_occlusion, ray_leaves_clear
from pbrwarp.kernels.light_buffer_regions import REGION_SLACK
from pbrwarp.kernels.robust import RAY_FAR, SHADOW_RAY_SHORTENING, offset_ray_origin, triangle_hit_error
from pbrwarp.kernels.scene_data import SceneData
from pbrwarp.light_buffers import build, no_light_buffers
from pbrwarp.meshes import bunny, icosphere

from assets import GLTF, asset_id
from scenes import render_checked


sample_light = light_sampler(True, True, True)


@wp.func
def spawned_shadow_ray(scene: SceneData, light: int, f: int, b0: float, b1: float, b2: float):
    """(point, origin, direction, max_t) of the shadow ray towards ``light`` from the point of
    triangle f with barycentric coordinates (b0, b1, b2) of its corners, spawned as the render
    kernel spawns them."""
    p0 = scene.positions[scene.indices[3 * f]]
    p1 = scene.positions[scene.indices[3 * f + 1]]
    p2 = scene.positions[scene.indices[3 * f + 2]]
    p = p0 * b0 + p1 * b1 + p2 * b2
    data = scene.lights[light]
    to_light = -data.direction
    if data.kind != 1:
        to_light = wp.normalize(data.position - p)
    ng = wp.normalize(wp.cross(p1 - p0, p2 - p0))
    if wp.dot(ng, to_light) < 0.0:
        ng = -ng
    origin = offset_ray_origin(p, triangle_hit_error(p0, p1, p2), ng, to_light)
    direction = to_light
    max_t = RAY_FAR
    if data.kind != 1:
        direction = wp.normalize(data.position - origin)
        max_t = wp.length(data.position - origin) * (1.0 - SHADOW_RAY_SHORTENING)
    return p, origin, direction, max_t


@wp.kernel
def verdicts(scene: SceneData, buffers: LightBuffers, light: int, faces: wp.array(dtype=int),
             barycentrics: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec3i)):
    """(light buffer verdict, BVH any-hit, lit by the light) for a shadow ray from a point on each
    given triangle (it traces none outside a spot's cone)."""
    i = wp.tid()
    f = faces[i]
    b = barycentrics[i]
    p, origin, direction, max_t = spawned_shadow_ray(scene, light, f, b[0], b[1], 1.0 - b[0] - b[1])
    data = scene.lights[light]
    verdict, blocker = light_buffer_occlusion(buffers, light, data.position, scene.positions, scene.indices, origin,
                                              direction, max_t, f)
    reached = wp.where(sample_light(data, p).irradiance == wp.vec3(0.0), 0, 1)
    out[i] = wp.vec3i(verdict, wp.where(wp.mesh_query_ray_anyhit(scene.mesh, origin, direction, max_t), 1, 0), reached)


@wp.kernel
def interior_rays(scene: SceneData, buffers: LightBuffers, light: int, faces: wp.array(dtype=int),
                  barycentrics: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3i)):
    """(whether the render kernel takes the shadow ray from a point of each given triangle (the
    given barycentrics of its corners) as lit without a query, BVH any-hit, lit by the light)."""
    i = wp.tid()
    f = faces[i]
    b = barycentrics[i]
    p, origin, direction, max_t = spawned_shadow_ray(scene, light, f, b[0], b[1], b[2])
    skipped = wp.where(ray_leaves_clear(buffers, light, f, b[0], b[1], b[2]), 1, 0)
    reached = wp.where(sample_light(scene.lights[light], p).irradiance == wp.vec3(0.0), 0, 1)
    out[i] = wp.vec3i(skipped, wp.where(wp.mesh_query_ray_anyhit(scene.mesh, origin, direction, max_t), 1, 0), reached)


def scene_with_floor(mesh, light, shift=0.0):
    scene = pw.Scene()
    mesh = mesh.copy()
    mesh.apply_translation(-mesh.bounding_box.centroid)
    mesh.apply_scale(1.0 / np.max(np.linalg.norm(mesh.vertices, axis=1)))
    mesh.apply_translation(np.broadcast_to(shift, 3))
    scene.add_mesh(mesh, pw.Material())
    floor = np.array([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], float) + shift
    scene.add_mesh(trimesh.Trimesh(floor, [[0, 2, 1], [0, 3, 2]]), pw.Material())
    scene.add_light(light)
    return scene


LIGHTS = {
    "point": pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0),
    "point inside the cube of the mesh": pw.PointLight(position=(0.0, 1.3, 0.2), intensity=40.0),
    "directional": pw.DirectionalLight(direction=(-0.5, -1.0, -0.3), intensity=3.0),
    "narrow spot": pw.SpotLight(position=(1.0, 3.0, 1.0), direction=(-0.3, -1.0, -0.3), intensity=60.0,
                                inner_cone=0.3, outer_cone=0.5),
    "wide spot": pw.SpotLight(position=(1.0, 3.0, 1.0), direction=(-0.3, -1.0, -0.3), intensity=60.0,
                              inner_cone=1.0, outer_cone=1.4),
}


def assert_same_shadows_as_the_bvh(scene, cam, size, monkeypatch):
    """The image with light buffers (and the shadow cache) equals, but for <= 0.1% of pixels, the
    one whose shadow rays all go through Warp's BVH: in the first frame, and in the second, which
    reuses the buffers with their interiors and regions marked."""
    with_buffers = render_checked(scene, cam, size=size)
    reused = render_checked(scene, cam, size=size)
    monkeypatch.setattr(sys.modules["pbrwarp.render"], "build_light_buffers", lambda *args: no_light_buffers())
    bvh_only = render_checked(scene, cam, size=size)
    for frame in (with_buffers, reused):
        differs = ~np.all(np.isclose(frame.rgb, bvh_only.rgb, rtol=1e-6, atol=1e-30), axis=-1)
        assert differs.mean() <= 1e-3


def moved(light, offset):
    """``light`` with its position moved by ``offset`` (directional lights unchanged)."""
    if not hasattr(light, "position"):
        return light
    return dataclasses.replace(light, position=tuple(np.asarray(light.position) + offset))


def assert_verdicts_are_the_bvhs(scene):
    """Shadow rays from random points of the scene's triangles (the floor's two, its last, get as
    many as the mesh) towards its first light: the light buffers decide nearly all of them, and
    every verdict but for <= 1e-4 of them is the BVH's. Returns the light buffers."""
    gpu = upload(scene)
    buffers = build(scene, gpu)
    rng = np.random.default_rng(1)
    n = 200_000
    faces = rng.integers(0, len(gpu.data.indices) // 3, n)
    faces[: n // 2] = len(gpu.data.indices) // 3 - 1 - rng.integers(0, 2, n // 2)
    uv = rng.random((n, 2))
    uv = np.where(uv.sum(axis=1, keepdims=True) > 1.0, 1.0 - uv, uv)
    out = wp.empty(n, dtype=wp.vec3i)
    wp.launch(verdicts, dim=n, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int), wp.array(uv, dtype=wp.vec2), out])
    verdict, bvh, reached = out.numpy().T
    verdict, bvh = verdict[reached == 1], bvh[reached == 1]
    decided = verdict != int(UNDECIDED)
    assert decided.mean() >= 0.99, decided.mean()
    assert 0.02 < bvh.mean() < 0.98
    # a ray grazing a triangle's edge may be told apart differently by the two traversals' rounding
    assert (verdict[decided] != bvh[decided]).sum() <= 1e-4 * len(verdict)
    return buffers


@pytest.mark.parametrize("light", LIGHTS)
@pytest.mark.parametrize("mesh,offset", [("icosphere", 0.0), ("bunny", 0.0), ("icosphere", 1e4)],
                         ids=["icosphere", "bunny", "icosphere 1e4 from the origin"])
def test_light_buffer_verdicts_are_the_bvhs(light, mesh, offset):
    """Far from the origin the float32 shadow rays miss the light by more: still no verdict differs."""
    shift = np.array([offset, 0.5 * offset, -offset])
    scene = scene_with_floor(icosphere(5) if mesh == "icosphere" else bunny(), moved(LIGHTS[light], shift),
                             shift)
    assert_verdicts_are_the_bvhs(scene)


@pytest.mark.parametrize("light", LIGHTS)
def test_light_buffer_verdicts_are_the_bvhs_in_the_finer_views_of_dense_scenes(light, monkeypatch):
    """The finer cells a denser scene's light buffers get (here the icosphere's scene counts as
    one with 9 times its triangles: 3 times 512 cells a side where the budget allows) give the
    BVH's verdicts too, and explain names them."""
    import pbrwarp.light_buffers as light_buffers

    scene = scene_with_floor(icosphere(5), LIGHTS[light])
    monkeypatch.setattr(light_buffers, "RESOLUTION_TRIANGLES", scene.triangle_count / 9)
    views = 1 if light in ("directional", "narrow spot") else 6
    side = min(3 * light_buffers.RESOLUTION, light_buffers.RESOLUTION_STEP
               * int(np.sqrt(light_buffers.MAX_CELLS / views) // light_buffers.RESOLUTION_STEP))
    assert assert_verdicts_are_the_bvhs(scene).resolution == side > light_buffers.RESOLUTION
    assert f"each of {side}² directions per view, finer than the 512² of scenes up to" in pw.explain(scene)


def test_denser_scenes_get_finer_light_buffer_views():
    """RESOLUTION cells a side up to about RESOLUTION_TRIANGLES triangles, then as many cells per
    triangle (the side growing with the square root of the count, to the nearest multiple of
    RESOLUTION_STEP), within MAX_CELLS over all the views; never fewer cells for more triangles
    or fewer views."""
    from pbrwarp.light_buffers import MAX_CELLS, RESOLUTION, RESOLUTION_STEP, RESOLUTION_TRIANGLES, resolution

    assert resolution(1, 6) == resolution(RESOLUTION_TRIANGLES, 6) == RESOLUTION
    assert resolution(4 * RESOLUTION_TRIANGLES, 6) == 2 * RESOLUTION
    # a floor's two triangles more do not change the side
    assert resolution(RESOLUTION_TRIANGLES + 2, 6) == RESOLUTION
    counts = np.unique(np.geomspace(1, 1e8, 400).astype(int))
    for views in (1, 6, 24, 600):
        sides = [resolution(int(t), views) for t in counts]
        assert all(a <= b for a, b in zip(sides, sides[1:]))
        for t, side in zip(counts, sides):
            assert side % RESOLUTION_STEP == 0
            if side > RESOLUTION:
                assert views * side * side <= MAX_CELLS
                ideal = RESOLUTION * np.sqrt(t / RESOLUTION_TRIANGLES)
                assert side <= ideal + RESOLUTION_STEP / 2
                # short of the ideal only where one step more would break the budget
                assert side >= ideal - RESOLUTION_STEP / 2 or views * (side + RESOLUTION_STEP) ** 2 > MAX_CELLS
            assert resolution(int(t), 2 * views) <= side
    assert resolution(10**8, 600) == RESOLUTION


@pytest.mark.parametrize("light", LIGHTS)
def test_view_count_is_the_number_of_light_views(light):
    """The light-buffer side is chosen on every render from view_count, which must count the
    views light_views makes."""
    from pbrwarp.shadow_maps import light_views, view_count

    assert view_count(LIGHTS[light]) == len(light_views(LIGHTS[light], np.zeros(3), 2.0, 64, 1))


def clear_marks(mesh, light, offset=0.0):
    """(uploaded scene, light buffers, per triangle its mark for the light) of ``mesh`` on the floor
    (all moved by ``offset`` times (1, 0.5, -1)), once the buffers were reused (which marks
    interiors and regions)."""
    shift = np.array([offset, 0.5 * offset, -offset])
    scene = scene_with_floor(icosphere(5) if mesh == "icosphere" else bunny(), moved(LIGHTS[light], shift), shift)
    gpu = upload(scene)
    build(scene, gpu)
    buffers = build(scene, gpu)  # reused: a marked copy, kept from then on
    assert build(scene, gpu) is buffers
    return gpu, buffers, buffers.triangle_clear.numpy()[: buffers.triangles].astype(int)


@pytest.mark.parametrize("light", ["point", "point inside the cube of the mesh", "narrow spot", "wide spot"])
@pytest.mark.parametrize("mesh", ["icosphere", "bunny"])
def test_triangles_marked_clear_are_never_shadowed(light, mesh):
    """A triangle marked clear of a light skips its shadow rays' queries: the BVH finds no occluder
    for rays from anywhere on it, and a convex sphere's lit side is mostly marked."""
    gpu, buffers, marks = clear_marks(mesh, light)
    clear = np.flatnonzero(marks == int(CLEAR))
    if mesh == "icosphere" and light == "point":
        assert len(clear) >= 0.25 * buffers.triangles
    if len(clear) == 0:
        return
    rng = np.random.default_rng(2)
    n = 100_000
    faces = rng.choice(clear, n)
    uv = rng.random((n, 2))
    uv = np.where(uv.sum(axis=1, keepdims=True) > 1.0, 1.0 - uv, uv)
    # the corners and edges too, where neighbours meet
    uv[: n // 10] = rng.choice([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [0.5, 0.5], [0.0, 0.5], [0.5, 0.0]], n // 10)
    out = wp.empty(n, dtype=wp.vec3i)
    wp.launch(verdicts, dim=n, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int), wp.array(uv, dtype=wp.vec2), out])
    verdict, bvh, reached = out.numpy().T
    assert np.all(verdict[reached == 1] == 0)
    assert np.all(bvh[reached == 1] == 0)


@pytest.mark.parametrize("light", ["point", "point inside the cube of the mesh", "directional", "narrow spot",
                                   "wide spot"])
@pytest.mark.parametrize("mesh", ["icosphere", "bunny"])
def test_rays_from_a_clear_interior_are_never_shadowed(light, mesh):
    """A triangle whose interior (shrunk by INTERIOR_SHRINKS[k] about its centroid) is marked clear
    skips the queries of the rays leaving it there: the BVH finds no occluder for rays from
    anywhere in it, its corners and edges included; rays from outside it are queried. The noisy
    bunny's lit side, whose neighbours rise in front of each other's planes, is mostly marked so."""
    gpu, buffers, marks = clear_marks(mesh, light)
    interior = np.flatnonzero((marks >= int(INTERIOR_CLEAR)) & (marks < int(REGIONS_CLEAR)))
    if mesh == "bunny" and light in ("point", "directional"):
        assert len(interior) >= 0.2 * buffers.triangles
    if len(interior) == 0:
        return
    rng = np.random.default_rng(3)
    n = 100_000
    faces = rng.choice(interior, n)
    least = np.array([float(x) for x in INTERIOR_SHRINKS])[marks[faces] - int(INTERIOR_CLEAR)] / 3.0
    # points of the shrunk triangle: least + (1 - 3 least) times barycentrics of the whole one
    b = rng.dirichlet(np.ones(3), n)
    # its corners and edges too
    b[: n // 10] = rng.choice([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.5]],
                              n // 10)
    inside = least[:, None] + (1.0 - 3.0 * least[:, None]) * b
    out = wp.empty(n, dtype=wp.vec3i)
    wp.launch(interior_rays, dim=n, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int),
                                            wp.array(inside.astype(np.float32), dtype=wp.vec3), out])
    skipped, bvh, reached = out.numpy().T
    # float32 barycentrics of the shrunk triangle's boundary may round just below the threshold
    assert skipped[reached == 1].mean() >= 0.9
    assert np.all(bvh[(reached == 1) & (skipped == 1)] == 0)
    # just outside it (outside the triangle for the first level, the whole of it): queried
    outside = inside.copy()
    outside[:, 0] = np.where(least > 0.0, 0.5 * least, -1e-3)
    rest = outside[:, 1:].sum(axis=1, keepdims=True)
    shares = np.divide(outside[:, 1:], rest, out=np.full_like(outside[:, 1:], 0.5), where=rest > 0.0)
    outside[:, 1:] = shares * (1.0 - outside[:, :1])
    wp.launch(interior_rays, dim=n, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int),
                                            wp.array(outside.astype(np.float32), dtype=wp.vec3), out])
    assert not np.any(out.numpy()[:, 0])


def floor_faces(gpu):
    """The floor's two triangles (scene_with_floor's largest)."""
    corners = gpu.data.positions.numpy().astype(np.float64)[gpu.data.indices.numpy().reshape(-1, 3)]
    areas = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    return np.argsort(areas)[-2:]


@pytest.mark.parametrize("light", ["point", "point inside the cube of the mesh", "directional", "narrow spot",
                                   "wide spot"])
@pytest.mark.parametrize("mesh,offset", [("icosphere", 0.0), ("bunny", 0.0), ("icosphere", 1e4)],
                         ids=["icosphere", "bunny", "icosphere 1e4 from the origin"])
def test_rays_from_a_clear_region_are_never_shadowed(light, mesh, offset):
    """A large triangle not clear of a light as a whole (the floor's two) gets a grid of regions,
    squares of its barycentric plane, each marked clear where no triangle can block a shadow ray
    leaving it: the BVH finds no occluder for the rays the render kernel takes as lit without a
    query, from anywhere in the triangle, region edges and corners included; nearly every point of
    a clear region is taken so, no point outside the triangle is, and the floor beside the mesh
    is mostly clear."""
    gpu, buffers, marks = clear_marks(mesh, light, offset)
    regioned = np.flatnonzero(marks >= int(REGIONS_CLEAR))
    floor = floor_faces(gpu)
    grids = buffers.region_grids.numpy()
    flags = buffers.region_clear.numpy()
    if offset == 0.0 and light in ("point", "directional", "wide spot"):
        assert set(floor) <= set(regioned)
        for face in floor:
            n, first = grids[int(marks[face]) - int(REGIONS_CLEAR)]
            in_triangle = np.add.outer(np.arange(n), np.arange(n)).reshape(-1) < n
            assert flags[first:first + n * n][in_triangle].mean() >= 0.6
    if len(regioned) == 0:
        return
    rng = np.random.default_rng(6)
    count = 100_000
    faces = rng.choice(regioned, count)
    n = grids[marks[faces] - int(REGIONS_CLEAR), 0]
    first = grids[marks[faces] - int(REGIONS_CLEAR), 1]
    # a random region's corners, edges and inside
    i = (rng.random(count) * n).astype(int)
    j = (rng.random(count) * (n - i)).astype(int)
    corner = rng.choice([0.0, 1.0, 0.5], (count, 2))
    inside = rng.random((count, 2))
    uv = np.where(rng.random((count, 1)) < 0.3, corner, inside)
    b01 = (np.column_stack([i, j]) + uv) / n[:, None]
    total = b01.sum(axis=1, keepdims=True)
    b01 = np.divide(b01, total, out=b01.copy(), where=total > 1.0)
    b = np.column_stack([b01, 1.0 - b01.sum(axis=1)]).astype(np.float32)
    clear = flags[first + i * n + j] == 1
    out = wp.empty(count, dtype=wp.vec3i)
    wp.launch(interior_rays, dim=count, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int),
                                                wp.array(b, dtype=wp.vec3), out])
    skipped, bvh, reached = out.numpy().T
    assert np.all(bvh[(reached == 1) & (skipped == 1)] == 0)
    if clear.any():
        # a point on a region's edge may be looked up in its neighbour
        assert skipped[clear & (reached == 1)].mean() >= 0.9
    # outside the triangle, beyond the slack: queried
    b[:, 2] = -3.0 * float(REGION_SLACK)
    total = b[:, :2].sum(axis=1, keepdims=True)
    b[:, :2] = np.divide(b[:, :2], total, out=np.full_like(b[:, :2], 0.5), where=total > 0.0) * (1.0 - b[:, 2:])
    wp.launch(interior_rays, dim=count, inputs=[gpu.data, buffers, 0, wp.array(faces, dtype=int),
                                                wp.array(b, dtype=wp.vec3), out])
    assert not np.any(out.numpy()[:, 0])


def test_region_triangles_are_the_largest_up_to_the_limit(monkeypatch):
    """With more large triangles than a light has region slots, the largest get them."""
    import pbrwarp.light_buffers as light_buffers

    monkeypatch.setattr(light_buffers, "MIN_REGION_GRID", 1)
    gpu, buffers, marks = clear_marks("icosphere", "point")
    regioned = np.flatnonzero(marks >= int(REGIONS_CLEAR))
    assert len(regioned) <= int(MAX_REGION_TRIANGLES)
    assert set(floor_faces(gpu)) <= set(regioned)
    assert len(set(marks[regioned])) == len(regioned)  # each its own slot


@pytest.mark.parametrize("light", LIGHTS)
def test_triangles_too_short_for_regions_are_not_sized(light):
    """The float64 sizing is skipped for triangles shorter than _shortest_region_triangle: none of
    them would get regions (triangles of every size, near and far from the light)."""
    import pbrwarp.light_buffers as light_buffers

    rng = np.random.default_rng(5)
    scene = scene_with_floor(icosphere(3), LIGHTS[light])
    centres = rng.uniform(-3.0, 3.0, (400, 3))
    scale = 10.0 ** rng.uniform(-3.0, -0.5, (400, 1, 1))
    corners = centres[:, None, :] + scale * rng.normal(size=(400, 3, 3))
    scene.add_mesh(trimesh.Trimesh(corners.reshape(-1, 3), np.arange(1200).reshape(-1, 3), process=False),
                   pw.Material())
    gpu = upload(scene)
    buffers = build(scene, gpu)
    if buffers.light_views.numpy()[0][1] == 0:
        pytest.skip("no light buffers for this light")
    faces = gpu.data.indices.numpy().reshape(-1, 3)
    positions = gpu.data.positions.numpy()
    size = light_buffers.region_grid_sizes(buffers, 0, positions[faces].astype(np.float64))
    longest = light_buffers._longest_edges(scene, gpu, faces, positions)
    shortest = light_buffers._shortest_region_triangle(buffers, 0)
    assert np.all(longest[size > 0] > shortest)
    assert np.sum(size > 0) > 0
    if buffers.clearance.numpy()[0] > 0.2:  # no random triangle near the light: the tiny ones are skipped
        assert np.sum(longest <= shortest) > 0.05 * len(faces)


def test_regions_stay_within_their_memory_budget(monkeypatch):
    """Past MAX_REGIONS flags no triangle gets regions (its rays are queried as before)."""
    import pbrwarp.light_buffers as light_buffers

    monkeypatch.setattr(light_buffers, "MAX_REGIONS", 0)
    gpu, buffers, marks = clear_marks("icosphere", "point")
    assert marks.max() < int(REGIONS_CLEAR)


@wp.kernel
def separations(solids: wp.array(dtype=wp.vec3d, ndim=2), triangles: wp.array(dtype=wp.vec3d, ndim=2),
                margin: wp.float64, out: wp.array(dtype=int)):
    """Per row: a base triangle (solids[i, 0:3]) and its tops (solids[i, 3:6]: one apex thrice, or
    the base moved by a vector), against triangles[i]."""
    i = wp.tid()
    solid = swept_solid(solids[i, 0], solids[i, 1], solids[i, 2], solids[i, 3], solids[i, 4], solids[i, 5])
    out[i] = wp.where(solid_separated(solid, triangles[i, 0], triangles[i, 1], triangles[i, 2], margin), 1, 0)


def convex_samples(corners, count, rng):
    """Random points of the convex hull of ``corners`` (k, 3), with the corners and edge points."""
    weights = rng.dirichlet(np.ones(len(corners)) * 0.3, count)
    return np.vstack([weights @ corners, corners])


@pytest.mark.parametrize("kind", ["pyramid", "prism"])
def test_solid_separation_is_never_claimed_within_the_margin(kind):
    """solid_separated(solid, q, margin) claims a separating plane: wherever it does, no point of
    the solid (the segments from its base to its apex, for a point light; the prism the base
    sweeps along a vector, for a directional one) lies within the margin of a point of q (dense
    samples of both, float64); it finds one for a neighbour that faces the light across a concave
    crease (which the base triangle's own plane does not exclude) and for one bent away from it,
    and none for triangles that reach into the solid."""
    rng = np.random.default_rng(4)
    n = 400
    apex = np.array([0.0, 0.0, 5.0])
    base = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

    def with_tops(bases, lift):
        tops = np.repeat(lift[:, None, :], 3, axis=1) if kind == "pyramid" else bases + lift[:, None, :]
        return np.concatenate([bases, tops], axis=1)

    bases = base[None] + rng.normal(0.0, 0.2, (n, 3, 3))
    solids = with_tops(bases, apex + rng.normal(0.0, 0.2, (n, 3)))
    triangles = rng.normal(0.0, 1.0, (n, 3, 3)) * 0.6 + [0.4, 0.4, 0.4]
    margin = 0.05
    out = wp.empty(n, dtype=int)
    wp.launch(separations, dim=n, inputs=[wp.array(solids, dtype=wp.vec3d), wp.array(triangles, dtype=wp.vec3d),
                                          margin, out])
    separated = out.numpy().astype(bool)
    assert 0.1 < separated.mean() < 0.9
    for i in np.flatnonzero(separated):
        a = convex_samples(solids[i], 3000, rng)
        b = convex_samples(triangles[i], 1000, rng)
        nearest = np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2))
        assert nearest > margin, i

    # across the base's edge from (1, 0, 0) to (0, 1, 0): a neighbour rising in front of the base's
    # plane (concave), facing the apex too; one bent below it (convex); one leaning over the base
    edge = base[1:]
    cases = {"concave, facing the light": ([1.0, 1.0, 0.3], True), "convex": ([1.0, 1.0, -0.3], True),
             "leaning over the base": ([0.2, 0.2, 0.3], False), "crossing the pyramid": ([0.1, 0.1, 2.0], False)}
    keep = 0.9
    centroid = base.mean(axis=0)
    shrunk = centroid + (base - centroid) * keep
    solids = with_tops(np.array([shrunk] * len(cases)), np.array([apex] * len(cases)))
    triangles = np.array([np.vstack([edge, tip]) for tip, _ in cases.values()])
    wp.launch(separations, dim=len(cases), inputs=[wp.array(solids, dtype=wp.vec3d),
                                                   wp.array(triangles, dtype=wp.vec3d), 1e-4, out])
    assert dict(zip(cases, out.numpy()[: len(cases)].astype(bool))) == {name: want for name, (_, want) in cases.items()}


def test_no_light_buffer_for_a_light_on_a_surface():
    scene = scene_with_floor(icosphere(3), pw.PointLight(position=(0.0, 1.0, 0.0), intensity=5.0))
    buffers = build(scene, upload(scene))
    assert tuple(buffers.light_views.numpy()[0]) == (0, 0)


def test_interiors_are_marked_when_the_buffers_are_first_reused():
    """A light moving every frame rebuilds its buffers every frame: the interiors' marks, which
    pay off only over several frames, wait for the first reuse. They go into a copy: the buffers
    of the first frame, which other renders may still be reading, do not change."""
    scene = scene_with_floor(bunny(), LIGHTS["point"])
    gpu = upload(scene)
    buffers = build(scene, gpu)
    first = buffers.triangle_clear.numpy().copy()
    assert first.max() == int(CLEAR)
    reused = build(scene, gpu).triangle_clear.numpy()
    assert np.array_equal(buffers.triangle_clear.numpy(), first)
    assert np.array_equal(reused[reused < int(INTERIOR_CLEAR)], first[reused < int(INTERIOR_CLEAR)])
    assert (reused >= int(INTERIOR_CLEAR)).mean() >= 0.2
    assert (reused >= int(REGIONS_CLEAR)).sum() == 2  # the floor's two triangles


def test_marking_interiors_again_changes_nothing(monkeypatch):
    """mark_interiors on buffers already marked copies every mark and the region grids they point
    at (with regions for every triangle left unmarked, a second marking would find new ones), and
    leaves the buffers it was given as they were."""
    import pbrwarp.light_buffers as light_buffers

    monkeypatch.setattr(light_buffers, "MIN_REGION_GRID", 1)
    scene = scene_with_floor(icosphere(3), LIGHTS["point"])
    gpu = upload(scene)
    build(scene, gpu)
    buffers = build(scene, gpu)  # reused: interiors and regions marked
    marks = buffers.triangle_clear.numpy().copy()
    grids, flags = buffers.region_grids.numpy().copy(), buffers.region_clear.numpy().copy()
    assert marks.max() >= int(REGIONS_CLEAR)
    again = light_buffers.mark_interiors(scene, gpu, buffers, 2)
    for marked in (buffers, again):
        assert np.array_equal(marked.triangle_clear.numpy(), marks)
        assert np.array_equal(marked.region_grids.numpy(), grids)
        assert np.array_equal(marked.region_clear.numpy(), flags)


def test_only_lights_outside_a_closed_mesh_leave_its_back_faces_unlit():
    """front_only_faces: a closed double-sided sphere's back faces are never seen from a light
    outside its bounding box (point, or directional); from one inside they may be; a single-sided
    mesh's never are; an open double-sided one's always may be."""
    from pbrwarp.light_buffers import front_only_faces

    scene = pw.Scene()
    scene.add_mesh(icosphere(2), pw.Material())
    scene.add_mesh(icosphere(1).apply_translation((3.0, 0.0, 0.0)), pw.Material(double_sided=False))
    scene.add_mesh(trimesh.Trimesh([[-1, -2, -1], [1, -2, -1], [1, -2, 1]], [[0, 2, 1]]), pw.Material())
    for light in (pw.PointLight(position=(0.0, 0.0, 4.0)), pw.PointLight(position=(0.2, 0.1, 0.0)),
                  pw.DirectionalLight(direction=(0.0, -1.0, 0.0))):
        scene.add_light(light)
    gpu = upload(scene)
    primitive = gpu.data.face_material.numpy()
    expected = {0: [True, True, False], 1: [False, True, False], 2: [True, True, False]}
    per_light = front_only_faces(scene, gpu)
    for light, flags in enumerate(per_light):
        assert np.array_equal(flags.numpy(), np.array(expected[light], np.uint8)[primitive])
    assert per_light[0] is per_light[2]  # lights that agree share one array


@pytest.mark.parametrize("material", [pw.Material(), pw.Material(double_sided=False)], ids=["closed", "single-sided"])
def test_no_marks_where_no_shadow_ray_leaves(material, monkeypatch):
    """A sphere whose back faces are never seen from the light (closed, or single-sided) sends no
    shadow ray from the triangles facing away from it: they get no marks, those facing it are
    still marked clear, and the shadows are the BVH's, also seen from inside the sphere, where a
    double-sided sphere's back faces are shaded and their rays queried."""
    scene = pw.Scene()
    scene.add_mesh(icosphere(3), material)
    scene.add_mesh(trimesh.Trimesh([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], [[0, 2, 1], [0, 3, 2]]),
                   pw.Material())
    scene.add_light(LIGHTS["point"])
    gpu = upload(scene)
    build(scene, gpu)
    buffers = build(scene, gpu)  # reused: interiors and regions marked
    marks = buffers.triangle_clear.numpy()
    p = gpu.data.positions.numpy().astype(np.float64)[gpu.data.indices.numpy().reshape(-1, 3)]
    facing = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                       np.asarray(LIGHTS["point"].position) - p[:, 0])
    sphere = gpu.data.face_material.numpy() == 0
    assert np.all(marks[sphere & (facing < 0.0)] == 0)
    assert np.mean(marks[sphere & (facing > 0.0)] == int(CLEAR)) >= 0.5
    assert_same_shadows_as_the_bvh(scene, pw.Camera.look_at(eye=(0.0, 0.8, 3.2), target=(0.0, -0.2, 0.0)), (48, 48),
                                   monkeypatch)
    monkeypatch.undo()
    assert_same_shadows_as_the_bvh(scene, pw.Camera.look_at(eye=(0.0, 0.2, 0.3), target=(0.5, 0.5, -1.0)), (48, 48),
                                   monkeypatch)


@pytest.mark.parametrize("light", ["point", "point inside the cube of the mesh", "directional", "wide spot"])
def test_closed_meshes_list_only_their_triangles_facing_the_light(light):
    """A closed sphere lit from outside its bounding box lists none of its triangles turned away
    from the light (a segment crossing one leaves the sphere through one facing the light); with
    the light inside the box it lists them all; the open floor lists both faces. The verdicts
    stay the BVH's (test_light_buffer_verdicts_are_the_bvhs)."""
    for position, dropped in ((None, True), ((0.3, 0.2, 0.1), False)):
        chosen = LIGHTS[light] if position is None or not hasattr(LIGHTS[light], "position") else dataclasses.replace(
            LIGHTS[light], position=position)
        if position is not None and not hasattr(chosen, "position"):
            continue
        scene = pw.Scene()
        scene.add_mesh(icosphere(3).apply_scale(0.5), pw.Material())
        scene.add_mesh(trimesh.Trimesh([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], [[0, 2, 1], [0, 3, 2]]),
                       pw.Material())
        scene.add_light(chosen)
        gpu = upload(scene)
        buffers = build(scene, gpu)
        assert buffers.light_views.numpy()[0][1] > 0
        listed = np.zeros(buffers.triangles, bool)
        listed[buffers.cell_faces.numpy()[: buffers.cell_start.numpy()[-1]]] = True
        p = gpu.data.positions.numpy().astype(np.float64)[gpu.data.indices.numpy().reshape(-1, 3)]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        if hasattr(chosen, "position"):
            towards = np.asarray(chosen.position) - p[:, 0]
        else:
            towards = -np.broadcast_to(np.asarray(chosen.direction), normal.shape)
        away = np.einsum("ij,ij->i", normal, towards) < -1e-3 * np.linalg.norm(normal, axis=1) * np.linalg.norm(
            towards, axis=1)
        sphere = gpu.data.face_material.numpy() == 0
        assert away[sphere].sum() > 100
        assert not np.any(listed[sphere & away]) if dropped else np.all(listed[sphere & away])
        assert np.all(listed[~sphere])


@pytest.mark.parametrize("double_sided", [True, False])
def test_a_floor_seen_only_from_below_the_light_gets_no_marks(double_sided, monkeypatch):
    """A floor wound to face down, under a light above: double-sided, its top is lit and marked
    (clear whole or by regions); single-sided, its top is never shaded, and it gets no marks."""
    scene = pw.Scene()
    scene.add_mesh(icosphere(2), pw.Material())
    scene.add_mesh(trimesh.Trimesh([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], [[0, 1, 2], [0, 2, 3]]),
                   pw.Material(double_sided=double_sided))
    scene.add_light(LIGHTS["point"])
    gpu = upload(scene)
    build(scene, gpu)
    floor = build(scene, gpu).triangle_clear.numpy()[gpu.data.face_material.numpy() == 1]
    if double_sided:
        assert np.all(floor != 0)
    else:
        assert np.all(floor == 0)
    assert_same_shadows_as_the_bvh(scene, pw.Camera.look_at(eye=(0.0, -2.5, 3.2), target=(0.0, -0.5, 0.0)), (48, 48),
                                   monkeypatch)


def test_buffers_are_reused_until_lights_or_geometry_move():
    scene = scene_with_floor(icosphere(3), pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    first = build(scene, upload(scene))
    marked = build(scene, upload(scene))  # the first reuse: a marked copy of the same lists
    assert marked.cell_faces is first.cell_faces and marked.triangle_clear is not first.triangle_clear
    assert build(scene, upload(scene)) is marked
    scene.lights[0].intensity = 10.0
    assert build(scene, upload(scene)) is marked
    scene.lights[0].position = (2.0, 3.0, 1.0)
    assert build(scene, upload(scene)) is not marked


@pytest.mark.parametrize("light", ["point", "directional", "wide spot"])
def test_rendered_shadows_do_not_depend_on_the_light_buffers(light, monkeypatch):
    scene = scene_with_floor(bunny(), LIGHTS[light])
    cam = pw.Camera.look_at(eye=(0.0, 0.8, 3.2), target=(0.0, -0.2, 0.0))
    assert_same_shadows_as_the_bvh(scene, cam, (160, 120), monkeypatch)


def test_a_light_over_the_entry_budget_leaves_its_rays_to_the_bvh(monkeypatch):
    import pbrwarp.light_buffers as light_buffers

    scene = scene_with_floor(icosphere(3), pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    scene.add_light(pw.DirectionalLight(direction=(-0.5, -1.0, -0.3), intensity=3.0))
    monkeypatch.setattr(light_buffers, "MAX_ENTRIES_PER_CELL", 0)
    monkeypatch.setattr(light_buffers, "MAX_ENTRIES_PER_TRIANGLE", 0)
    buffers = build(scene, upload(scene))
    assert [tuple(s) for s in buffers.light_views.numpy()] == [(0, 0), (0, 0)]


@pytest.mark.parametrize("path", GLTF, ids=asset_id)
def test_every_asset_renders_the_same_shadows_with_and_without_light_buffers(path, monkeypatch):
    scene = pw.Scene.load(path)
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    scene.add_light(pw.PointLight(position=tuple(centre + np.array([0.6, 1.2, 0.8]) * radius),
                                  intensity=50.0 * radius * radius))
    scene.add_light(pw.DirectionalLight(direction=(-0.4, -1.0, -0.3), intensity=2.0))
    assert_same_shadows_as_the_bvh(scene, None, (96, 72), monkeypatch)


def test_shadow_cache_keeps_the_shadows_of_every_light(monkeypatch):
    """The shadow cache remembers the last blocker of the first SHADOW_CACHE_LIGHTS lights only:
    with more lights than that, some shadowed by the sphere and some not, every light's shadows
    are still those the BVH alone casts."""
    from pbrwarp.kernels.light_buffer_query import SHADOW_CACHE_LIGHTS

    scene = scene_with_floor(icosphere(4), pw.PointLight(position=(2.0, 3.0, 2.0), intensity=20.0))
    for k in range(SHADOW_CACHE_LIGHTS + 1):
        angle = 2.0 * np.pi * k / (SHADOW_CACHE_LIGHTS + 1)
        scene.add_light(pw.PointLight(position=(2.5 * np.cos(angle), 2.0 + 0.3 * k, 2.5 * np.sin(angle)),
                                      intensity=10.0))
    cam = pw.Camera.look_at(eye=(0.0, 0.8, 3.2), target=(0.0, -0.2, 0.0))
    assert_same_shadows_as_the_bvh(scene, cam, (160, 120), monkeypatch)


@pytest.mark.parametrize("light", ["point", "narrow spot"])
def test_cells_per_radian_bounds_how_fast_directions_cross_cells(light):
    """The light buffer query's fast path keeps a ray in its origin's cell when the origin lies
    farther inside it than the ray's angular drift times cells_per_radian: the bound must hold
    for every pair of nearby directions anywhere in the view (here measured by finite
    differences), and not be loose by more than the corners' stretch."""
    from pbrwarp.light_buffers import RESOLUTION, cells_per_radian
    from pbrwarp.raster import projection
    from pbrwarp.shadow_maps import light_views

    views = [projection(cam) for cam, _ in light_views(LIGHTS[light], np.zeros(3), 2.0, RESOLUTION, 1)]
    rng = np.random.default_rng(5)
    for view in views:
        to_camera = np.array(view.to_camera, dtype=np.float64).reshape(3, 3)
        to_world = np.linalg.inv(to_camera)
        # directions through random points of the view, and ones turned by 1e-6 radians
        screen = rng.uniform(0.0, 1.0, (20_000, 2)) * [view.half_width * 2.0, view.half_height * 2.0]
        camera = np.column_stack([screen[:, 0] / view.half_width - 1.0, 1.0 - screen[:, 1] / view.half_height,
                                  np.ones(len(screen))])
        d = camera @ to_world.T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        turn = np.cross(d, rng.normal(size=d.shape))
        turn /= np.linalg.norm(turn, axis=1, keepdims=True)
        angle = 1e-6
        turned = d * np.cos(angle) + turn * np.sin(angle)
        c = turned @ to_camera.T
        moved = np.column_stack([(c[:, 0] / c[:, 2] + 1.0) * view.half_width,
                                 (1.0 - c[:, 1] / c[:, 2]) * view.half_height])
        rate = np.abs(moved - screen).max(axis=1) / angle
        bound = cells_per_radian(view)
        assert rate.max() <= bound
        assert rate.max() >= bound / 4.0
