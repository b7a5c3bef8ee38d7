"""What the light buffers' cell count buys: shadow-ray frames of meshes from 69k to 1.6M triangles
with each light buffer view 512 cells a side (the side below 100k triangles), 1024, and the side
pbrwarp.light_buffers.resolution picks for the scene.

    python bench/light_buffer_resolution.py [--repeats 7] [--size 1024]

Per scene (bench/frames.py's: the mesh at unit radius on a floor, one point light, so six views)
and side, on every core: building the light buffers, marking their interiors and regions (as on
their first reuse), and the median whole frame (pw.render, visibility "raster", spp 1, shadow rays
through the buffers built for it) over interleaved rounds after a warm-up, beside the frame without
shadows. Writes bench/results/light_buffer_resolution.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, interleaved_medians, write_results  # noqa: E402
from frames import frame, scene_on_floor  # noqa: E402
from visibility import subdivided  # noqa: E402

from pbrwarp import light_buffers  # noqa: E402
from pbrwarp.gpu_scene import upload  # noqa: E402
from pbrwarp.meshes import bunny  # noqa: E402


def meshes():
    return [("stanford bunny", bunny(decimated=False)), ("happy buddha", subdivided("happy-buddha", 0)),
            ("happy buddha, subdivided once", subdivided("happy-buddha", 1)),
            ("happy buddha, subdivided twice", subdivided("happy-buddha", 2))]


def with_side(scene, side: int):
    """(build ms, marks ms, cells, entries) of ``scene``'s light buffers built with ``side`` cells a
    side, kept on the scene for its frames."""
    gpu = upload(scene)
    chosen = light_buffers.scene_resolution
    light_buffers.scene_resolution = lambda _: side
    try:
        t0 = time.perf_counter()
        buffers = light_buffers.build(scene, gpu)
        t1 = time.perf_counter()
        marked = light_buffers.build(scene, gpu)  # the first reuse: a copy with interiors and regions marked
        assert marked.cell_faces is buffers.cell_faces and light_buffers.build(scene, gpu) is marked
        t2 = time.perf_counter()
    finally:
        light_buffers.scene_resolution = chosen
    assert buffers.resolution == side
    return 1e3 * (t1 - t0), 1e3 * (t2 - t1), buffers.cell_start.shape[0] - 1, int(buffers.cell_start.numpy()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--size", type=int, default=1024)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    rows = []
    for name, mesh in meshes():
        base, camera = scene_on_floor(mesh)
        chosen = light_buffers.scene_resolution(base)
        sides = sorted({light_buffers.RESOLUTION, 2 * light_buffers.RESOLUTION, chosen})
        scenes, built = {}, {}
        for side in sides:
            scenes[side], _ = scene_on_floor(mesh)
            built[side] = with_side(scenes[side], side)

        fns = {side: frame(scenes[side], camera, args.size, "raster", "rays") for side in sides}
        fns["no shadows"] = frame(base, camera, args.size, "raster", False)
        times = interleaved_medians(fns, args.repeats)
        for side in sides:
            build_ms, marks_ms, cells, entries = built[side]
            row = {"scene": f"{name} ({base.triangle_count:,} tris)", "side": side, "chosen": side == chosen,
                   "cells": cells, "entries": entries, "build ms": build_ms, "marks ms": marks_ms,
                   "frame ms": 1e3 * times[side], "no shadows ms": 1e3 * times["no shadows"]}
            rows.append(row)
            print(row, file=sys.stderr)
    lines = [f"| scene ({args.size}², 1 point light, visibility raster) | cells a side | cells | list entries | "
             "built ms | marked ms | frame ms | of which shadow rays ms | frame vs 512 a side |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        at_512 = next(o for o in rows if o["scene"] == r["scene"] and o["side"] == light_buffers.RESOLUTION)
        side = f"**{r['side']}** (chosen)" if r["chosen"] else str(r["side"])
        lines.append(f"| {r['scene']} | {side} | {r['cells'] / 1e6:.1f}M | {r['entries'] / 1e6:.1f}M | "
                     f"{r['build ms']:.0f} | {r['marks ms']:.0f} | {r['frame ms']:.1f} | "
                     f"{r['frame ms'] - r['no shadows ms']:.1f} | {r['frame ms'] / at_512['frame ms']:.2f}x |")
    lines += ["", "Every core. \"built\": pbrwarp.light_buffers.build for the scene's point light (six views of "
              "the side's square of cells), without interior or region marks, once (the first frame pays it); "
              "\"marked\": the marks made on the buffers' first reuse (the second frame pays them); \"frame\": "
              "the median of pw.render with those buffers kept, spp 1, the variants and the frame without "
              "shadows timed in turn round after round; \"of which shadow rays\": the frame less the one "
              "without shadows. The chosen side is pbrwarp.light_buffers.resolution's for the scene."]
    write_results("light_buffer_resolution", command_line(ap, args), {"rows": rows}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
