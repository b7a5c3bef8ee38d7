"""Light buffers, the shadow rays' acceleration structure (kernels/light_buffer.py): per light, the
triangles seen through each cell of a grid of directions, nearest first. Built on every core from
the same views as the shadow maps and kept in the scene cache (pbrwarp/scene_cache.py) while its
geometry, the lights' placement and which sides of each mesh are shaded stay the same; a shadow
ray tests a handful of triangles instead of walking the BVH, or none from a triangle marked clear
of the light (nothing nearer to the light in its cells lies in front of its plane), from the
marked interior of one (nothing comes near the solid that interior's rays sweep towards the
light), or from a marked region of a large one (a floor, lit but for the shadows on it)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import huge_pages
from .errors import InputError
from .gpu_scene import back_faces_unseen, closed_seen_from, face_flags
from .parallel import run_all, thread_count
from .raster import projection
from .shadow_maps import light_geometry, light_views, view_count
from pbrwarp.kernels import light_buffer as lb
from pbrwarp.kernels.light_buffer_cells import count_cells, fill_cells, nearest_surface_distance
from pbrwarp.kernels.light_buffer_interiors import mark_clear_interiors
from pbrwarp.kernels.light_buffer_marks import finish_cells, mark_clear_triangles
from pbrwarp.kernels.light_buffer_planes import LightPlane, light_planes
from pbrwarp.kernels.light_buffer_regions import mark_clear_regions
from pbrwarp.kernels.loading import load_for_cpu
from pbrwarp.kernels.projection import Projection

# Cells per side of each view: RESOLUTION, which keeps the lists of an 80k-triangle sphere in a
# 90-degree cube face at a few triangles (bench/frames.py), for scenes of up to
# RESOLUTION_TRIANGLES triangles. A denser scene's cells would list many more, and a shadow ray
# tests the triangles its cell lists one by one: its views get finer, their side growing with the
# square root of the triangle count (about as many cells per triangle) in steps of
# RESOLUTION_STEP, within MAX_CELLS cells over all its views (8 bytes each while building, 4
# kept). bench/light_buffer_resolution.py measures the choice.
RESOLUTION = 512
RESOLUTION_TRIANGLES = 100_000
RESOLUTION_STEP = 128
MAX_CELLS = 1 << 23
# Light buffers are not built for a light closer than this fraction of the scene's radius to a
# triangle: its shadow rays would span many cells near the light; they walk the BVH instead.
MIN_CLEARANCE_RADII = 1.0e-4
# Budget of a light's list entries: this many per triangle plus this many per cell of its views.
MAX_ENTRIES_PER_TRIANGLE = 16
MAX_ENTRIES_PER_CELL = 8
# Work items per thread of the stages that split views and lights into blocks; but at most
# BLOCK_ITEMS triangles or regions, and BLOCK_CELLS cells, a block, so that each job lasts a small
# fraction of a second and an interrupt waits for little (a job cannot be stopped once launched,
# and the blocks of a dense scene split only by thread would each take seconds).
WORK_BLOCKS_PER_THREAD = 4
BLOCK_ITEMS = 1 << 14
BLOCK_CELLS = 1 << 15
# Fraction taken off the float32 distance from a light to the nearest surface.
CLEARANCE_MARGIN = 1.0e-3
# Regions of a large triangle (kernels/light_buffer_regions.mark_clear_regions) span about
# REGION_CELLS cells across as the light sees them: smaller ones follow a shadow's outline more
# closely and cost more to mark. A triangle not clear of a light gets a grid of regions if it has at least
# MIN_REGION_GRID of them per side, of at most MAX_REGION_GRID (65,536 flags); a light gets at
# most MAX_REGIONS_PER_LIGHT flags, all lights together MAX_REGIONS (bytes of memory).
REGION_CELLS = 16
MIN_REGION_GRID = 4
MAX_REGION_GRID = 256
MAX_REGIONS_PER_LIGHT = 1 << 22
MAX_REGIONS = 1 << 25
# Triangles sized for regions at a time.
REGION_SIZING_BLOCK = 1 << 18


def launch_threads(items: int) -> int:
    """Launch dimension for ``items`` handled lb.ITEMS_PER_THREAD per Warp thread."""
    return -(-items // int(lb.ITEMS_PER_THREAD))


def _light_point(light):
    """A light's position, None for a directional light (infinitely far away)."""
    return np.asarray(light.position, dtype=np.float64) if hasattr(light, "position") else None


def _per_light_face_flags(scene, gpu, kind: str, seen_from) -> list[wp.array]:
    """Per light of ``scene``, gpu_scene.face_flags of ``seen_from(scene, prim, the light's point)``."""
    return [face_flags(scene, gpu, kind, [seen_from(scene, prim, _light_point(light)) for prim in scene.primitives])
            for light in scene.punctual_lights]


def front_only_faces(scene, gpu) -> list[wp.array]:
    """Per light of ``scene``, per triangle (uint8): 1 where the triangle is shaded from its front
    only, as the light sees the scene: its mesh's back faces are never seen from the light's
    position (gpu_scene.back_faces_unseen). There a triangle facing away from the light sends no
    shadow ray towards it, and its marks are not worth making
    (kernels/light_buffer_planes.no_shadow_rays_leave). A camera that does see such back faces
    (one inside a closed mesh that the light is outside of) gets their shadows by queries."""
    return _per_light_face_flags(scene, gpu, "front only", back_faces_unseen)


def closed_faces(scene, gpu) -> list[wp.array]:
    """Per light of ``scene``, per triangle (uint8): 1 where the triangle's mesh is an opaque
    closed volume with the light outside (gpu_scene.closed_seen_from). Its triangles facing away
    from the light are not listed (kernels/light_buffer_planes.never_first_blocker): whatever
    they would block, one facing the light blocks too."""
    return _per_light_face_flags(scene, gpu, "closed", closed_seen_from)


def resolution(triangles: int, views: int) -> int:
    """Cells per side of each light-buffer view of a scene with this many triangles and views
    (over all its lights): RESOLUTION up to about RESOLUTION_TRIANGLES triangles, then growing
    with the square root of the count, to the nearest multiple of RESOLUTION_STEP, and never so
    large that the views hold over MAX_CELLS cells between them (unless RESOLUTION does)."""
    wanted = RESOLUTION * math.sqrt(max(triangles, 1) / RESOLUTION_TRIANGLES)
    wanted = RESOLUTION_STEP * round(wanted / RESOLUTION_STEP)
    within_budget = RESOLUTION_STEP * math.floor(math.sqrt(MAX_CELLS / max(views, 1)) / RESOLUTION_STEP)
    return max(RESOLUTION, min(wanted, within_budget))


def scene_resolution(scene) -> int:
    """resolution() for ``scene``: its triangles, and the views of all its lights. Cheap (no
    bounds, no views made): every render's explain text asks for it."""
    return resolution(scene.triangle_count, sum(view_count(light) for light in scene.punctual_lights))


@dataclass(frozen=True)
class _Kept:
    """The scene cache's "light buffers" value: the buffers, and whether their interiors are marked."""

    buffers: lb.LightBuffers
    marked: bool


def build(scene, gpu, threads: int | None = None) -> lb.LightBuffers:
    """The light buffers of every light of ``scene`` (uploaded as ``gpu``), kept in the scene cache.

    Triangle interiors are marked clear (kernels/light_buffer_interiors.mark_clear_interiors) when the
    buffers are first reused, for a second frame: the marks can cost as much as the rest of the
    build and pay off only over frames whose lights and geometry stay put, so a light moving every
    frame never pays for them. No triangle is marked where no shadow ray leaves it
    (front_only_faces). The marks go into a copy that then replaces the kept buffers
    (mark_interiors), made by the first render that reuses them: renders under way keep reading
    the unmarked buffers, and renders starting while the copy is made render with them too (the
    marks only spare queries, whose answers they already know)."""
    # the materials' sides and cut-outs decide which triangles are listed and marked
    # (front_only_faces, closed_faces)
    sides = tuple((p.material.double_sided, p.material.alpha_mode == "MASK") for p in scene.primitives)
    key = (gpu.geometry, tuple(light_geometry(light) for light in scene.punctual_lights), sides)
    threads = thread_count(threads)
    kept = scene.cache.lookup("light buffers", key)
    if kept is None:  # a first frame, or one rendered while another thread builds them
        return scene.cache.get("light buffers", key, lambda: _Kept(_build(scene, gpu, threads), False)).buffers
    if not kept.marked:
        kept = scene.cache.improve("light buffers", key, kept,
                                   lambda unmarked: _Kept(mark_interiors(scene, gpu, unmarked.buffers, threads), True))
    return kept.buffers


def _build(scene, gpu, threads: int) -> lb.LightBuffers:
    """build's light buffers, their triangles marked clear as a whole but no interiors."""
    for kernel in (nearest_surface_distance, count_cells, fill_cells, light_planes, finish_cells,
                   mark_clear_triangles, mark_clear_interiors):
        load_for_cpu(kernel)
    positions, indices = gpu.data.positions, gpu.data.indices
    triangles = len(indices) // 3
    front_only = front_only_faces(scene, gpu)
    closed = closed_faces(scene, gpu)
    lo, hi = scene.bounds()
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-30)
    clearances = _clearances(gpu, scene.punctual_lights)
    side = scene_resolution(scene)
    views, spans, view_closed = [], [], []
    for light, clearance, light_closed in zip(scene.punctual_lights, clearances, closed):
        if clearance < MIN_CLEARANCE_RADII * radius:
            spans.append((0, 0))
            continue
        try:
            light_projections = [projection(cam, orthographic=bool(view.orthographic))
                                 for cam, view in light_views(light, center, radius, side, 1)]
        except InputError:  # a scene so large that its views overflow: the BVH handles it
            spans.append((0, 0))
            continue
        spans.append((len(views), len(light_projections)))
        views += light_projections
        view_closed += [light_closed] * len(light_projections)
    cells = side * side
    # the large arrays on huge pages: their first touch would fault once per 4 KiB page
    counts = huge_pages.zeros(max(len(views), 1) * cells, wp.int32)

    def count(v):
        wp.launch(count_cells, dim=launch_threads(triangles), device="cpu",
                  inputs=[positions, indices, views[v], v * cells, triangles, view_closed[v], counts])

    run_all(count, range(len(views)), threads)
    per_cell = counts.numpy().reshape(-1, cells)
    view_entries = per_cell.sum(axis=1, dtype=np.int64)
    kept = []
    for k, (first, n) in enumerate(spans):
        # a light whose lists would outgrow the budget (huge or degenerate geometry seen edge-on)
        # leaves its shadow rays to the BVH
        budget = MAX_ENTRIES_PER_TRIANGLE * triangles + MAX_ENTRIES_PER_CELL * n * cells
        if n and view_entries[first:first + n].sum() > budget:
            per_cell[first:first + n] = 0
            view_entries[first:first + n] = 0
            spans[k] = (0, 0)
        else:
            kept += range(first, first + n)
    total = int(view_entries.sum())
    if total >= 2**31:
        raise InputError(f"light buffers too large: {total} cell entries; use shadows='map'")
    cell_start = huge_pages.empty(per_cell.size + 1, wp.int32)
    start = cell_start.numpy()  # a view
    start[0] = 0
    np.cumsum(per_cell.reshape(-1), dtype=np.int32, out=start[1:])  # in int32 (no overflow: total < 2^31)
    del per_cell, counts  # freed before the cursors are made: 8 bytes a cell at most while building
    cursors = huge_pages.empty(len(start) - 1, wp.int32)
    cursors.numpy()[:] = start[:-1]
    entries = max(total, 1)
    cell_faces = huge_pages.empty(entries, wp.int32)
    cell_near = huge_pages.empty(entries, float)
    cell_clear = huge_pages.zeros(entries, wp.uint8)

    def fill(v):
        wp.launch(fill_cells, dim=launch_threads(triangles), device="cpu",
                  inputs=[positions, indices, views[v], v * cells, triangles, view_closed[v], cursors, cell_faces,
                          cell_near])

    # views no triangle is seen in (often half of a point light's cube) need no more work
    run_all(fill, [v for v in kept if view_entries[v]], threads)
    # per light: its triangles' planes, then its lists sorted and entries marked, and later the
    # triangles marked, in blocks that spread every view's work over the threads (the mesh often
    # fills one or two faces)
    blocks = WORK_BLOCKS_PER_THREAD * threads
    rows = max(min(-(-side // blocks), BLOCK_CELLS // side), 1)
    planes = wp.empty(max(triangles, 1), dtype=LightPlane, device="cpu")
    for light, (first, n) in enumerate(spans):
        if n == 0:
            continue

        def plane(block, view=views[first], light_front_only=front_only[light]):
            start, end = block
            wp.launch(light_planes, dim=launch_threads(end - start), device="cpu",
                      inputs=[positions, indices, view, start, end, light_front_only, planes])

        def finish(job):
            v, row = job
            wp.launch(finish_cells, dim=min(rows, side - row), device="cpu",
                      inputs=[positions, indices, planes, side, v * cells + row * side, cell_start,
                              cell_faces, cell_near, cell_clear])

        def filled(v, row):
            block = v * cells + row * side
            return start[min(block + rows * side, (v + 1) * cells)] > start[block]

        run_all(plane, _work_blocks(triangles, threads), threads)
        run_all(finish, [(v, row) for v in range(first, first + n) for row in range(0, side, rows)
                         if filled(v, row)], threads)
    buffers = lb.LightBuffers()
    buffers.views = wp.array(views if views else [Projection()], dtype=Projection, device="cpu")
    buffers.view_cells_per_radian = wp.array([cells_per_radian(view) for view in views] or [0.0], dtype=wp.float64,
                                             device="cpu")
    buffers.light_views = wp.array(spans if spans else [(0, 0)], dtype=wp.vec2i, device="cpu")
    buffers.clearance = wp.array([min(c, 3e38) for c in clearances] or [0.0], dtype=float, device="cpu")
    buffers.cell_start, buffers.cell_faces, buffers.cell_near = cell_start, cell_faces, cell_near
    buffers.cell_clear = cell_clear
    buffers.triangle_clear = wp.zeros(max(len(scene.punctual_lights) * triangles, 1), dtype=wp.uint8, device="cpu")
    buffers.region_grids, buffers.region_clear = _no_regions()
    buffers.triangles = triangles
    buffers.resolution = side
    _mark_triangles(mark_clear_triangles, buffers, gpu, threads, front_only, parallel_views=False)
    return buffers


def mark_interiors(scene, gpu, buffers: lb.LightBuffers, threads: int) -> lb.LightBuffers:
    """A copy of ``scene``'s light ``buffers`` (``scene`` uploaded as ``gpu``) with the interiors
    of the triangles not clear of their lights as a whole marked
    (kernels/light_buffer_interiors.mark_clear_interiors), then the regions of the large ones left
    (mark_clear_regions), every light's, but for the triangles no shadow ray leaves
    (front_only_faces); build makes it on the first reuse. ``buffers`` are not changed (renders
    may be reading them); the copy shares all their arrays but the marks and the regions. Marks
    already made are kept, and no regions are added where there are some."""
    marked = lb.LightBuffers()
    for field in lb.LightBuffers.vars:
        setattr(marked, field, getattr(buffers, field))
    marked.triangle_clear = wp.clone(buffers.triangle_clear)
    front_only = front_only_faces(scene, gpu)
    _mark_triangles(mark_clear_interiors, marked, gpu, threads, front_only, parallel_views=True)
    _mark_regions(scene, marked, gpu, threads, front_only)
    return marked


def _no_regions():
    return wp.zeros(1, dtype=wp.vec2i, device="cpu"), wp.zeros(1, dtype=wp.uint8, device="cpu")


def region_grid_sizes(buffers: lb.LightBuffers, light: int, corners: np.ndarray,
                      front_only: np.ndarray | None = None) -> np.ndarray:
    """Per triangle (``corners``: (n, 3, 3) float64), the side of a grid of regions REGION_CELLS
    cells across as ``light``'s views see them (0 where fewer than MIN_REGION_GRID, and where
    ``front_only`` (bool per triangle, as front_only_faces) is set and the light lies behind the
    triangle's front: no shadow ray leaves it): the longest edge over the nearest the triangle may
    come to the light (no nearer than its clearance), in cells per radian, or in a parallel view
    in cells per unit."""
    view, scale = _cell_scale(buffers, light)
    longest = _longest_edge(corners)
    if view["orthographic"]:
        towards_light = np.broadcast_to(-np.asarray(view["to_camera"], dtype=np.float64).reshape(3, 3)[2],
                                        (len(corners), 3))
        across = longest * scale
    else:
        towards_light = np.asarray(view["eye"], dtype=np.float64) - corners[:, 0]
        to_corners = np.min(np.linalg.norm(corners - np.asarray(view["eye"], dtype=np.float64), axis=2), axis=1)
        nearest = np.maximum(to_corners - longest, float(buffers.clearance.numpy()[light]))
        across = np.divide(longest, nearest, out=np.full_like(longest, np.inf), where=nearest > 0) * scale
    size = np.minimum(np.ceil(across / REGION_CELLS), MAX_REGION_GRID)
    if front_only is not None:
        front = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        size[front_only & (np.einsum("ij,ij->i", front, towards_light) < 0.0)] = 0
    return np.where(size >= MIN_REGION_GRID, size, 0).astype(np.int64)


def _mark_regions(scene, buffers: lb.LightBuffers, gpu, threads: int, front_only: list[wp.array]):
    """Give the largest triangles not otherwise marked for a light (at most MAX_REGION_TRIANGLES)
    grids of regions, mark which are clear, then point the triangles' marks at their grids;
    nothing where marks point at grids already (new grids would replace the ones they index)."""
    triangles = buffers.triangles
    spans = buffers.light_views.numpy()
    marks = buffers.triangle_clear.numpy()  # a view
    if np.any(marks >= int(lb.REGIONS_CLEAR)):
        return
    positions = gpu.data.positions.numpy()
    faces = gpu.data.indices.numpy().reshape(-1, 3)
    per_light = int(lb.MAX_REGION_TRIANGLES)
    grids = np.zeros((len(spans) * per_light, 2), dtype=np.int32)
    chosen = []  # (light, slot, face)
    total = 0
    longest = _longest_edges(scene, gpu, faces, positions)
    for light, (_, count) in enumerate(spans):
        if count == 0:
            continue
        unmarked = np.flatnonzero(marks[light * triangles:(light + 1) * triangles] == int(lb.NOT_CLEAR))
        # the float64 sizing only for triangles long enough to get regions however near the light
        unmarked = unmarked[longest[unmarked] > _shortest_region_triangle(buffers, light)]
        if len(unmarked) == 0:
            continue
        # in blocks: a large mesh's corners in float64 would take 72 bytes a triangle at once
        light_front_only = front_only[light].numpy() != 0
        size = np.concatenate([region_grid_sizes(buffers, light, positions[faces[block]].astype(np.float64),
                                                 light_front_only[block])
                               for block in np.array_split(unmarked, -(-len(unmarked) // REGION_SIZING_BLOCK))])
        order = np.argsort(-size, kind="stable")[:per_light]
        flags = 0
        for slot, k in enumerate(order[size[order] > 0]):
            n = int(size[k])
            if flags + n * n > MAX_REGIONS_PER_LIGHT or total + n * n > MAX_REGIONS:
                break
            grids[light * per_light + slot] = (n, total)
            chosen.append((light, slot, int(unmarked[k])))
            flags += n * n
            total += n * n
    if not chosen:
        return
    buffers.region_grids = wp.array(grids, dtype=wp.vec2i, device="cpu")
    buffers.region_clear = huge_pages.zeros(total, wp.uint8)

    def mark(job):
        light, slot, face, start, end = job
        n, first = (int(x) for x in grids[light * per_light + slot])
        wp.launch(mark_clear_regions, dim=launch_threads(end - start), device="cpu",
                  inputs=[buffers, light, gpu.data.positions, gpu.data.indices, face, wp.vec2i(n, first), start, end])

    load_for_cpu(mark_clear_regions)
    jobs = []
    for light, slot, face in chosen:
        n = int(grids[light * per_light + slot][0])
        for start, end in _work_blocks(n * n, threads):
            jobs.append((light, slot, face, start, end))
    run_all(mark, jobs, threads)
    # the marks last, once the flags they point to are all written
    for light, slot, face in chosen:
        marks[light * triangles + face] = int(lb.REGIONS_CLEAR) + slot


def _longest_edges(scene, gpu, faces: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per triangle of ``gpu`` (``scene`` uploaded, its ``faces`` and ``positions`` as NumPy
    arrays), its longest edge (float32), kept in the scene cache while the geometry stays."""
    def measure():
        longest = np.empty(len(faces), dtype=np.float32)
        for start in range(0, len(faces), REGION_SIZING_BLOCK):
            corners = positions[faces[start:start + REGION_SIZING_BLOCK]]
            longest[start:start + len(corners)] = _longest_edge(corners)
        longest.setflags(write=False)  # shared by every thread that marks
        return longest

    return scene.cache.get("longest edges", gpu.geometry, measure)


def _longest_edge(corners: np.ndarray) -> np.ndarray:
    """Per triangle (``corners``: (n, 3, 3)), the length of its longest edge, in corners' dtype."""
    return np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1, initial=0.0)


def _shortest_region_triangle(buffers: lb.LightBuffers, light: int) -> float:
    """A longest edge below which region_grid_sizes gives a triangle no regions for ``light``
    wherever it lies: (MIN_REGION_GRID - 1) REGION_CELLS cells across at the light's clearance
    (pinhole views), less 1% for the float32 edge lengths."""
    view, scale = _cell_scale(buffers, light)
    cells = (MIN_REGION_GRID - 1) * REGION_CELLS * 0.99
    if view["orthographic"]:
        return cells / scale
    return cells * float(buffers.clearance.numpy()[light]) / scale


def _cell_scale(buffers: lb.LightBuffers, light: int):
    """(the first view of ``light`` as a numpy record, how many cells its views cross per unit of
    length (a parallel view) or at most per radian (pinhole views))."""
    first, count = buffers.light_views.numpy()[light]
    view = buffers.views.numpy()[first]
    if view["orthographic"]:
        rows = np.asarray(view["to_camera"], dtype=np.float64).reshape(3, 3)
        return view, max(view["half_width"] * np.linalg.norm(rows[0]), view["half_height"] * np.linalg.norm(rows[1]))
    return view, float(buffers.view_cells_per_radian.numpy()[first:first + count].max())


def _mark_triangles(kernel, buffers: lb.LightBuffers, gpu, threads: int, front_only: list[wp.array],
                    parallel_views: bool):
    """``kernel`` (mark_clear_triangles or mark_clear_interiors) over every triangle and light with
    buffers (those of parallel views, directional lights', too if ``parallel_views``), in blocks
    spread over the threads; ``front_only`` per light, as front_only_faces."""
    views = buffers.views.numpy()
    spans = buffers.light_views.numpy()
    lights = [k for k, (first, n) in enumerate(spans) if n and (parallel_views or not views[first]["orthographic"])]

    def mark(job):
        light, (start, end) = job
        wp.launch(kernel, dim=launch_threads(end - start), device="cpu",
                  inputs=[buffers, light, gpu.data.positions, gpu.data.indices, front_only[light], start, end])

    run_all(mark, [(light, block) for light in lights for block in _work_blocks(buffers.triangles, threads)],
            threads)


def _work_blocks(items: int, threads: int) -> list[tuple[int, int]]:
    """[start, end) blocks of ``items`` (triangles, regions), WORK_BLOCKS_PER_THREAD per thread,
    or more, of BLOCK_ITEMS each."""
    per_block = max(min(-(-items // (WORK_BLOCKS_PER_THREAD * threads)), BLOCK_ITEMS), 1)
    return [(start, min(start + per_block, items)) for start in range(0, items, per_block)]


def cells_per_radian(view: Projection) -> float:
    """A bound, anywhere in a pinhole view, on the cells a direction crosses per radian it turns
    (0 for a parallel view): the half-size over the tangent of the half-angle, times 1 + tan^2 of
    the angle off the axis, at most 1 + tan_x^2 + tan_y^2 at the view's corners."""
    if view.orthographic:
        return 0.0
    rows = np.array(view.to_camera, dtype=np.float64).reshape(3, 3)
    tan_x, tan_y = 1.0 / np.linalg.norm(rows[0]), 1.0 / np.linalg.norm(rows[1])
    stretch = 1.0 + tan_x * tan_x + tan_y * tan_y
    return max(view.half_width / tan_x, view.half_height / tan_y) * stretch


def _clearances(gpu, lights) -> list[float]:
    """Per light, a distance within which no triangle lies (of its position; infinite for a
    directional light): the nearest surface point's distance, less a margin for its rounding."""
    positional = [light for light in lights if hasattr(light, "position")]
    distances = iter([])
    if positional:
        points = wp.array(np.array([light.position for light in positional], np.float32), dtype=wp.vec3, device="cpu")
        out = wp.empty(len(positional), dtype=float, device="cpu")
        wp.launch(nearest_surface_distance, dim=len(positional), inputs=[gpu.data.mesh, points, out], device="cpu")
        distances = iter(out.numpy().astype(np.float64) * (1.0 - CLEARANCE_MARGIN))
    return [next(distances) if hasattr(light, "position") else np.inf for light in lights]


@functools.cache
def no_light_buffers() -> lb.LightBuffers:
    """Light buffers for no light: the render kernel's argument when it traces no shadow rays; given
    with shadow rays, every light's rays go to the BVH."""
    buffers = lb.LightBuffers()
    buffers.views = wp.array([Projection()], dtype=Projection, device="cpu")
    buffers.view_cells_per_radian = wp.zeros(1, dtype=wp.float64, device="cpu")
    buffers.light_views = wp.array([(0, 0)], dtype=wp.vec2i, device="cpu")
    buffers.clearance = wp.zeros(1, dtype=float, device="cpu")
    buffers.cell_start = wp.zeros(2, dtype=wp.int32, device="cpu")
    buffers.cell_faces = wp.zeros(1, dtype=wp.int32, device="cpu")
    buffers.cell_near = wp.zeros(1, dtype=float, device="cpu")
    buffers.cell_clear = wp.zeros(1, dtype=wp.uint8, device="cpu")
    buffers.triangle_clear = wp.zeros(1, dtype=wp.uint8, device="cpu")
    buffers.region_grids, buffers.region_clear = _no_regions()
    buffers.triangles = 0
    buffers.resolution = 1
    return buffers
