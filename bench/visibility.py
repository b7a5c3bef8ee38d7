"""Primary visibility: the rasterized visibility buffer vs Warp ray casting vs Open3D (Embree).

    python bench/visibility.py [--repeats 5] [--quick] [--framing hull|sphere]

Samples per second (one per pixel, every pixel counted, hit or not) of
- raster: pbrwarp.raster.visibility_buffer, whole frame (projection, binning, rasterization;
  the camera-independent sample positions are cached after the warm-up), on 1 and all threads;
- ray cast: wp.mesh_query_ray from the eye per pixel, one launch per thread taking rows from a
  shared counter as the renderer's do (pbrwarp.render.ROWS_PER_TAKE at a time);
- Open3D's RaycastingScene.cast_rays (Embree, all cores) on the same rays, precomputed,
  when open3d is installed.
The raster culls the mesh's clusters (pbrwarp.raster.triangle_clusters, as pw.render does), and
is also timed without them; and with every back face culled, as pw.render draws single-sided
meshes (glTF's default) and closed ones seen from outside: for the closed icospheres the buffer
names the same triangles. Meshes: an icosphere and the Stanford bunny at 512², 1024², 2048²; icospheres of 20k
to 1.3M triangles, Suzanne subdivided to 15k, the happy Buddha to 1.6M triangles and a 2M-triangle
terrain (a 1000 x 1000 height field seen at a slant) at 1024². Also the
raster's time split (binning vs rasterization) and least-squares cost models, time = a triangles
+ b samples for the raster and c samples log2(triangles) for the ray cast, whose constants
pbrwarp/raster.py keeps. Medians of --repeats runs after a warm-up.
The camera fits the mesh's convex hull (Camera.frame); with --framing sphere it fits the mesh's
bounding sphere instead (1.1 times its radius inside the 45 degree field of view), which leaves
the mesh smaller on screen: the view results recorded before Camera.frame fitted the hull used,
for comparing code across that change.
Writes bench/results/visibility.{md,json} (visibility_sphere.{md,json} with --framing sphere).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import DivisibleWork, command_line, median_time, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp.gpu_scene import upload  # noqa: E402
from pbrwarp.kernels import stages  # noqa: E402
from pbrwarp.kernels.camera import CameraData, camera_ray_direction  # noqa: E402
from pbrwarp.kernels.loading import load_for_cpu  # noqa: E402
from pbrwarp.kernels.robust import RAY_FAR  # noqa: E402
from pbrwarp.meshes import asset, bunny, icosphere  # noqa: E402
from pbrwarp.raster import CLUSTER_SIZE, decode, visibility_buffer  # noqa: E402
from pbrwarp.kernels.work_queue import take_next_item  # noqa: E402
from pbrwarp.parallel import run_all  # noqa: E402
from pbrwarp.render import ROWS_PER_TAKE, _camera_data  # noqa: E402


@wp.kernel(enable_backward=False)
def ray_cast_rows(mesh: wp.uint64, cam: CameraData, rows: wp.array(dtype=wp.int32), rows_per_take: int,
                  out_face: wp.array2d(dtype=wp.int32)):
    """Nearest triangle through each pixel centre, as render_tile finds it, rows_per_take rows at
    a time taken from the counter ``rows`` until none are left."""
    first_row = take_next_item(rows) * rows_per_take
    while first_row < cam.height:
        for py in range(first_row, wp.min(first_row + rows_per_take, cam.height)):
            for px in range(cam.width):
                q = wp.mesh_query_ray(mesh, cam.eye, camera_ray_direction(cam, float(px) + 0.5, float(py) + 0.5),
                                      RAY_FAR)
                out_face[py, px] = wp.where(q.result, q.face, -1)
        first_row = take_next_item(rows) * rows_per_take


def ray_cast(geom, cam, threads, out):
    rows = wp.zeros(1, dtype=wp.int32, device="cpu")
    run_all(lambda _: wp.launch(ray_cast_rows, dim=1, inputs=[geom.mesh.id, cam, rows, ROWS_PER_TAKE, out],
                                device="cpu"), range(threads), threads)


def open3d_scene(mesh):
    try:
        import open3d as o3d
    except ImportError:
        return None
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    return scene


def on_core(core, fn):
    """fn() with the calling thread held to CPU ``core``, then free again."""
    allowed = os.sched_getaffinity(0)  # pid 0: the calling thread
    os.sched_setaffinity(0, {core})
    try:
        return fn()
    finally:
        os.sched_setaffinity(0, allowed)


def sphere_framed(scene, direction, fov_y=45.0, margin=1.1):
    """A camera looking at the scene's bounding sphere (of its bounding box) from ``direction``,
    the sphere ``margin`` times its radius inside the vertical field of view."""
    lo, hi = scene.bounds()
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    d = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    distance = margin * radius / math.sin(math.radians(fov_y) / 2.0)
    return pw.Camera.look_at(centre + d * distance, centre, fov_y=fov_y)


def bench_case(label, mesh, size, repeats, threads_all, framing="hull"):
    scene = pw.Scene()
    scene.add_mesh(mesh, pw.Material())
    geometry = upload(scene)._keep[0]
    direction = (0.3, 0.4, 1.0)
    camera = pw.Camera.frame(scene, direction=direction) if framing == "hull" else sphere_framed(scene, direction)
    cam = _camera_data(camera, size, size)
    samples = size * size
    triangles = len(mesh.faces)
    row = {"mesh": label, "triangles": triangles, "size": size, "samples": samples}

    buffer = wp.empty((size, size), dtype=wp.uint64, device="cpu")

    every_face = wp.ones(triangles, dtype=wp.uint8, device="cpu")

    def raster(threads, out=buffer, timings=None, cull=None, clusters=geometry.clusters, counts=None):
        return visibility_buffer(geometry.positions, geometry.indices, cam, threads=threads, out=out, timings=timings,
                                 cull_back_faces=cull, clusters=clusters, counts=counts)

    # In each round: one thread; all threads right after it (the pool thread asleep, as after any
    # pause); the divisible yardstick on one thread; then, the pool awake (as in a frame, whose
    # other stages keep it busy), all threads with reused and new buffers, with and without
    # clusters, and the yardstick, in turn, so that a burst of load on this shared machine slows
    # every variant alike rather than one of them (their ratios matter).
    raster(1)
    clock = time.perf_counter()
    raster(1)
    yardstick = DivisibleWork(time.perf_counter() - clock, threads_all)
    awake = {f"raster_ms_{threads_all}t": (threads_all, buffer, None, geometry.clusters),
             f"raster_new_buffer_ms_{threads_all}t": (threads_all, None, None, geometry.clusters),
             f"raster_culled_ms_{threads_all}t": (threads_all, buffer, every_face, geometry.clusters),
             f"raster_without_clusters_ms_{threads_all}t": (threads_all, buffer, None, None),
             f"divisible_ms_{threads_all}t": None}
    # one thread on each core in turn: the cores of a virtual machine need not run at the same pace
    # (the host may share one's physical core), which bounds what two threads can gain
    cores = sorted(os.sched_getaffinity(0))[:threads_all] if hasattr(os, "sched_setaffinity") else []
    times = {key: [] for key in ["raster_ms_1t", f"raster_after_one_thread_ms_{threads_all}t", "divisible_ms_1t",
                                 *awake, *(f"raster_ms_1t_core{core}" for core in cores)]}
    splits = []

    def timed(key, fn):
        t0 = time.perf_counter()
        fn()
        if repeat:
            times[key].append(time.perf_counter() - t0)

    keys = list(awake)
    for repeat in range(repeats + 1):  # the first round warms up
        timed("raster_ms_1t", lambda: raster(1))
        timed(f"raster_after_one_thread_ms_{threads_all}t", lambda: raster(threads_all))
        timed("divisible_ms_1t", yardstick.one)
        yardstick.wake()
        for key in keys[repeat % len(keys):] + keys[:repeat % len(keys)]:
            if awake[key] is None:
                timed(key, yardstick.split)
            else:
                threads, out, cull, clusters = awake[key]
                timed(key, lambda: raster(threads, out, None, cull, clusters))
        for core in cores:
            timed(f"raster_ms_1t_core{core}", lambda: on_core(core, lambda: raster(1)))
        # the split in a call of its own, as timing the parts apart stops the launches between them
        split = {}
        raster(threads_all, buffer, split)
        if repeat:
            splits.append(split)
    for key, seconds in times.items():
        row[key] = 1e3 * statistics.median(seconds)
    row["raster_ms_1t_per_core"] = [row.pop(f"raster_ms_1t_core{core}") for core in cores]

    def round_speedups(one_thread, all_threads):
        # each round's ratio: both calls come within ~0.1 s of each other, so a drift of this
        # shared machine's speed between rounds cancels out
        return [a / b for a, b in zip(times[one_thread], times[all_threads])]

    for key, one_thread, all_threads in (
            ("raster_speedup", "raster_ms_1t", f"raster_ms_{threads_all}t"),
            ("raster_speedup_after_one_thread", "raster_ms_1t", f"raster_after_one_thread_ms_{threads_all}t"),
            ("divisible_speedup", "divisible_ms_1t", f"divisible_ms_{threads_all}t")):
        ratios = round_speedups(one_thread, all_threads)
        row[key] = statistics.median(ratios)
        quartiles = statistics.quantiles(ratios, n=4)
        row[f"{key}_quartiles"] = [quartiles[0], quartiles[2]]
    row["binning_ms"] = 1e3 * statistics.median(t["binning"] for t in splits)
    row["rasterization_ms"] = 1e3 * statistics.median(t["raster"] for t in splits)

    faces = wp.empty((size, size), dtype=wp.int32, device="cpu")
    load_for_cpu(ray_cast_rows)
    row[f"raycast_ms_{threads_all}t"] = 1e3 * median_time(lambda: ray_cast(geometry, cam, threads_all, faces), repeats)
    counts, culled_counts = {}, {}
    ids, _ = decode(raster(threads_all, counts=counts))
    raster(threads_all, cull=every_face, counts=culled_counts)
    row["clusters"] = counts["clusters"]
    row["clusters_occluded"] = counts["occluded"] / counts["clusters"]
    row["clusters_facing_away_culled"] = culled_counts["facing_away"] / counts["clusters"]
    row["clusters_occluded_culled"] = culled_counts["occluded"] / counts["clusters"]
    row["same_buffer_without_clusters"] = bool(np.array_equal(raster(threads_all).numpy().copy(),
                                                              raster(threads_all, clusters=None).numpy()))
    row["coverage"] = float((ids >= 0).mean())
    row["same_triangle"] = float((ids == faces.numpy()).mean())
    row["culled_same_triangle"] = float((decode(raster(threads_all, cull=every_face))[0] == ids).mean())

    o3d = open3d_scene(mesh)
    if o3d is not None:
        import open3d

        dirs = wp.empty(samples, dtype=wp.vec3, device="cpu")
        wp.launch(stages.primary_ray_directions, dim=samples, inputs=[cam, dirs], device="cpu")
        rays = np.hstack([np.broadcast_to(np.asarray(camera.eye, np.float32), (samples, 3)), dirs.numpy()])
        rays = open3d.core.Tensor(rays.astype(np.float32))
        row["embree_ms"] = 1e3 * median_time(lambda: o3d.cast_rays(rays), repeats)

    for key in [k for k in row if k.endswith("_ms") or "_ms_" in k]:
        if (key not in ("binning_ms", "rasterization_ms", "raster_ms_1t_per_core")
                and not key.startswith("divisible")):
            row[key.replace("_ms", "_msamples_per_s")] = samples / row[key] / 1e3
    if "embree_ms" in row:
        row["raster_to_embree"] = row["embree_ms"] / row[f"raster_ms_{threads_all}t"]
        row["culled_raster_to_embree"] = row["embree_ms"] / row[f"raster_culled_ms_{threads_all}t"]
    return row


def fit_cost_models(rows, threads_all):
    """Least-squares constants (seconds per unit) of the raster and ray-cast time models."""
    tris = np.array([r["triangles"] for r in rows], float)
    samples = np.array([r["samples"] for r in rows], float)
    raster = np.array([r[f"raster_ms_{threads_all}t"] for r in rows]) * 1e-3
    raycast = np.array([r[f"raycast_ms_{threads_all}t"] for r in rows]) * 1e-3
    # relative errors matter equally for small and large frames: weight rows by 1 / time
    a, b = np.linalg.lstsq(np.stack([tris, samples], 1) / raster[:, None], np.ones_like(raster), rcond=None)[0]
    (c,) = np.linalg.lstsq((samples * np.log2(tris))[:, None] / raycast[:, None], np.ones_like(raycast), rcond=None)[0]
    model = {"raster_seconds_per_triangle": a, "raster_seconds_per_sample": b,
             "raycast_seconds_per_sample_log2_triangle": c}
    for r in rows:
        r["raster_model_ms"] = 1e3 * (a * r["triangles"] + b * r["samples"])
        r["raycast_model_ms"] = 1e3 * c * r["samples"] * math.log2(r["triangles"])
    return model


def spread(quartiles):
    return f"[{quartiles[0]:.2f}-{quartiles[1]:.2f}]"


def markdown(rows, model, threads_all):
    t = threads_all
    lines = [
        f"| mesh | triangles | size | raster ms 1t / {t}t | speedup [middle half of rounds] (right after a 1t call) | "
        f"divisible kernel's speedup [middle half] | raster ms 1t on each core | "
        f"{t}t with a new buffer | binning / rasterization ms {t}t | "
        f"without clusters ms {t}t | back faces culled ms {t}t | ray cast ms {t}t | Embree ms | "
        f"raster / ray cast / Embree Msamples/s | raster ÷ Embree (culled) | clusters occluded (culled: facing away + occluded) | "
        f"model raster / ray cast ms | coverage | same triangle (culled) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        embree_ms = f"{r['embree_ms']:.1f}" if "embree_ms" in r else "n/a"
        embree_rate = f"{r['embree_msamples_per_s']:.1f}" if "embree_ms" in r else "n/a"
        ratio = (f"{r['raster_to_embree']:.2f}x ({r['culled_raster_to_embree']:.2f}x)" if "raster_to_embree" in r
                 else "n/a")
        lines.append(
            f"| {r['mesh']} | {r['triangles']:,} | {r['size']}² | {r['raster_ms_1t']:.1f} / {r[f'raster_ms_{t}t']:.1f} | "
            f"{r['raster_speedup']:.2f}x {spread(r['raster_speedup_quartiles'])} "
            f"({r['raster_speedup_after_one_thread']:.2f}x) | "
            f"{r['divisible_speedup']:.2f}x {spread(r['divisible_speedup_quartiles'])} | "
            f"{' / '.join(f'{ms:.1f}' for ms in r['raster_ms_1t_per_core']) or 'n/a'} | "
            f"{r[f'raster_new_buffer_ms_{t}t']:.1f} | {r['binning_ms']:.1f} / {r['rasterization_ms']:.1f} | "
            f"{r[f'raster_without_clusters_ms_{t}t']:.1f} | "
            f"{r[f'raster_culled_ms_{t}t']:.1f} | {r[f'raycast_ms_{t}t']:.1f} | {embree_ms} | "
            f"{r[f'raster_msamples_per_s_{t}t']:.1f} / {r[f'raycast_msamples_per_s_{t}t']:.1f} / {embree_rate} | {ratio} | "
            f"{100 * r['clusters_occluded']:.0f}% ({100 * r['clusters_facing_away_culled']:.0f}% + "
            f"{100 * r['clusters_occluded_culled']:.0f}%) | "
            f"{r['raster_model_ms']:.1f} / {r['raycast_model_ms']:.1f} | {r['coverage']:.3f} | "
            f"{r['same_triangle']:.5f} ({r['culled_same_triangle']:.5f}) |")
    lines += [
        "",
        "Samples are pixels (spp 1), all counted, hit or not. Raster: whole visibility_buffer call (binning = "
        "buffer clear, vertex projection, small triangles drawn at once, the others' rectangles binned and the "
        "bins laid out; rasterization = the bins filled and the binned triangles drawn, tile by tile; timed in "
        "a call of their own that stops the launches between the two), sample "
        "positions cached, output buffer reused (out=) except in the new-buffer column, whose fresh pages "
        f"page-fault, with the mesh's clusters of {CLUSTER_SIZE} triangles culled where they lie off screen, face away "
        "(if flagged) or lie behind what the clusters facing the eye drew (clusters=, as pw.render passes "
        "them) except in the without-clusters column. Each round times one thread, then all threads right after "
        "it (in brackets under speedup: the pool thread asleep, its wake-up delaying its share), then, with "
        "the pool awake as a frame's other stages keep it, the other raster variants and the divisible kernel in turn, round after round. Divisible kernel: a compute-only Warp "
        "kernel as long on one thread as the row's raster, split in equal parts over the threads through the "
        "same pool: the speedup a perfectly divisible kernel of that length gets on this machine. Speedups are "
        "medians of each round's ratio (its one-thread time over its all-thread time); in square brackets, the "
        "lower and upper quartiles of those ratios, how far they scatter on this machine. One thread on each "
        "core: the one-thread call with the calling thread held to each core in turn, medians; where one core "
        "runs slower (a virtual machine's host may share its physical core), two threads sharing the work as "
        "it comes gain at most 1 + t_fast / t_slow over the faster core's time t_fast. Clusters occluded: the fraction culled as hidden; in brackets, with back faces culled, "
        "those culled as facing away and as hidden. Back faces culled: every "
        "triangle flagged in cull_back_faces, as pw.render flags single-sided meshes and closed ones seen from "
        "outside (the icospheres are closed; the others stand for single-sided meshes). Ray cast: "
        "wp.mesh_query_ray per pixel in row bands on the thread pool. Embree: "
        "Open3D RaycastingScene.cast_rays on all cores, rays precomputed. Same triangle: fraction of pixels "
        "where raster and ray cast name the same triangle (or both none); in brackets, where the culled "
        "raster names the same triangle as the full one.",
        "",
        "Buffers drawn with clusters culled equal those drawn without, bit for bit, in "
        f"{sum(r['same_buffer_without_clusters'] for r in rows)} of {len(rows)} rows.",
        "",
        f"Cost models on {t} threads, least squares weighted by 1/time over all rows (pbrwarp/raster.py keeps them):",
        f"- raster (reused buffer) ≈ {model['raster_seconds_per_triangle'] * 1e9:.1f} ns × triangles + "
        f"{model['raster_seconds_per_sample'] * 1e9:.2f} ns × samples",
        f"- ray cast ≈ {model['raycast_seconds_per_sample_log2_triangle'] * 1e9:.2f} ns × samples × log2(triangles)",
    ]
    return "\n".join(lines) + "\n"


def subdivided(name, times):
    """A shared-asset mesh with each triangle split in four ``times`` times: Suzanne (968
    triangles) twice gives 15,488, the happy Buddha (100,000) twice 1,600,000, the ends of the
    issue's 10k to 2M range."""
    import trimesh

    mesh = trimesh.load(asset(f"meshes/{name}.obj"), force="mesh", process=True)
    for _ in range(times):
        mesh = mesh.subdivide()
    return mesh


def terrain(cells=1000, seed=3):
    """A cells x cells height field of rolling hills, 2 cells² triangles, about 1 unit across."""
    import trimesh

    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.linspace(-0.5, 0.5, cells + 1), np.linspace(-0.5, 0.5, cells + 1))
    y = np.zeros_like(x)
    for _ in range(12):
        k = rng.normal(size=2) * 12.0
        y += 0.01 * np.sin(k[0] * x + k[1] * z + rng.uniform(0, 2 * np.pi))
    corner = (np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]).ravel()
    quads = np.stack([corner, corner + cells + 1, corner + cells + 2, corner + 1], axis=1)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return trimesh.Trimesh(np.stack([x, y, z], axis=-1).reshape(-1, 3), faces, process=False)


def cases(quick):
    if quick:
        return [("icosphere", icosphere(4), 128)]
    out = []
    sphere = icosphere(6)
    rabbit = bunny(decimated=False)
    for size in (512, 1024, 2048):
        out.append(("icosphere", sphere, size))
        out.append(("stanford bunny", rabbit, size))
    for subdivisions in (5, 7, 8):
        out.append(("icosphere", icosphere(subdivisions), 1024))
    out.append(("suzanne", subdivided("suzanne", 2), 1024))
    out.append(("happy buddha", subdivided("happy-buddha", 2), 1024))
    out.append(("terrain", terrain(), 1024))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="one small case, for checking the script")
    ap.add_argument("--framing", choices=("hull", "sphere"), default="hull",
                    help="fit the camera to the mesh's convex hull (Camera.frame) or its bounding sphere")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    threads_all = os.cpu_count() or 1
    rows = []
    for label, mesh, size in cases(args.quick):
        rows.append(bench_case(label, mesh, size, args.repeats, threads_all, args.framing))
        print(rows[-1], file=sys.stderr)
    rows.sort(key=lambda r: (r["mesh"] != "icosphere" or r["triangles"] != 81920, r["mesh"], r["triangles"], r["size"]))
    model = fit_cost_models(rows, threads_all) if len(rows) > 2 else {}
    command = command_line(ap, args)
    if args.quick:
        print(rows)
        return
    name = "visibility" if args.framing == "hull" else "visibility_sphere"
    write_results(name, command, {"rows": rows, "cost_model": model}, markdown(rows, model, threads_all))


if __name__ == "__main__":
    main()
