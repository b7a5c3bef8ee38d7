"""What specializing kernels per scene buys: specialized vs all-effects kernel, same scene.

    python bench/specialize.py [--repeats 5] [--size 512] [--cold]

Scenes: a bare one (one untextured convex mesh, one directional light), a textured,
normal-mapped torus under a point light, and the demo scene. Frames on every core, medians of
--repeats after a warm-up, both kernels timed in the same run. Also counts the kernel variants
the session compiled and the compile (or cache load) time of each; --cold compiles them into an
empty kernel cache, as a user's first session does. Writes
bench/results/specialize.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, median_time, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp import meshes  # noqa: E402
from pbrwarp.features import Features, scene_features  # noqa: E402
from pbrwarp.gpu_scene import upload  # noqa: E402
from pbrwarp.kernels.loading import load_for_cpu  # noqa: E402
from pbrwarp.kernels.render import render_kernel  # noqa: E402


def bench_scenes():
    bare = pw.Scene()
    bare.add_mesh(meshes.icosphere(6), pw.Material(base_color=(0.8, 0.3, 0.2), roughness=0.4))
    bare.add_light(pw.DirectionalLight(direction=(-0.3, -0.5, -1.0), intensity=3.0))
    textured = pw.Scene()
    textured.add_mesh(meshes.normal_mapped_torus())
    textured.add_light(pw.PointLight(position=(3.0, 4.0, 5.0), intensity=60.0))
    demo, demo_cam = meshes.demo_scene()
    return [("bare: convex icosphere (81,920 tris), 1 directional light", bare, pw.Camera.frame(bare)),
            ("textured, normal-mapped torus, 1 point light", textured, pw.Camera.frame(textured)),
            ("demo scene (sphere grid + torus, 3 lights)", demo, demo_cam)]


def compile_time(features: Features) -> float:
    """Seconds to build (or load from Warp's disk cache) the kernel of ``features``."""
    kernel = render_kernel(features)
    t0 = time.perf_counter()
    load_for_cpu(kernel)
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--cold", action="store_true", help="compile into an empty kernel cache, as a first session does")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    if args.cold:
        import tempfile

        wp.config.kernel_cache_dir = tempfile.mkdtemp(prefix="pbrwarp-bench-cache-")
    rows, variants = [], {}
    for name, scene, cam in bench_scenes():
        features = scene_features(scene, upload(scene), shadows=True, spp=1, samples=args.size**2)
        for f in (features, Features.everything(1)):
            if f not in variants:
                variants[f] = compile_time(f)

        def frame(specialize, visibility="auto"):
            return pw.render(scene, cam, width=args.size, height=args.size, progress=False, specialize=specialize,
                             visibility=visibility)

        special = median_time(lambda: frame(True), args.repeats)
        special_raycast = median_time(lambda: frame(True, "raycast"), args.repeats)
        general = median_time(lambda: frame(False), args.repeats)
        dropped = [k for k, v in features.__dict__.items() if not v]
        rows.append({"scene": name, "specialized_ms": 1e3 * special, "specialized_raycast_ms": 1e3 * special_raycast,
                     "all_effects_ms": 1e3 * general,
                     "speedup": general / special, "dropped": dropped, "visibility": features.visibility})
        print(rows[-1], file=sys.stderr)
    lines = [f"| scene ({args.size}², all cores) | specialized ms | all-effects ms | speedup | primary visibility | "
             "specialized, ray cast ms | speedup without the raster | effects compiled out |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['specialized_ms']:.1f} | {r['all_effects_ms']:.1f} | {r['speedup']:.2f}x | "
                     f"{r['visibility']} | {r['specialized_raycast_ms']:.1f} | "
                     f"{r['all_effects_ms'] / r['specialized_raycast_ms']:.2f}x | {', '.join(r['dropped']) or 'none'} |")
    lines += ["", "The all-effects kernel ray-casts primary visibility; the specialized one takes the path "
              "visibility=\"auto\" picks for the scene (rasterized or ray cast, by the cost model of bench/visibility.py)."]
    lines += ["", f"Kernel variants this session: {len(variants)}; build or cache-load time each: "
              + ", ".join(f"{t:.2f} s" for t in variants.values())
              + " (a few seconds means compiled now, milliseconds loaded from Warp's disk cache)."]
    command = command_line(ap, args)
    write_results("specialize", command, {"rows": rows, "variant_load_seconds": list(variants.values())},
                  "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
