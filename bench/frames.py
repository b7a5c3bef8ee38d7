"""Whole shaded frames by visibility path and shadow technique, against one Embree primary-ray pass.

    python bench/frames.py [--repeats 5] [--size 1024]

Scenes: the 81,920-triangle icosphere and the 69,451-triangle Stanford bunny, each standing on a
two-triangle floor (so that it casts a shadow and shadows are not compiled out), one point
light, spp 1, every core. Frames: visibility "raycast" and "raster", each with shadows by rays
(through light buffers kept from the previous frame, or, "rebuilt", built anew for this one, as
after a light or the geometry moved), by maps reused from the previous frame (a moving camera),
and by maps rendered anew, and without shadows. Embree: Open3D's RaycastingScene.cast_rays on the same
primary rays (when open3d is installed), the issue's yardstick: a full shaded frame with
ray-traced shadows should take no longer than that one pass. Medians of --repeats rounds after a
warm-up round, every variant and the Embree pass timed in turn within each round. Also the first
frame of a new Python process (pw.render with default options, the scene already built, kernels
and albedo tables in the disk cache: upload, light buffers, kernel loading and all), the median of
--repeats processes. Writes bench/results/frames.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

import numpy as np
import trimesh
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, interleaved_medians, rebuilt, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp.kernels import stages  # noqa: E402
from pbrwarp.meshes import bunny, icosphere  # noqa: E402
from pbrwarp.render import _camera_data  # noqa: E402

VARIANTS = (
    ("raycast", "rays"), ("raster", "rays"), ("raster", "rays rebuilt"), ("raycast", "map reused"),
    ("raster", "map reused"), ("raster", "map rebuilt"), ("raster", False),
)


def meshes():
    """(name, mesh) of the frames' scenes: the 81,920-triangle icosphere and the full Stanford bunny."""
    return [("icosphere (81,920 tris)", icosphere(6)), ("stanford bunny (69,451 tris)", bunny(decimated=False))]


def scene_on_floor(mesh):
    """``mesh`` scaled to unit radius on a floor, a point light above and to the side."""
    mesh = mesh.copy()
    mesh.apply_translation(-mesh.bounding_box.centroid)
    mesh.apply_scale(1.0 / np.max(np.linalg.norm(mesh.vertices, axis=1)))
    scene = pw.Scene()
    scene.add_mesh(mesh, pw.Material(base_color=(0.8, 0.6, 0.4), roughness=0.4))
    floor = trimesh.Trimesh([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], [[0, 2, 1], [0, 3, 2]])
    scene.add_mesh(floor, pw.Material(base_color=(0.7, 0.7, 0.7)))
    scene.add_light(pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    return scene, pw.Camera.look_at(eye=(0.0, 0.8, 3.2), target=(0.0, -0.2, 0.0))


def embree_pass(scene, camera, size):
    """One Open3D (Embree) primary-ray pass over the camera's pixel centres, as a callable; None
    without open3d."""
    try:
        import open3d as o3d
    except ImportError:
        return None
    raycaster = o3d.t.geometry.RaycastingScene()
    for prim in scene.primitives:
        raycaster.add_triangles(o3d.core.Tensor(prim.positions.astype(np.float32)),
                                o3d.core.Tensor(prim.faces.astype(np.uint32)))
    cam = _camera_data(camera, size, size)
    dirs = wp.empty(size * size, dtype=wp.vec3, device="cpu")
    wp.launch(stages.primary_ray_directions, dim=size * size, inputs=[cam, dirs], device="cpu")
    rays = np.hstack([np.broadcast_to(np.asarray(camera.eye, np.float32), (size * size, 3)), dirs.numpy()])
    rays = o3d.core.Tensor(rays.astype(np.float32))
    return lambda: raycaster.cast_rays(rays)


def frame(scene, camera, size, visibility, shadows):
    """One whole frame of a variant, as a callable."""
    mode = shadows.split()[0] if shadows else shadows

    def render_one():
        pw.render(scene, camera, width=size, height=size, visibility=visibility, shadows=mode, progress=False)

    if shadows == "map rebuilt":
        return lambda: rebuilt(scene, "shadow maps", render_one)
    if shadows == "rays rebuilt":
        return lambda: rebuilt(scene, "light buffers", render_one)
    return render_one


def first_frame_seconds(scene_index: int, size: int) -> float:
    """Seconds of a new process's first pw.render (default options) of scene ``scene_index``."""
    code = (f"import sys; sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r}); import time; "
            "import warp as wp; wp.config.quiet = True; import pbrwarp as pw; import frames; "
            f"scene, camera = frames.scene_on_floor(frames.meshes()[{scene_index}][1]); t = time.perf_counter(); "
            f"pw.render(scene, camera, width={size}, height={size}, progress=False); "
            "print(time.perf_counter() - t)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(result.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=1024)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    rows = []
    for index, (name, mesh) in enumerate(meshes()):
        scene, camera = scene_on_floor(mesh)
        variants = {f"{visibility}, shadows {shadows or 'off'}": frame(scene, camera, args.size, visibility, shadows)
                    for visibility, shadows in VARIANTS}
        embree = embree_pass(scene, camera, args.size)
        if embree is not None:
            variants["embree"] = embree
        # all variants in turn, round after round (common.interleaved_medians)
        row = {"scene": name, "embree_ms": None}
        row.update({("embree_ms" if key == "embree" else key): 1e3 * seconds
                    for key, seconds in interleaved_medians(variants, args.repeats).items()})
        first_frame_seconds(index, args.size)  # caches whatever the in-process rounds did not
        row["first frame, new process"] = 1e3 * statistics.median(
            first_frame_seconds(index, args.size) for _ in range(args.repeats))
        rows.append(row)
        print(row, file=sys.stderr)
    keys = [f"{v}, shadows {s or 'off'}" for v, s in VARIANTS] + ["first frame, new process"]
    lines = [f"| scene ({args.size}², 1 point light) | " + " | ".join(f"{k} ms" for k in keys) + " | Embree primary pass ms |",
             "|---|" + "---|" * (len(keys) + 1)]
    for r in rows:
        embree = f"{r['embree_ms']:.1f}" if r["embree_ms"] is not None else "n/a"
        lines.append(f"| {r['scene']} | " + " | ".join(f"{r[k]:.1f}" for k in keys) + f" | {embree} |")
    lines += ["", "Whole frames (spp 1, every core, medians; every variant and the Embree pass timed in turn, "
              "round after round). \"rays\": shadow rays through the light buffers "
              "built for an earlier frame (same lights and geometry; their triangle interiors and the floor's "
              "regions were marked when they were first reused), \"rays rebuilt\": built for this frame (six "
              "512² cube faces of triangle lists for the point light, no interior or region marks); \"map reused\": the maps rendered "
              "for an earlier frame serve this one; \"map rebuilt\": rendered for this frame, six 1024² cube "
              "faces for the point light. \"first frame, new process\": pw.render with default options in a "
              "fresh Python process, the scene built and the kernels and albedo tables in the disk cache (the "
              "mesh's upload, its light buffers and the kernels' loading included), median of as many processes."]
    command = command_line(ap, args)
    write_results("frames", command, {"rows": rows}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
