"""Path tracing speed: the Cornell box, against Mitsuba 3's ``path`` integrator where installed.

    python bench/pathtrace.py [--size 256] [--spp 64] [--segments 1 2 4 8] [--repeats 5]

Renders ``pbrwarp.meshes.cornell_box()`` with ``integrator="path"`` on every core, at each path
length of ``--segments``, and, when the optional ``mitsuba`` package runs here, Mitsuba 3's
``path`` integrator on its ``llvm_ad_rgb`` variant on the same scene: the same triangles (one flat
shaded mesh per pbrwarp primitive), two-sided Lambertian materials of the same reflectances, the
same emitter radiance, camera and image, a box pixel filter as pbrwarp's, and an independent
sampler. As a yardstick Mitsuba also renders its own ``mi.cornell_box()`` (the one the issue's
4.4 s for 512² was measured on: another geometry of the same room). Mitsuba's LLVM backend needs
libLLVM with the instructions it emits: on Debian 12, ``apt install libllvm19`` and
``DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1`` (the script sets the latter when
the file exists).

Path length: Mitsuba's ``max_depth`` counts path segments (the camera ray included), pbrwarp's
``max_bounces`` the scattering events after the first hit, so 8 segments are ``max_depth=8`` and
``max_bounces=7``. Within each round every renderer runs once per path length, in turn, after a
warm-up round (compiles, scene loads, BVH builds); times are medians over the rounds, and the
ratio is the median of the per-round ratios, so that load on this shared machine falls on both.

Where the time goes: the script also measures Warp's ``mesh_query_ray`` alone on the scene's
BVH (the one the path tracer queries), from random points inside the room in uniformly random
directions, on one thread: the rate of closest-hit queries that every path segment and shadow ray
pays.

The images are compared as a check that the renderers agree on the scene: the mean radiance
and the relative RMSE of 16 x 16-pixel block means, at the longest path length.

Writes bench/results/pathtrace.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp import meshes  # noqa: E402
from pbrwarp.kernels.path import ROULETTE_FROM_BOUNCE  # noqa: E402

LLVM = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")


def pbrwarp_renderer(scene, cam, size, spp):
    def render(segments, seed):
        return pw.render(scene, cam, size, size, spp=spp, integrator="path", max_bounces=segments - 1, seed=seed,
                         progress=False, aovs=False).rgb

    return render


def _mitsuba():
    """The mitsuba module set to its LLVM variant, or the reason it cannot run here."""
    if LLVM.exists():
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", str(LLVM))
    try:
        import mitsuba as mi

        mi.set_variant("llvm_ad_rgb")
        return mi
    except Exception as error:  # ImportError, or no usable LLVM: Mitsuba is an optional peer
        return f"{type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}"


def mitsuba_scene_dict(scene, cam, size, spp, folder: Path):
    """Mitsuba's description of a pbrwarp scene of Lambertian, possibly emissive primitives: one
    flat-shaded PLY per primitive written into ``folder``."""
    import trimesh

    look = np.asarray(cam.eye) + np.asarray(cam.forward)
    spec = {
        "type": "scene",
        "integrator": {"type": "path"},
        "sensor": {
            "type": "perspective", "fov": cam.fov_y, "fov_axis": "y",
            "to_world": _look_at(cam.eye, look, cam.up),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
        },
    }
    for i, prim in enumerate(scene.primitives):
        path = folder / f"primitive{i}.ply"
        trimesh.Trimesh(prim.positions, prim.faces, process=False).export(path)
        m = prim.material
        shape = {"type": "ply", "filename": str(path), "face_normals": True,
                 "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {
                     "type": "rgb", "value": [float(c) for c in m.base_color[:3]]}}}}
        emitted = np.asarray(m.emissive, dtype=float)
        if emitted.max() > 0.0:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emitted.tolist()}}
        spec[f"primitive{i}"] = shape
    return spec


def _look_at(eye, target, up):
    import mitsuba as mi

    return mi.ScalarTransform4f().look_at(origin=[float(c) for c in eye], target=[float(c) for c in target],
                                          up=[float(c) for c in up])


def mitsuba_renderer(mi, spec, rr_depth=None):
    """Mitsuba's path integrator on ``spec``; Russian roulette from its ``rr_depth``-th surface
    (None: its default, 5)."""
    import drjit as dr

    loaded = mi.load_dict(spec)
    integrators = {}
    roulette = {} if rr_depth is None else {"rr_depth": rr_depth}

    def render(segments, seed):
        if segments not in integrators:
            integrators[segments] = mi.load_dict({"type": "path", "max_depth": segments, **roulette})
        image = mi.render(loaded, spp=spec["sensor"]["sampler"]["sample_count"], seed=seed,
                          integrator=integrators[segments])
        dr.eval(image)
        dr.sync_thread()
        return np.asarray(image)[..., :3]

    return render


def mitsuba_own_cornell(mi, size, spp):
    spec = mi.cornell_box()
    spec["sensor"]["film"]["width"] = spec["sensor"]["film"]["height"] = size
    spec["sensor"]["sampler"]["sample_count"] = spp
    return mitsuba_renderer(mi, spec)


@wp.kernel(enable_backward=False, module="unique")
def _cast_rays(mesh: wp.uint64, lower: wp.vec3, upper: wp.vec3, rays: int, out: wp.array(dtype=float)):
    state = wp.rand_init(wp.tid())
    total = float(0.0)
    for _ in range(rays):
        o = wp.vec3(wp.randf(state, lower[0], upper[0]), wp.randf(state, lower[1], upper[1]),
                    wp.randf(state, lower[2], upper[2]))
        d = wp.sample_unit_sphere_surface(state)
        q = wp.mesh_query_ray(mesh, o, d, 1.0e6)
        if q.result:
            total += q.t
    out[wp.tid()] = total


def ray_rate(scene, rays=1_000_000, repeats=5):
    """Millions of closest-hit mesh_query_ray calls a second on one thread, on the scene's BVH:
    rays from random points of the middle 80% of its bounding box, uniformly in direction."""
    from pbrwarp.gpu_scene import upload

    lower, upper = scene.bounds()
    lower, upper = lower + 0.1 * (upper - lower), upper - 0.1 * (upper - lower)
    mesh = upload(scene).geometry.mesh
    out = wp.zeros(1, dtype=float, device="cpu")
    args = [mesh.id, wp.vec3(*lower), wp.vec3(*upper)]
    wp.launch(_cast_rays, 1, args + [1000, out], device="cpu")  # compiles
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        wp.launch(_cast_rays, 1, args + [rays, out], device="cpu")
        wp.synchronize_device("cpu")
        times.append(time.perf_counter() - t0)
    return rays / statistics.median(times) / 1e6


def block_means(image, block=16):
    h, w = image.shape[:2]
    return image[: h - h % block, : w - w % block].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))


def main(argv=None):
    ap = argparse.ArgumentParser(prog="pathtrace.py", description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    scene, cam = meshes.cornell_box()
    renderers = {"pbrwarp": pbrwarp_renderer(scene, cam, args.size, args.spp)}
    mi = _mitsuba()
    folder = tempfile.TemporaryDirectory()
    if isinstance(mi, str):
        print(f"Mitsuba not measured: {mi}", file=sys.stderr)
    else:
        spec = mitsuba_scene_dict(scene, cam, args.size, args.spp, Path(folder.name))
        # "mitsuba" plays pbrwarp's roulette, so the two run the same estimator
        renderers["mitsuba"] = mitsuba_renderer(mi, spec, rr_depth=ROULETTE_FROM_BOUNCE)
        renderers["mitsuba, rr_depth 5 (its default)"] = mitsuba_renderer(mi, spec)
        renderers["mitsuba, mi.cornell_box()"] = mitsuba_own_cornell(mi, args.size, args.spp)
    times = {(name, s): [] for name in renderers for s in args.segments}
    images = {}
    for round_ in range(args.repeats + 1):  # round 0 warms up
        for segments in args.segments:
            for name, render in renderers.items():
                t0 = time.perf_counter()
                images[name, segments] = render(segments, round_ + 1)
                if round_ > 0:
                    times[name, segments].append(time.perf_counter() - t0)
    folder.cleanup()

    rows = []
    for segments in args.segments:
        for name in renderers:
            row = {"renderer": name, "segments": segments, "seconds": statistics.median(times[name, segments]),
                   "mean_rgb": images[name, segments].mean(axis=(0, 1)).tolist()}
            if name != "mitsuba" and "mitsuba" in renderers:
                row["relative_to_mitsuba"] = statistics.median(
                    a / b for a, b in zip(times[name, segments], times["mitsuba", segments]))
            rows.append(row)
    rate = ray_rate(scene, repeats=args.repeats)
    longest = max(args.segments)
    agreement = None
    if "mitsuba" in renderers:
        a, b = block_means(images["pbrwarp", longest]), block_means(images["mitsuba", longest])
        agreement = float(np.sqrt(np.mean((a - b) ** 2 / (b**2 + 1e-4))))

    lines = ["| path segments | renderer | seconds (median) | time relative to Mitsuba (same scene) | "
             "mean radiance (R, G, B) |", "|---|---|---|---|---|"]
    for r in rows:
        relative = f"{r['relative_to_mitsuba']:.2f}x" if "relative_to_mitsuba" in r else (
            "1.00x" if r["renderer"] == "mitsuba" else "")
        mean = ", ".join(f"{c:.4f}" for c in r["mean_rgb"])
        lines.append(f"| {r['segments']} | {r['renderer']} | {r['seconds']:.3f} | {relative} | {mean} |")
    lines += ["", f"Cornell box (pbrwarp.meshes.cornell_box()), {args.size}x{args.size}, {args.spp} spp, every core; "
              f"medians of {args.repeats} rounds after a warm-up, the renderers timed in turn each round; 'relative' "
              "is the median of the per-round ratios (lower is faster). 'mitsuba' starts Russian roulette where "
              f"pbrwarp does (rr_depth={ROULETTE_FROM_BOUNCE}: a path may end after its third surface), so both run the "
              "same estimator; 'rr_depth 5' is Mitsuba's default (longer paths: more work, less noise). "
              "'mitsuba, mi.cornell_box()' is Mitsuba's own Cornell box (other geometry, its defaults, for scale)."]
    if agreement is not None:
        lines.append(f"Agreement at {longest} segments: relative RMSE of 16x16 block means, pbrwarp against "
                     f"Mitsuba on the same scene: {agreement:.4f}.")
    else:
        lines.append(f"Mitsuba was not measured: {mi}")
    lines.append(f"Warp's mesh_query_ray on this scene's BVH, one thread: {rate:.2f} M closest-hit queries/s "
                 f"({1e3 / rate:.0f} ns each).")
    write_results("pathtrace", command_line(ap, args), {"rows": rows, "block_rel_rmse": agreement,
                                                        "mesh_query_ray_mrays_per_s": rate},
                  "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
