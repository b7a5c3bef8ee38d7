"""Where a whole frame's time goes: bench/frames.py's scenes taken apart with render options.

    python bench/frame_parts.py [--repeats 5] [--size 1024]

Per scene and thread count (1 and every core), medians of interleaved rounds after a warm-up:
the rasterized visibility buffer alone; whole frames (visibility "raster") without shadows, then
without the depth and normal outputs, then with the diffuse lobe's albedo coupling replaced by the
cheapest coupling ("none", no table lookups), then with shadow rays through the light buffers
kept from an earlier frame, the same with their large triangles' region marks dropped for the
frame, and with their interiors' and regions' marks dropped; building the light buffers, and
marking their interiors and regions (as on their first reuse).
Differences between these are the parts' costs.
Writes bench/results/frame_parts.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, interleaved_medians, rebuilt, write_results  # noqa: E402
from frames import meshes, scene_on_floor  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp import light_buffers  # noqa: E402
from pbrwarp.gpu_scene import back_face_culling, upload  # noqa: E402
from pbrwarp.kernels.light_buffer import INTERIOR_CLEAR, NOT_CLEAR, REGIONS_CLEAR  # noqa: E402
from pbrwarp.raster import reused_buffer, visibility_buffer  # noqa: E402
from pbrwarp.render import _camera_data  # noqa: E402

PARTS = ("raster only", "no shadows", "no shadows, no AOVs", "no shadows, coupling none", "shadow rays",
         "shadow rays, no region marks", "shadow rays, no interior or region marks", "light buffers built",
         "interiors and regions marked")


def dropped(marks: np.ndarray, first_code) -> np.ndarray:
    """Light buffer triangle marks with the codes from ``first_code`` on dropped: INTERIOR_CLEAR
    drops the interiors' and regions' (whole triangles' kept), REGIONS_CLEAR the regions'."""
    return np.where(marks >= int(first_code), int(NOT_CLEAR), marks).astype(np.uint8)


def variants(scene, camera, size, threads):
    gpu = upload(scene)
    cam = _camera_data(camera, size, size)
    cull, _ = back_face_culling(scene, gpu, camera.eye)
    out = reused_buffer("camera", size, size)

    def frame(**options):
        return lambda: pw.render(scene, camera, width=size, height=size, threads=threads, visibility="raster",
                                 progress=False, **options)

    def build():
        rebuilt(scene, "light buffers", lambda: light_buffers.build(scene, gpu, threads))

    def without_marks(first_code):
        def run():
            # the kept buffers' marks, less some, for one frame (the same compiled kernel)
            buffers = light_buffers.build(scene, gpu, threads)
            marks = buffers.triangle_clear.numpy().copy()
            buffers.triangle_clear.assign(dropped(marks, first_code))
            try:
                frame(shadows="rays")()
            finally:
                buffers.triangle_clear.assign(marks)
        return run

    def mark_interiors():
        # the kept buffers' interiors and regions marked again (into a copy) from the whole triangles' marks
        buffers = light_buffers.build(scene, gpu, threads)
        marks = buffers.triangle_clear.numpy().copy()
        buffers.triangle_clear.assign(dropped(marks, INTERIOR_CLEAR))
        try:
            light_buffers.mark_interiors(scene, gpu, buffers, threads)
        finally:
            buffers.triangle_clear.assign(marks)

    return dict(zip(PARTS, (
        lambda: visibility_buffer(gpu.data.positions, gpu.data.indices, cam, threads=threads, out=out,
                                  cull_back_faces=cull),
        frame(shadows=False),
        frame(shadows=False, aovs=False),
        frame(shadows=False, brdf=pw.BRDF(coupling="none")),
        frame(shadows="rays"),
        without_marks(REGIONS_CLEAR),
        without_marks(INTERIOR_CLEAR),
        build,
        mark_interiors,
    )))


def mark_shares(scene, gpu) -> tuple[float, float]:
    """(the share of the scene's triangles whose interiors its kept light buffers mark clear of its
    first light, the share of the regions of its region triangles marked clear)."""
    buffers = light_buffers.build(scene, gpu)
    marks = buffers.triangle_clear.numpy()[: buffers.triangles]
    grids = buffers.region_grids.numpy()
    flags = buffers.region_clear.numpy()
    clear = regions = 0
    for code in marks[marks >= int(REGIONS_CLEAR)]:
        n, first = (int(x) for x in grids[int(code) - int(REGIONS_CLEAR)])
        in_triangle = np.add.outer(np.arange(n), np.arange(n)).reshape(-1) < n
        clear += int(flags[first:first + n * n][in_triangle].sum())
        regions += int(in_triangle.sum())
    interiors = (marks >= int(INTERIOR_CLEAR)) & (marks < int(REGIONS_CLEAR))
    return float(interiors.mean()), clear / max(regions, 1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=1024)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    cores = os.cpu_count() or 1
    rows = []
    for name, mesh in meshes():
        scene, camera = scene_on_floor(mesh)
        for threads in sorted({1, cores}):
            times = interleaved_medians(variants(scene, camera, args.size, threads), args.repeats)
            interiors, regions = mark_shares(scene, upload(scene))
            row = {"scene": name, "threads": threads, **{part: 1e3 * times[part] for part in PARTS},
                   "interior marks": interiors, "regions clear": regions}
            rows.append(row)
            print(row, file=sys.stderr)
    lines = [f"| scene ({args.size}², 1 point light, visibility raster) | threads | "
             + " | ".join(f"{p} ms" for p in PARTS) + " | triangles with interior marks | regions clear |",
             "|---|---|" + "---|" * (len(PARTS) + 2)]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['threads']} | " + " | ".join(f"{r[p]:.1f}" for p in PARTS)
                     + f" | {100 * r['interior marks']:.1f}% | {100 * r['regions clear']:.1f}% |")
    lines += ["", "Medians of interleaved rounds after a warm-up. \"raster only\": the visibility buffer alone "
              "(back faces culled as renders cull them); frames: pw.render with visibility=\"raster\", "
              "spp 1; \"coupling none\": the diffuse lobe's albedo coupling (two table lookups and a mean "
              "per evaluation) replaced by none; \"shadow rays\": through light buffers kept from an "
              "earlier frame (their triangle interiors and the floor's regions marked on their first "
              "reuse); \"no region marks\", \"no interior or region marks\": the same with those marks "
              "dropped for the frame; \"light buffers built\": pbrwarp.light_buffers.build for the "
              "scene's one point light (six 512² faces), without interior or region marks; \"interiors "
              "and regions marked\": pbrwarp.light_buffers.mark_interiors, as on the buffers' first "
              "reuse; the last columns: the share of triangles whose interiors are marked, and of the "
              "region triangles' (the floor's two) regions marked clear."]
    command = command_line(ap, args)
    write_results("frame_parts", command, {"rows": rows}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
