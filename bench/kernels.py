"""Time pbrwarp's pipeline stages and whole frames.

    python bench/kernels.py [--repeats 5] [--quick]

Stages (camera rays, closest hit, any hit) run as single launches on one thread and as tiles on
every core; whole frames (one point light, ray-traced shadows on and off, primary visibility ray
cast as the stages are; bench/frames.py times rasterized frames) on 1 and N threads.
Primary-ray throughput is also compared with Open3D's RaycastingScene (Embree) on the very same
rays when the optional ``open3d-cpu`` package is installed. Medians of ``--repeats`` runs after a
warm-up; ratios compare numbers measured in the same run. Writes bench/results/kernels.{md,json}.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import trimesh
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, median_time, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp.kernels import stages  # noqa: E402
from pbrwarp.gpu_scene import upload  # noqa: E402
from pbrwarp.meshes import ASSETS  # noqa: E402
from pbrwarp.render import _camera_data  # noqa: E402


def test_meshes(quick: bool):
    sphere = trimesh.creation.icosphere(subdivisions=4 if quick else 6)
    meshes = {f"icosphere ({len(sphere.faces):,} tris)": sphere}
    bunny = ASSETS / "meshes" / "stanford-bunny.obj"
    if bunny.exists():  # from the shared assets beside the clone; without them, the icosphere alone
        mesh = trimesh.load(bunny, force="mesh")
        meshes[f"stanford bunny ({len(mesh.faces):,} tris)"] = mesh
    return meshes


def split(n: int, parts: int):
    step = math.ceil(n / parts)
    return [(a, min(a + step, n)) for a in range(0, n, step)]


def launch_chunks(kernel, n, threads, make_inputs, chunk=16384):
    """Launch ``kernel`` over [0, n) in chunks spread over ``threads`` threads."""
    ranges = split(n, max(1, math.ceil(n / chunk)))
    if threads == 1:
        wp.launch(kernel, dim=n, inputs=make_inputs(0, n), device="cpu")
        return
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda r: wp.launch(kernel, dim=r[1] - r[0], inputs=make_inputs(*r), device="cpu"), ranges))


def bench_mesh(name, mesh, size, repeats, threads_all):
    scene = pw.Scene()
    scene.add_mesh(mesh, pw.Material(base_color=(0.8, 0.7, 0.6), roughness=0.4))
    cam = pw.Camera.frame(scene, direction=(0.3, 0.4, 1.0))
    lo, hi = scene.bounds()
    radius = float(np.linalg.norm(hi - lo))
    light_pos = 0.5 * (lo + hi) + radius * np.array([1.0, 1.5, 1.0])
    scene.add_light(pw.PointLight(position=tuple(light_pos), intensity=radius**2 * 3.0))
    gpu = upload(scene)
    n = size * size
    cam_data = _camera_data(cam, size, size)
    dirs = wp.empty(n, dtype=wp.vec3, device="cpu")
    t = wp.empty(n, dtype=float, device="cpu")
    face = wp.empty(n, dtype=int, device="cpu")
    origins = wp.empty(n, dtype=wp.vec3, device="cpu")
    hit = wp.empty(n, dtype=int, device="cpu")
    eye = wp.vec3(*cam.eye)
    to_light = wp.vec3(*(np.array([1.0, 1.5, 1.0]) / np.linalg.norm([1.0, 1.5, 1.0])))
    geom = gpu._keep[0]
    row = {"mesh": name, "size": size, "pixels": n}

    def camera_rays():
        wp.launch(stages.primary_ray_directions, dim=n, inputs=[cam_data, dirs], device="cpu")

    def closest(threads):
        launch_chunks(stages.closest_hits, n, threads, lambda a, b: [gpu.data.mesh, eye, dirs[a:b], t[a:b], face[a:b]])

    def anyhit(threads):
        launch_chunks(stages.any_hits, n, threads, lambda a, b: [gpu.data.mesh, origins[a:b], to_light, hit[a:b]])

    camera_rays()
    closest(1)
    wp.launch(stages.shadow_origins, dim=n, inputs=[geom.positions, geom.indices, eye, dirs, t, face, to_light, origins], device="cpu")
    row["camera_rays_ms"] = 1e3 * median_time(camera_rays, repeats)
    for threads in (1, threads_all):
        row[f"closest_hit_ms_{threads}t"] = 1e3 * median_time(lambda: closest(threads), repeats)
        row[f"any_hit_ms_{threads}t"] = 1e3 * median_time(lambda: anyhit(threads), repeats)
        for shadows in (False, True):
            key = f"frame_{'shadows' if shadows else 'noshadows'}_ms_{threads}t"
            row[key] = 1e3 * median_time(lambda: pw.render(scene, cam, width=size, height=size, threads=threads,
                                                           shadows=shadows, visibility="raycast", progress=False),
                                         repeats)
    hits = int((face.numpy() >= 0).sum())
    row["primary_hits"] = hits
    row["primary_mrays_per_s_1t"] = n / row["closest_hit_ms_1t"] / 1e3
    row[f"primary_mrays_per_s_{threads_all}t"] = n / row[f"closest_hit_ms_{threads_all}t"] / 1e3
    row["frame_speedup"] = row["frame_shadows_ms_1t"] / row[f"frame_shadows_ms_{threads_all}t"]
    row["shading_ms_1t_derived"] = row["frame_noshadows_ms_1t"] - row["closest_hit_ms_1t"]
    row.update(open3d_primary(mesh, cam.eye, dirs.numpy(), repeats))
    if "open3d_mrays_per_s" in row:
        row["primary_ratio_to_open3d"] = row[f"primary_mrays_per_s_{threads_all}t"] / row["open3d_mrays_per_s"]
    return row


def open3d_primary(mesh, eye, dirs, repeats):
    try:
        import open3d as o3d
    except ImportError:
        return {}
    rc = o3d.t.geometry.RaycastingScene()
    rc.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)), o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    rays = o3d.core.Tensor(np.hstack([np.broadcast_to(np.asarray(eye, np.float32), dirs.shape), dirs]).astype(np.float32))
    seconds = median_time(lambda: rc.cast_rays(rays), repeats)
    return {"open3d_ms": 1e3 * seconds, "open3d_mrays_per_s": len(dirs) / seconds / 1e6}


def markdown(rows, threads_all):
    lines = [
        f"| mesh | size | camera rays ms | closest hit ms 1t / {threads_all}t | any hit ms 1t / {threads_all}t | "
        f"shading ms 1t (derived) | frame ms 1t / {threads_all}t (shadows) | speedup | frame ms {threads_all}t, no shadows | "
        f"primary Mrays/s {threads_all}t | Open3D Mrays/s | ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        o3d = f"{r['open3d_mrays_per_s']:.2f}" if "open3d_mrays_per_s" in r else "n/a"
        ratio = f"{r['primary_ratio_to_open3d']:.2f}x" if "primary_ratio_to_open3d" in r else "n/a"
        lines.append(
            f"| {r['mesh']} | {r['size']}² | {r['camera_rays_ms']:.1f} | {r['closest_hit_ms_1t']:.1f} / {r[f'closest_hit_ms_{threads_all}t']:.1f} | "
            f"{r['any_hit_ms_1t']:.1f} / {r[f'any_hit_ms_{threads_all}t']:.1f} | {r['shading_ms_1t_derived']:.1f} | "
            f"{r['frame_shadows_ms_1t']:.0f} / {r[f'frame_shadows_ms_{threads_all}t']:.0f} | {r['frame_speedup']:.2f}x | "
            f"{r[f'frame_noshadows_ms_{threads_all}t']:.0f} | {r[f'primary_mrays_per_s_{threads_all}t']:.2f} | {o3d} | {ratio} |")
    lines.append("")
    lines.append("Shading time is derived: the whole frame without shadows minus the closest-hit pass. "
                 "Any hit traces one shadow ray per primary hit towards a directional light. "
                 "Open3D casts the same primary rays on all cores (its default); ratio = pbrwarp / Open3D.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="small mesh and sizes, for checking the script")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    threads_all = os.cpu_count() or 1
    sizes = (128,) if args.quick else (512, 1024)
    rows = []
    for name, mesh in test_meshes(args.quick).items():
        for size in sizes:
            rows.append(bench_mesh(name, mesh, size, args.repeats, threads_all))
            print(rows[-1], file=sys.stderr)
    command = command_line(ap, args)
    if not args.quick:
        write_results("kernels", command, {"rows": rows}, markdown(rows, threads_all))
    else:
        print(markdown(rows, threads_all))


if __name__ == "__main__":
    main()
