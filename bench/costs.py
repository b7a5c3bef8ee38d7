"""Smaller costs the README quotes: the demo renders, the albedo coupling in a whole frame, and the
split sum against its Monte Carlo reference on single spheres.

    python bench/costs.py [--repeats 5]

Frames on every core, medians of --repeats after a warm-up, compared within the same run.
Writes bench/results/costs.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import trimesh
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, median_time, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp.meshes import asset, demo_scene  # noqa: E402


def demo_rows(repeats):
    hdr = asset("hdr/venice_sunset_1k.hdr")  # from the shared assets: a clear error when they are missing
    scene, camera = demo_scene()

    def render(width=960, height=540, **options):
        return pw.render(scene, camera, width=width, height=height, spp=4, progress=False, **options)

    rows = [("demo render, 960×540, 4 spp", 1e3 * median_time(render, repeats))]
    scene.environment = pw.Environment.load(hdr)
    t0 = time.perf_counter()
    render()
    rows.append(("demo render with the Venice HDR, first (prefiltering included)", 1e3 * (time.perf_counter() - t0)))
    rows.append(("demo render with the Venice HDR, prefiltered", 1e3 * median_time(render, repeats)))
    scene.environment = None
    for coupling in ("albedo", "fresnel"):
        brdf = pw.BRDF(coupling=coupling)
        rows.append((f"demo render 512×384, 4 spp, coupling={coupling}",
                     1e3 * median_time(lambda: render(512, 384, brdf=brdf), repeats)))
    return rows


def split_sum_rows():
    """Relative RMSE of the split sum against Monte Carlo (2048 unshadowed directions) on one
    sphere under the procedural sky, and the same at its centre pixels (n.v ~ 1)."""
    rows = []
    camera = pw.Camera.look_at(eye=(0, 0, 3.2), target=(0, 0, 0), fov_y=40.0)
    for metallic in (0.0, 0.5, 1.0):
        for roughness in (0.15, 0.8):
            scene = pw.Scene()
            scene.add_mesh(trimesh.creation.icosphere(subdivisions=3),
                           pw.Material(base_color=(0.8, 0.5, 0.3), metallic=metallic, roughness=roughness))
            scene.environment = pw.Environment.sky()
            kw = dict(width=24, height=24, progress=False)
            best = pw.render(scene, camera, ibl=pw.IBL(method="monte_carlo", samples=2048), **kw)
            split = pw.render(scene, camera, **kw)
            covered = best.alpha > 0
            rmse = np.sqrt(np.mean((split.rgb[covered] - best.rgb[covered]) ** 2)) / best.rgb[covered].mean()
            centre = np.abs(split.rgb[11:13, 11:13] - best.rgb[11:13, 11:13]).max() / best.rgb[11:13, 11:13].mean()
            rows.append((metallic, roughness, float(rmse), float(centre)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    demo = demo_rows(args.repeats)
    spheres = split_sum_rows()
    lines = ["| render (2 cores) | ms |", "|---|---|"] + [f"| {name} | {ms:.0f} |" for name, ms in demo]
    lines += ["", "Split sum against Monte Carlo (2048 directions, unshadowed) on one sphere under "
              "pw.Environment.sky(), 24×24:", "",
              "| metallic | roughness | relative RMSE, whole sphere | worst relative error, centre pixels |",
              "|---|---|---|---|"]
    lines += [f"| {m} | {r} | {e:.3f} | {c:.3f} |" for m, r, e, c in spheres]
    command = command_line(ap, args)
    write_results("costs", command, {"demo_ms": demo, "split_sum_vs_monte_carlo": spheres}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
