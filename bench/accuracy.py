"""What accuracy costs in time: every BRDF rung, the presets, sample counts and shadows, measured
against a reference for error and timed, side by side.

    python bench/accuracy.py [--repeats 5] [--size 256x192]

- BRDF rows swap one term of the default (the real-time model of Karis 2013) for another rung,
  or use a preset. Their error is against the reference BRDF (pbrwarp.brdf.PRESETS["reference"]) rendered with
  the same 4 stratified samples per pixel, so it is the BRDF's error alone.
- Sampling rows render the default BRDF at 1..64 spp against the same BRDF at 256 spp.
- The shadow row turns shadow rays off, against shadow rays on.
- Texture filter rows render a brick floor seen at a grazing angle (textures many times finer
  than the pixels far away) with each texture filter at 1 and 4 spp, against bilinear lookups
  at 256 spp; the notes give the one-off cost of building the floor's mip chains.
Error: relative RMSE of linear radiance over the covered pixels (per pixel, relative to
reference^2 + 0.01, as Rousselle et al. 2011; radiance clipped at 64), mean over the scenes,
and mean
NVIDIA FLIP of the ACES-tone-mapped images when flip-evaluator is installed. Time: whole frames
on every core at spp 1 (median of --repeats after a warm-up, summed over the scenes), and ns per
BRDF evaluation (a kernel of 1e7 evaluations on one thread, minus the cost of its inputs).
Writes bench/results/accuracy.{md,json,png} and accuracy_differences.png (a contact sheet of
4x-amplified differences to the reference, one row per rung).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np
import trimesh
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import RESULTS, command_line, median_time, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp import meshes  # noqa: E402
from pbrwarp.brdf import PRESETS  # noqa: E402
from pbrwarp.kernels import stages  # noqa: E402

DEFAULT = pw.BRDF()
REFERENCE = PRESETS["reference"]
FAMILY_RUNGS = {
    "diffuse": ["lambert", "burley"],
    "distribution": ["ggx", "blinn_phong"],
    "geometry": ["implicit", "schlick_ggx", "smith_separable", "smith_correlated", "smith_correlated_fast"],
    "fresnel": ["none", "schlick", "spherical_gaussian", "exact"],
    "energy": ["single", "multiscatter"],
    "coupling": ["albedo", "fresnel", "none"],
    "model": ["microfacet", "phong", "blinn_phong"],
    "metallic_mix": ["gltf", "f0"],
}


def report_scenes():
    """The four scenes of the report: (name, scene, camera)."""
    grid = meshes.sphere_grid(base_color=(0.8, 0.2, 0.1), subdivisions=3)
    for direction in ((-0.5, -0.5, -1.0), (0.6, -0.3, -1.0), (0.0, 0.7, -1.0)):
        grid.add_light(pw.DirectionalLight(direction=direction, intensity=2.0))
    grazing = pw.Scene()
    grazing.add_mesh(trimesh.creation.box(extents=(40.0, 0.1, 40.0)), pw.Material(base_color=(0.3, 0.3, 0.35), roughness=0.25))
    grazing.add_light(pw.DirectionalLight(direction=(0.0, -0.2, 1.0), intensity=5.0))
    grazing.add_light(pw.PointLight(position=(3.0, 1.0, -8.0), intensity=60.0))
    textured_path = meshes.ASSETS / "gltf/NormalTangentTest/glTF-Binary/NormalTangentTest.glb"
    if textured_path.exists():
        textured = pw.Scene.load(textured_path)
    else:
        textured = pw.Scene()
        textured.add_mesh(meshes.normal_mapped_torus())
    textured.add_light(pw.DirectionalLight(direction=(-0.3, -0.4, -1.0), intensity=3.0))
    textured.add_light(pw.PointLight(position=tuple(textured.bounds()[1] * 2.0 + 1.0), intensity=20.0))
    white = pw.Scene()
    sphere = trimesh.creation.icosphere(subdivisions=4)
    for i, (metallic, roughness) in enumerate(((1.0, 0.6), (1.0, 1.0), (0.0, 0.6), (0.0, 1.0))):
        white.add_mesh(sphere, pw.Material(base_color=(1.0, 1.0, 1.0), metallic=metallic, roughness=roughness),
                       transform=trimesh.transformations.translation_matrix((2.4 * i - 3.6, 0.0, 0.0)))
    # a metal given by a complex IOR (illustrative values, a gold-like yellow), for the conductor
    # Fresnel of the exact rung
    white.add_mesh(sphere, pw.Material.conductor(n=(0.2, 0.9, 1.1), k=(3.9, 2.45, 1.8), roughness=0.3),
                   transform=trimesh.transformations.translation_matrix((0.0, 2.4, 0.0)))
    white.add_light(pw.DirectionalLight(direction=(0.0, 0.0, -1.0), intensity=3.0))
    white.add_light(pw.PointLight(position=(0.0, 4.0, 2.0), intensity=40.0))
    return [
        ("sphere grid", grid, pw.Camera.frame(grid, direction=(0, 0, 1))),
        ("grazing plane", grazing, pw.Camera.look_at(eye=(0.0, 0.6, 10.0), target=(0.0, 0.0, -10.0), fov_y=40.0)),
        ("textured glTF", textured, pw.Camera.frame(textured, direction=(0.2, 0.2, 1.0))),
        ("white spheres", white, pw.Camera.frame(white, direction=(0, 0, 1))),
    ]


# Radiance above this (6 EV over display white) is clipped before comparing: a sub-pixel
# highlight of 1e4 nits caught by one sample shows as white whatever its value, but would
# otherwise dominate the mean.
ERROR_RADIANCE_CLIP = 64.0


def rel_rmse(test, ref, covered):
    """sqrt(mean((x - ref)^2 / (ref^2 + 0.01))) over the covered pixels (the relative MSE of
    Rousselle et al. 2011) of radiance clipped at ERROR_RADIANCE_CLIP."""
    t = np.minimum(test[covered].astype(np.float64), ERROR_RADIANCE_CLIP)
    r = np.minimum(ref[covered].astype(np.float64), ERROR_RADIANCE_CLIP)
    return float(np.sqrt(np.mean((t - r) ** 2 / (r**2 + 0.01))))


def flip(test_frame, ref_frame):
    try:
        import flip_evaluator
    except ImportError:
        return None
    ref = ref_frame.to_srgb8().astype(np.float32) / 255.0
    test = test_frame.to_srgb8().astype(np.float32) / 255.0
    return float(flip_evaluator.evaluate(ref, test, "LDR")[1])


def brdf_ns_per_eval(brdf, repeats):
    threads, evals = 1000, 10_000
    out = wp.empty(threads, dtype=wp.vec3, device="cpu")
    kernel = stages.brdf_throughput_kernel(**dataclasses.asdict(brdf))
    full = median_time(lambda: wp.launch(kernel, threads, inputs=[evals, out], device="cpu"), repeats)
    inputs = median_time(lambda: wp.launch(stages.random_inputs_only, threads, inputs=[evals, out], device="cpu"), repeats)
    return 1e9 * (full - inputs) / (threads * evals)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", default="256x192")
    args = ap.parse_args(argv)
    width, height = (int(x) for x in args.size.split("x"))
    wp.config.log_level = wp.LOG_WARNING
    scenes = report_scenes()

    def render(scene, cam, **kw):
        return pw.render(scene, cam, width=width, height=height, progress=False, **kw)

    def frame_ms(**kw):
        return 1e3 * sum(median_time(lambda: render(s, c, **kw), args.repeats) for _, s, c in scenes)

    rows = []

    def add(family, label, errors, flips, ms, ns=None):
        rows.append({"family": family, "rung": label, "rel_rmse": float(np.mean(errors)), "per_scene": errors,
                     "flip": float(np.mean(flips)) if all(f is not None for f in flips) else None, "ms": ms, "ns_per_eval": ns})
        print(rows[-1], file=sys.stderr)

    t0 = time.perf_counter()
    # BRDF rungs and presets, against the reference BRDF at the same samples
    references = [render(s, c, spp=4, brdf=REFERENCE) for _, s, c in scenes]
    candidates = [("preset", f"quality={name}", brdf) for name, brdf in PRESETS.items()]
    for family, rungs in FAMILY_RUNGS.items():
        for rung in rungs:
            brdf = pw.BRDF(**{**DEFAULT.__dict__, family: rung})
            if brdf != DEFAULT:
                candidates.append((family, f"{family}={rung}", brdf))
    sheet = []
    for family, label, brdf in candidates:
        frames = [render(s, c, spp=4, brdf=brdf) for _, s, c in scenes]
        sheet.append((label, [difference_image(f, r) for f, r in zip(frames, references)]))
        errors = [rel_rmse(f.rgb, r.rgb, r.alpha > 0) for f, r in zip(frames, references)]
        add(family, label, errors, [flip(f, r) for f, r in zip(frames, references)], frame_ms(brdf=brdf),
            brdf_ns_per_eval(brdf, args.repeats))
    # sample counts and shadows with the default BRDF
    converged = [render(s, c, spp=256) for _, s, c in scenes]
    for spp in (1, 4, 16, 64):
        frames = [render(s, c, spp=spp) for _, s, c in scenes]
        add("sampling", f"spp={spp}", [rel_rmse(f.rgb, r.rgb, r.alpha > 0) for f, r in zip(frames, converged)],
            [flip(f, r) for f, r in zip(frames, converged)], frame_ms(spp=spp))
    with_shadows = [render(s, c) for _, s, c in scenes]
    frames = [render(s, c, shadows=False) for _, s, c in scenes]
    add("shadows", "shadows=False", [rel_rmse(f.rgb, r.rgb, r.alpha > 0) for f, r in zip(frames, with_shadows)],
        [flip(f, r) for f, r in zip(frames, with_shadows)], frame_ms(shadows=False))
    for label, settings in (("shadows=map (512, pcf 1)", pw.ShadowMap(resolution=512, pcf=1)),
                            ("shadows=map (1024, pcf 3, default)", pw.ShadowMap()),
                            ("shadows=map (2048, pcf 3)", pw.ShadowMap(resolution=2048))):
        frames = [render(s, c, shadows=settings) for _, s, c in scenes]

        def fresh_maps(settings=settings):
            # time the maps' rasterization too: a render that reuses them costs only the lookups
            for _, s, c in scenes:
                s.cache.drop("shadow maps")
                render(s, c, shadows=settings)

        add("shadows", label, [rel_rmse(f.rgb, r.rgb, r.alpha > 0) for f, r in zip(frames, with_shadows)],
            [flip(f, r) for f, r in zip(frames, with_shadows)], 1e3 * median_time(fresh_maps, args.repeats))
    rows.append({"family": "shadows", "rung": "shadows=map (default, maps reused)", "rel_rmse": rows[-2]["rel_rmse"],
                 "per_scene": rows[-2]["per_scene"], "flip": rows[-2]["flip"], "ms": frame_ms(shadows="map"),
                 "ns_per_eval": None})
    rows.append({"family": "shadows", "rung": "shadows=rays (ray traced)", "rel_rmse": 0.0, "per_scene": [0.0] * len(scenes),
                 "flip": 0.0, "ms": frame_ms(), "ns_per_eval": None})
    ibl_rows(add, render, args.repeats)
    mip_ms = texture_filter_rows(add, render, args.repeats)
    transmission_rows(add, render, args.repeats)
    print(f"done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)

    names = [n for n, _, _ in scenes]
    header = (f"| family | rung | ms / {len(scenes)} frames | ns / BRDF eval | rel. RMSE (mean) | FLIP (mean) | "
              + " | ".join(f"rel. RMSE {n}" for n in names) + " |")
    lines = [header, "|" + "---|" * (6 + len(names))]
    for r in rows:
        ns = f"{r['ns_per_eval']:.1f}" if r["ns_per_eval"] is not None else ""
        fl = f"{r['flip']:.4f}" if r["flip"] is not None else "n/a"
        per_scene = [f"{e:.4f}" for e in r["per_scene"]] if len(r["per_scene"]) == len(names) else [""] * len(names)
        lines.append(f"| {r['family']} | {r['rung']} | {r['ms']:.0f} | {ns} | {r['rel_rmse']:.4f} | {fl} | "
                     + " | ".join(per_scene) + " |")
    lines += ["", f"{width}x{height} frames on every core. BRDF and preset rows: error against "
              f"quality=reference ({REFERENCE.describe()}) at the same 4 spp; sampling rows: against 256 spp; "
              "ibl rows (one scene of their own: a sphere grid on a floor under an HDR, no punctual lights; "
              "per-scene columns empty, ms for its one frame): against Monte Carlo with 1024 shadowed directions per sample at 4 spp; "
              "shadows rows: against ray-traced shadows; shadow-map times include rasterizing the maps except "
              "where they are reused (a new camera, the same lights and geometry); texture filter rows (a brick floor "
              "of their own, per-scene columns empty, ms for its one frame at the row's spp): against bilinear "
              f"lookups at 256 spp; its mip chains take {mip_ms:.0f} ms to build, once per texture; transmission "
              "rows (a rough glass slab before a brick wall under an HDR; error over the glass's pixels only; ms "
              f"for its one frame at the row's spp): against the sampled rung at 256 spp with {GLASS_REFERENCE_IBL.samples} "
              "shadowed environment directions per sample. Times: spp 1 "
              "unless a row says otherwise, medians, summed over the four scenes.",
              "", "![error vs time](accuracy.png)", "",
              "Differences to the reference (tone-mapped, amplified 4x), one row per rung:", "",
              "![differences](accuracy_differences.png)"]
    command = command_line(ap, args)
    write_results("accuracy", command, {"rows": rows, "scenes": names}, "\n".join(lines) + "\n")
    plot(rows, RESULTS / "accuracy.png")
    contact_sheet(sheet, [n for n, _, _ in scenes], RESULTS / "accuracy_differences.png")


IBL_RUNGS = (
    ("split sum (dfg)", pw.IBL()),
    ("split sum (lagarde Fresnel)", pw.IBL(fresnel="lagarde")),
    ("monte carlo 16", pw.IBL(method="monte_carlo", samples=16, shadowed=True)),
    ("monte carlo 64", pw.IBL(method="monte_carlo", samples=64, shadowed=True)),
    ("monte carlo 256", pw.IBL(method="monte_carlo", samples=256, shadowed=True)),
    ("monte carlo 256, unshadowed", pw.IBL(method="monte_carlo", samples=256)),
)


def ibl_scene():
    """The 5 x 5 metallic x roughness sphere grid on a floor under the Venice sunset HDR (or the
    procedural sky without the shared assets), no punctual lights."""
    scene = meshes.sphere_grid(5, 5, base_color=(0.9, 0.6, 0.2), subdivisions=3)
    floor = trimesh.Trimesh([[-8, -6.3, -3], [8, -6.3, -3], [8, -6.3, 3], [-8, -6.3, 3]], [[0, 2, 1], [0, 3, 2]])
    scene.add_mesh(floor, pw.Material(base_color=(0.5, 0.5, 0.5), roughness=0.8))
    hdr = meshes.ASSETS / "hdr" / "venice_sunset_1k.hdr"
    try:
        scene.environment = pw.Environment.load(hdr)
    except (pw.PbrwarpError, ImportError):
        scene.environment = pw.Environment.sky()
    return scene, pw.Camera.frame(scene, direction=(0.0, 0.25, 1.0))


def ibl_rows(add, render, repeats):
    """Environment-lighting rungs against Monte Carlo with 1024 shadowed directions per sample,
    all at 4 spp and the default BRDF; times are spp 1 frames."""
    scene, cam = ibl_scene()
    reference = render(scene, cam, spp=4, ibl=pw.IBL(method="monte_carlo", samples=1024, shadowed=True))
    covered = reference.alpha > 0
    for label, ibl in IBL_RUNGS:
        frame = render(scene, cam, spp=4, ibl=ibl)
        add("ibl", label, [rel_rmse(frame.rgb, reference.rgb, covered)], [flip(frame, reference)],
            1e3 * median_time(lambda: render(scene, cam, ibl=ibl), repeats))


def texture_floor():
    """A brick floor (meshes.brick_material: 512² base colour and normal map) 60 units wide, the
    bricks repeated 30 times, seen from 1.5 units above it, lit by one directional light."""
    scene = pw.Scene()
    scene.add_mesh(meshes.normal_mapped_tile(size=60.0, repeats=30.0), transform=_floor_transform())
    scene.add_light(pw.DirectionalLight(direction=(-0.4, -1.0, -0.3), intensity=3.0))
    return scene, pw.Camera.look_at(eye=(0.0, 1.5, 12.0), target=(0.0, 0.0, -10.0), fov_y=50.0)


def _floor_transform():
    """The tile's z = 0 plane turned to y = 0, facing up."""
    return trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0))


def texture_filter_rows(add, render, repeats) -> float:
    """Texture filter rungs on the brick floor against bilinear lookups at 256 spp; returns the
    milliseconds building its mip chains takes (median)."""
    from pbrwarp import gpu_scene

    scene, cam = texture_floor()
    reference = render(scene, cam, spp=256, texture_filter="bilinear")
    covered = reference.alpha > 0
    for texture_filter in ("trilinear", "bilinear"):
        for spp in (1, 4):
            frame = render(scene, cam, spp=spp, texture_filter=texture_filter)
            add("texture filter", f"{texture_filter}, spp={spp}" + (" (default)" if texture_filter == "trilinear" and spp == 1 else ""),
                [rel_rmse(frame.rgb, reference.rgb, covered)], [flip(frame, reference)],
                1e3 * median_time(lambda: render(scene, cam, spp=spp, texture_filter=texture_filter), repeats))
    prims = scene.primitives
    return 1e3 * median_time(lambda: gpu_scene._build_texels(prims, None), repeats)


GLASS_REFERENCE_IBL = pw.IBL(method="monte_carlo", samples=8, shadowed=True)


def glass_scene(with_wall=True):
    """A rough (0.25) glass slab 0.3 units thick before a brick wall, under the Venice sunset HDR
    (or the procedural sky without the shared assets)."""
    scene = pw.Scene()
    if with_wall:
        scene.add_mesh(meshes.normal_mapped_tile(size=6.0, repeats=3.0),
                       transform=trimesh.transformations.translation_matrix((0.0, 0.0, -1.5)))
    slab = trimesh.creation.box(extents=(2.5, 2.5, 0.3))
    scene.add_mesh(slab, pw.Material(base_color=(1.0, 1.0, 1.0), roughness=0.25, transmission=1.0, thickness=0.3))
    hdr = meshes.ASSETS / "hdr" / "venice_sunset_1k.hdr"
    try:
        scene.environment = pw.Environment.load(hdr)
    except (pw.PbrwarpError, ImportError):
        scene.environment = pw.Environment.sky()
    return scene, pw.Camera.look_at(eye=(0.8, 0.6, 5.0), target=(0.0, 0.0, -0.5), fov_y=45.0)


def transmission_rows(add, render, repeats):
    """Rough transmission rungs: "prefiltered" (split-sum environment light; objects behind the
    glass stay sharp) and "sampled" (Monte Carlo environment light; the GGX transmission lobe
    sampled per camera sample), against the sampled rung at 256 spp, over the glass's pixels."""
    scene, cam = glass_scene()
    glass_only, _ = glass_scene(with_wall=False)
    glass = render(glass_only, cam, background=(0.0, 0.0, 0.0)).alpha > 0
    reference = render(scene, cam, spp=256, ibl=GLASS_REFERENCE_IBL)
    rungs = [("prefiltered", spp, None) for spp in (1, 4, 16)]
    rungs += [("sampled", spp, GLASS_REFERENCE_IBL) for spp in (4, 16, 64)]
    for name, spp, ibl in rungs:
        frame = render(scene, cam, spp=spp, ibl=ibl)
        label = f"{name}, spp={spp}" + (" (default)" if name == "prefiltered" and spp == 1 else "")
        add("transmission", label, [rel_rmse(frame.rgb, reference.rgb, glass)], [flip(frame, reference)],
            1e3 * median_time(lambda: render(scene, cam, spp=spp, ibl=ibl), repeats))


def difference_image(frame, reference):
    """|tone-mapped test - tone-mapped reference|, amplified 4x, as uint8 RGB."""
    d = np.abs(frame.to_srgb8().astype(np.int16) - reference.to_srgb8().astype(np.int16)) * 4
    return np.clip(d, 0, 255).astype(np.uint8)


def contact_sheet(sheet, scene_names, path):
    """One row per rung, one column per scene, of 4x-amplified differences to the reference."""
    from PIL import Image, ImageDraw

    h, w = sheet[0][1][0].shape[:2]
    label_w = 190
    out = Image.new("RGB", (label_w + w * len(scene_names), 16 + h * len(sheet)), (20, 20, 20))
    draw = ImageDraw.Draw(out)
    for j, name in enumerate(scene_names):
        draw.text((label_w + j * w + 4, 2), name, fill=(230, 230, 230))
    for i, (label, images) in enumerate(sheet):
        draw.text((4, 16 + i * h + h // 2 - 6), label, fill=(230, 230, 230))
        for j, image in enumerate(images):
            out.paste(Image.fromarray(image), (label_w + j * w, 16 + i * h))
    out.save(path)


def replot():
    """Redraw accuracy.png from accuracy.json (python -c "import accuracy; accuracy.replot()" in bench/)."""
    import json

    plot(json.loads((RESULTS / "accuracy.json").read_text())["rows"], RESULTS / "accuracy.png")


# Row families measured on a scene of their own, plotted apart from the four report scenes'.
ONE_SCENE_FAMILIES = ("ibl", "texture filter", "transmission")


def plot(rows, path):
    """Error vs cost, log axes, Pareto fronts dashed: BRDF rungs against ns per evaluation (their
    frame times differ by less than the timing noise), sampling and shadows against ms per frame."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed (pip install -e '.[bench]'): no plot", file=sys.stderr)
        return
    colours = {"preset": "black", "diffuse": "tab:green", "distribution": "tab:purple", "geometry": "tab:blue",
               "fresnel": "tab:orange", "energy": "tab:olive", "coupling": "tab:cyan", "model": "tab:pink",
               "metallic_mix": "gold", "sampling": "tab:red", "shadows": "tab:brown", "ibl": "tab:gray",
               "texture filter": "teal", "transmission": "tab:blue"}
    floor = 1e-4  # the reference itself (error 0) sits on the floor of the log axis
    fig, axes = plt.subplots(1, 5, figsize=(27, 5), dpi=110)
    panels = ((axes[0], [r for r in rows if r["ns_per_eval"] is not None], "ns_per_eval",
               "BRDF cost (ns per evaluation, one thread)", "BRDF rungs and presets (4 spp)"),
              (axes[1], [r for r in rows if r["ns_per_eval"] is None and r["family"] not in ONE_SCENE_FAMILIES], "ms",
               "time for the four report frames (ms, 2 cores)", "sample counts and shadows"),
              (axes[2], [r for r in rows if r["family"] == "ibl"], "ms",
               "time for the HDR-lit frame (ms, 2 cores)", "environment light (vs 1024 shadowed directions)"),
              (axes[3], [r for r in rows if r["family"] == "texture filter"], "ms",
               "time for the brick floor frame (ms, 2 cores)", "texture filters (vs bilinear at 256 spp)"),
              (axes[4], [r for r in rows if r["family"] == "transmission"], "ms",
               "time for the glass frame (ms, 2 cores)", "rough transmission (vs sampled, 256 spp)"))
    for ax, subset, key, xlabel, title in panels:
        points = [(max(r[key], 0.1), max(r["rel_rmse"], floor), r) for r in subset]
        for x, err, r in points:
            ax.scatter(x, err, color=colours[r["family"]], s=28, zorder=3)
            ax.annotate(r["rung"], (x, err), fontsize=6.5, xytext=(3, 2), textcoords="offset points")
        front, best = [], float("inf")
        for x, err, _ in sorted(points, key=lambda p: (p[0], p[1])):
            if err < best:
                front.append((x, err))
                best = err
        ax.plot(*zip(*front), color="grey", lw=1.0, ls="--", zorder=2, label="Pareto front")
        for family in dict.fromkeys(r["family"] for r in subset):
            ax.scatter([], [], color=colours[family], label=family)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative RMSE vs reference (mean over scenes)")
        ax.set_title(title)
        ax.legend(fontsize=7, loc="best")
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("pbrwarp: what accuracy costs in time")
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    main()
