"""What accuracy costs in time: every rung of every approximation, measured against a converged
path-traced ground truth for error and timed, side by side.

    python bench/accuracy.py [--size 160x120] [--reference-spp 16384] [--repeats 3] [--out DIR]

The reference of each scene is pw.render(integrator="path", max_bounces=16, brdf=quality=reference)
at --reference-spp samples per pixel, rendered once per run as two independent halves (seeds
REFERENCE_SEEDS, never the rows' seed 0) and averaged. Its own error is estimated as
relMSE(half A, half B) / 4 (each half has twice the full image's variance; their difference four
times) and reported beside the smallest nonzero error of the rows.
Error: relMSE with epsilon, per covered pixel the mean over channels of (x - y)^2 / (y^2 + 0.01)
(Rousselle et al. 2011), no clipping, averaged over the pixels but the 0.1% with the largest
errors (fireflies: OUTLIER_SHARE), mean over the scenes; and NVIDIA FLIP (flip-evaluator) of the
tone-mapped (to_srgb8) images. Time: whole frames on every core (median of --repeats after a
warm-up, summed over the scenes).
Rows: BRDF rungs and presets (direct integrator, 4 spp), spp 1..64, shadows (off, shadow maps),
integrators (path at max_bounces 1, 2, 4, 8; path + pw.denoise against path at more samples;
all with the reference BRDF, beside the direct integrator's quality=reference row), IBL rungs on
an HDR-lit scene, texture filters on a grazing brick floor; all against the path-traced
reference; rough transmission rungs on a glass slab before a brick wall, against its path
reference over the glass's pixels. --only transmission re-runs only those rows (and their
reference) and keeps the others from DIR/accuracy.json, saying so in the report.
Writes DIR/accuracy.{md,json,png} and DIR/accuracy_direct_misses.png (per scene: path reference,
direct default, and their difference amplified 4x).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

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
    """The report scenes: (name, scene, camera). The Cornell box is lit by its emissive ceiling
    light and a point light just below it (both integrators use the point light; only the path
    tracer is lit by the emissive quad)."""
    grid = meshes.sphere_grid(base_color=(0.8, 0.2, 0.1), subdivisions=3)
    for direction in ((-0.5, -0.5, -1.0), (0.6, -0.3, -1.0), (0.0, 0.7, -1.0)):
        grid.add_light(pw.DirectionalLight(direction=direction, intensity=2.0))
    grazing = pw.Scene()
    grazing.add_mesh(trimesh.creation.box(extents=(40.0, 0.1, 40.0)), pw.Material(base_color=(0.3, 0.3, 0.35), roughness=0.25))
    grazing.add_light(pw.DirectionalLight(direction=(0.0, -0.2, 1.0), intensity=5.0))
    grazing.add_light(pw.PointLight(position=(3.0, 1.0, -8.0), intensity=60.0))
    # WaterBottle, not NormalTangentTest: that model's mirror cells (roughness ~0) reflect the punctual
    # lights as glints, a delta light on a near-delta lobe, whose pixel integral no feasible number of
    # samples converges (the reference's own relMSE did not fall from 4096 to 16384 spp; docs/accuracy.md)
    textured_path = meshes.ASSETS / "gltf/WaterBottle/glTF/WaterBottle.gltf"
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
    box, box_camera = meshes.cornell_box()
    box.add_light(pw.PointLight(position=(0.278, 0.50, 0.28), intensity=1.0))
    return [
        ("sphere grid", grid, pw.Camera.frame(grid, direction=(0, 0, 1))),
        ("grazing plane", grazing, pw.Camera.look_at(eye=(0.0, 0.6, 10.0), target=(0.0, 0.0, -10.0), fov_y=40.0)),
        ("textured glTF", textured, pw.Camera.frame(textured, direction=(0.2, 0.2, 1.0))),
        ("white spheres", white, pw.Camera.frame(white, direction=(0, 0, 1))),
        ("cornell box", box, box_camera),
    ]




REFERENCE_BOUNCES = 16
REFERENCE_SEEDS = (1_000_003, 2_000_003)
ROW_SPP_PATH = 16


def brdf_ns_per_eval(brdf, repeats):
    """ns per evaluation of ``brdf``: a kernel of 1e7 evaluations on random inputs on one thread,
    minus the cost of those inputs alone."""
    import warp as wp

    threads, evals = 1000, 10_000
    out = wp.empty(threads, dtype=wp.vec3, device="cpu")
    kernel = stages.brdf_throughput_kernel(**brdf.__dict__)
    full = median_time(lambda: wp.launch(kernel, threads, inputs=[evals, out], device="cpu"), repeats)
    inputs = median_time(lambda: wp.launch(stages.random_inputs_only, threads, inputs=[evals, out], device="cpu"),
                         repeats)
    return 1e9 * (full - inputs) / (threads * evals)


# The share of covered pixels with the largest errors left out of relMSE. A point light's
# sub-pixel highlight on a near-mirror, caught by one sample, carries 1e4-1e6 times the radiance
# around it (a path tracer's caustics too); a handful of such pixels would otherwise decide the
# mean and make it grow with spp as more pixels catch one. 0.1% is 19 pixels of 160x120.
OUTLIER_SHARE = 0.001


def rel_mse(test, ref, covered) -> float:
    """The relative MSE of Rousselle et al. 2011 of linear radiance: per covered pixel, the mean
    over channels of (x - y)^2 / (y^2 + 0.01), averaged over the covered pixels but the
    OUTLIER_SHARE with the largest errors; no clipping of radiance."""
    t = test[covered].astype(np.float64)
    r = ref[covered].astype(np.float64)
    per_pixel = np.sort(np.mean((t - r) ** 2 / (r**2 + 0.01), axis=-1))
    kept = len(per_pixel) - int(np.ceil(OUTLIER_SHARE * len(per_pixel)))
    return float(np.mean(per_pixel[:max(kept, 1)]))


def flip(test_frame, ref_frame):
    try:
        import flip_evaluator
    except ImportError:
        return None
    ref = ref_frame.to_srgb8().astype(np.float32) / 255.0
    test = test_frame.to_srgb8().astype(np.float32) / 255.0
    return float(flip_evaluator.evaluate(ref, test, "LDR")[1])


class Reference:
    """A scene's path-traced ground truth: the mean of two independent halves, and its own
    estimated relMSE, relMSE(A, B) / 4. Textures are looked up bilinearly at every sample (no
    footprint filtering), so the reference converges to the pixel's box-filtered radiance."""

    def __init__(self, render, scene, cam, spp):
        half = max(1, spp // 2)
        a, b = (render(scene, cam, spp=half, integrator="path", max_bounces=REFERENCE_BOUNCES,
                       brdf=PRESETS["reference"], texture_filter="bilinear", seed=s) for s in REFERENCE_SEEDS)
        self.halves = a.rgb, b.rgb
        self.frame = a
        self.frame.rgb = 0.5 * (a.rgb + b.rgb)  # a new array: the halves stay as rendered
        self.covered = a.alpha > 0
        self.own_rel_mse = self.half_rel_mse(self.covered)

    def half_rel_mse(self, covered) -> float:
        """The reference's own relMSE over ``covered``: relMSE(half A, half B) / 4."""
        return rel_mse(*self.halves, covered) / 4.0


def measured_row(rows, family, label, make, refs, scene_list, repeats, scene):
    """Append to ``rows`` the row of ``make`` (scene, cam) -> Frame: its error against ``refs``, one
    per scene of ``scene_list``, and its time summed over them; returns its frames."""
    frames = [make(s, c) for _, s, c in scene_list]
    errors = [rel_mse(f.rgb, r.frame.rgb, r.covered) for f, r in zip(frames, refs)]
    flips = [flip(f, r.frame) for f, r in zip(frames, refs)]
    ms = 1e3 * sum(median_time(lambda: make(s, c), repeats) for _, s, c in scene_list)
    rows.append({"family": family, "rung": label, "rel_mse": float(np.mean(errors)), "per_scene": errors,
                 "flip": float(np.mean(flips)) if all(f is not None for f in flips) else None, "ms": ms,
                 "scene": scene})
    print(rows[-1], file=sys.stderr)
    return frames


def main(argv=None):
    ap = argparse.ArgumentParser(prog="accuracy.py", description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--only", choices=("transmission",), default=None,
                    help="re-run only these rows, keeping the others from DIR/accuracy.json")
    args = ap.parse_args(argv)
    width, height = (int(x) for x in args.size.split("x"))
    out = Path(args.out)
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    scenes = report_scenes()

    def render(scene, cam, **kw):
        return pw.render(scene, cam, width=width, height=height, progress=False, **kw)

    if args.only:
        return update_transmission_rows(ap, args, render, out)
    t0 = time.perf_counter()
    references = [Reference(render, s, c, args.reference_spp) for _, s, c in scenes]
    print(f"references in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    rows = []

    def row(family, label, make, refs=references, scene_list=scenes):
        scene = "report" if scene_list is scenes else scene_list[0][0]
        return measured_row(rows, family, label, make, refs, scene_list, args.repeats, scene)

    def direct(**kw):
        return lambda s, c: render(s, c, **kw)

    # BRDF rungs and presets, direct integrator at 4 spp
    default = pw.BRDF()
    candidates = [("preset", f"quality={name}", brdf) for name, brdf in PRESETS.items()]
    for family, rungs in FAMILY_RUNGS.items():
        for rung in rungs:
            brdf = pw.BRDF(**{**default.__dict__, family: rung})
            if brdf != default:
                candidates.append((family, f"{family}={rung}", brdf))
    for family, label, brdf in candidates:
        row(family, label + ", spp=4", direct(spp=4, brdf=brdf))
        rows[-1]["ns_per_brdf_eval"] = brdf_ns_per_eval(brdf, args.repeats)
    direct_default = None
    for spp in (1, 4, 16, 64):
        frames = row("sampling", f"direct, spp={spp}" + (" (default)" if spp == 1 else ""), direct(spp=spp))
        direct_default = direct_default or frames
    row("shadows", "shadows=False", direct(shadows=False))
    for label, settings in (("shadows=map (512, pcf 1)", pw.ShadowMap(resolution=512, pcf=1)),
                            ("shadows=map (1024, pcf 3, default)", pw.ShadowMap()),
                            ("shadows=map (2048, pcf 3)", pw.ShadowMap(resolution=2048))):
        def fresh_maps(s, c, settings=settings):
            # the maps' rasterization timed too: a render that reuses them costs only the lookups
            s.cache.drop("shadow maps")
            return render(s, c, shadows=settings)

        row("shadows", label, fresh_maps)
    # integrators, all with the reference's BRDF (so that the rows differ from the reference in
    # the integrator alone; quality=reference above is the direct integrator's row): path at
    # max_bounces 1..8, and denoised path against path at more samples
    for bounces in (1, 2, 4, 8):
        row("integrator", f"path, max_bounces={bounces}, spp={ROW_SPP_PATH}",
            direct(spp=ROW_SPP_PATH, integrator="path", max_bounces=bounces, brdf=REFERENCE))
    for spp in (4, 16):
        row("integrator", f"path, spp={spp} + denoise",
            lambda s, c, spp=spp: pw.denoise(render(s, c, spp=spp, integrator="path", brdf=REFERENCE)))
    for spp in (64, 256):
        row("integrator", f"path, spp={spp}", direct(spp=spp, integrator="path", brdf=REFERENCE))
    own_scenes = {"ibl scene": ibl_rows(row, render, args.reference_spp),
                  "brick floor": texture_filter_rows(row, render, args.reference_spp)}
    own_scenes["glass"] = transmission_rows(row, render, args.reference_spp)
    print(f"done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)

    names = [n for n, _, _ in scenes]
    own = {n: r.own_rel_mse for n, r in [*zip(names, references), *own_scenes.items()]}
    payload = {"rows": rows, "scenes": names, "reference_own_rel_mse": own, "size": [width, height],
               "reference_spp": args.reference_spp}
    command = command_line(ap, args)
    write_results("accuracy", command, payload, report_markdown(payload), directory=out)
    plot(rows, out / "accuracy.png")
    direct_misses_sheet([(n, r.frame, d) for n, r, d in zip(names, references, direct_default)],
                        out / "accuracy_direct_misses.png")



IBL_RUNGS = (
    ("split sum (dfg)", pw.IBL()),
    ("split sum (lagarde Fresnel)", pw.IBL(fresnel="lagarde")),
    ("monte carlo 16", pw.IBL(method="monte_carlo", samples=16, shadowed=True)),
    ("monte carlo 64", pw.IBL(method="monte_carlo", samples=64, shadowed=True)),
    ("monte carlo 64, no environment sampling", pw.IBL(method="monte_carlo", samples=64, shadowed=True,
                                                       environment_sampling=False)),
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


def ibl_rows(row, render, reference_spp) -> Reference:
    """Environment-lighting rungs (direct integrator, 4 spp) against the scene's path reference,
    which is returned."""
    scene, cam = ibl_scene()
    one = [("ibl scene", scene, cam)]
    reference = Reference(render, scene, cam, reference_spp)
    for label, ibl in IBL_RUNGS:
        row("ibl", label + ", spp=4", lambda s, c, ibl=ibl: render(s, c, spp=4, ibl=ibl), [reference], one)
    return reference


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


def texture_filter_rows(row, render, reference_spp) -> Reference:
    """Texture filter rungs on the brick floor against its path reference (bilinear lookups at
    every sample: the box-filtered texture), which is returned."""
    scene, cam = texture_floor()
    one = [("brick floor", scene, cam)]
    reference = Reference(render, scene, cam, reference_spp)
    for texture_filter in ("trilinear", "bilinear"):
        for spp in (1, 4):
            label = f"{texture_filter}, spp={spp}" + (" (default)" if texture_filter == "trilinear" and spp == 1 else "")
            row("texture filter", label, lambda s, c, f=texture_filter, n=spp: render(s, c, spp=n, texture_filter=f),
                [reference], one)
    return reference


# the environment light of the "sampled" rungs: 8 shadowed directions per sample
SAMPLED_GLASS_IBL = pw.IBL(method="monte_carlo", samples=8, shadowed=True)


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


def transmission_rows(row, render, reference_spp) -> Reference:
    """Rough transmission rungs: "prefiltered" (split-sum environment light; objects behind the
    glass stay sharp) and "sampled" (Monte Carlo environment light; the GGX transmission lobe
    sampled per camera sample), against the scene's path reference over the glass's pixels only
    (the reference, so restricted, is returned)."""
    scene, cam = glass_scene()
    one = [("glass", scene, cam)]
    reference = Reference(render, scene, cam, reference_spp)
    glass_only, _ = glass_scene(with_wall=False)
    reference.covered = render(glass_only, cam, background=(0.0, 0.0, 0.0)).alpha > 0
    reference.own_rel_mse = reference.half_rel_mse(reference.covered)
    rungs = [("prefiltered", spp, None) for spp in (1, 4, 16)]
    rungs += [("sampled", spp, SAMPLED_GLASS_IBL) for spp in (4, 16, 64)]
    for name, spp, ibl in rungs:
        label = f"{name}, spp={spp}" + (" (default)" if name == "prefiltered" and spp == 1 else "")
        row("transmission", label, lambda s, c, n=spp, i=ibl: render(s, c, spp=n, ibl=i), [reference], one)
    return reference


def direct_misses_sheet(entries, path):
    """One row per scene: path reference, direct default, |difference| amplified 4x (tone-mapped)."""
    from PIL import Image, ImageDraw

    h, w = entries[0][1].rgb.shape[:2]
    label_w, top = 110, 16
    out = Image.new("RGB", (label_w + 3 * w, top + h * len(entries)), (20, 20, 20))
    draw = ImageDraw.Draw(out)
    for j, title in enumerate(("path reference", "direct (default)", "|difference| x4")):
        draw.text((label_w + j * w + 4, 2), title, fill=(230, 230, 230))
    for i, (name, reference, direct) in enumerate(entries):
        a, b = reference.to_srgb8()[..., :3], direct.to_srgb8()[..., :3]
        difference = np.clip(np.abs(a.astype(np.int16) - b.astype(np.int16)) * 4, 0, 255).astype(np.uint8)
        draw.text((4, top + i * h + h // 2 - 6), name, fill=(230, 230, 230))
        for j, image in enumerate((a, b, difference)):
            out.paste(Image.fromarray(image), (label_w + j * w, top + i * h))
    out.save(path)


def smallest_errors(rows, names, own_scenes):
    """Per scene, the smallest nonzero relMSE of its rows (the report scenes' per-scene columns;
    a scene of its own, its rows' relMSE)."""
    smallest = {}
    for k, name in enumerate(names):
        errors = [r["per_scene"][k] for r in rows if r["scene"] == "report" and r["per_scene"][k] > 0]
        smallest[name] = min(errors, default=0.0)
    for name in own_scenes:
        errors = [r["rel_mse"] for r in rows if r["scene"] == name and r["rel_mse"] > 0]
        smallest[name] = min(errors, default=0.0)
    return smallest


def report_markdown(payload) -> str:
    """The report's table and notes from its JSON payload."""
    rows, names, own = payload["rows"], payload["scenes"], payload["reference_own_rel_mse"]
    width, height = payload.get("size", (160, 120))
    smallest = smallest_errors(rows, names, [n for n in own if n not in names])
    header = ("| family | rung | ms | ns / BRDF eval | relMSE (mean) | FLIP (mean) | "
              + " | ".join(f"relMSE {n}" for n in names) + " |")
    lines = [header, "|" + "---|" * (6 + len(names))]
    for r in rows:
        fl = f"{r['flip']:.4f}" if r["flip"] is not None else "n/a"
        per_scene = [f"{e:.3g}" for e in r["per_scene"]] if r["scene"] == "report" else [""] * len(names)
        ns = f"{r['ns_per_brdf_eval']:.1f}" if "ns_per_brdf_eval" in r else ""
        lines.append(f"| {r['family']} | {r['rung']} | {r['ms']:.0f} | {ns} | {r['rel_mse']:.3g} | {fl} | "
                     + " | ".join(per_scene) + " |")
    noisy = [n for n in own if smallest[n] and own[n] > smallest[n] / 10]
    lines += ["", f"{width}x{height} frames on every core. Reference: integrator=\"path\", max_bounces={REFERENCE_BOUNCES}, "
              f"quality=reference, {payload['reference_spp']} spp as two independent halves. Its own relMSE "
              "(relMSE(half A, half B) / 4) per scene, and the fraction it is of the scene's smallest nonzero "
              "error: " + ", ".join(f"{n} {own[n]:.2g} ({_fraction(own[n], smallest[n])})" for n in own if own[n] > 0)
              + ("." if not noisy else f"; above the tenth the report needs in {', '.join(noisy)}: "
                 "raise --reference-spp."),
              "Rows without per-scene errors have a scene of their own (ibl: an HDR-lit sphere grid; texture "
              "filter: a grazing brick floor; transmission: a rough glass slab before a brick wall, over the glass's "
              "pixels; each against its own path reference). relMSE leaves out the 0.1% of each image's "
              "pixels with the largest errors (fireflies). ms: the row's own spp, median, summed "
              "over the scenes it covers (ms of the shadow-map rows include rasterizing the maps); ns / BRDF eval: a "
              "kernel of 1e7 evaluations of the row's BRDF on one thread, minus the cost of its random inputs. "
              "Direct-integrator rows' error includes what direct lighting misses (interreflection, the emissive "
              "light of the Cornell box): see the figure below. The integrator rows (path) use the reference's BRDF, "
              "so they differ from it in bounces and samples alone: the direct integrator at that BRDF is the row "
              "quality=reference, spp=4.",
              "", "![error vs time](accuracy.png)", "",
              "What direct lighting misses, per scene: path reference, direct default, |difference| x4 (tone-mapped):",
              "", "![direct misses](accuracy_direct_misses.png)"]
    lines += ["", *payload.get("notes", [])] if payload.get("notes") else []
    return "\n".join(lines) + "\n"


def _fraction(part: float, whole: float) -> str:
    """``part`` as a fraction of ``whole``: "1/N", or "Nx" where it is larger."""
    if not whole > 0.0:
        return "no error to compare"
    return f"1/{whole / part:.0f}" if whole >= 1.5 * part else f"{part / whole:.2g}x"


def update_transmission_rows(ap, args, render, out):
    """Re-run the transmission rows and their reference into DIR/accuracy.json, keeping the other
    rows; the report notes which rows come from which run."""
    from common import machine

    path = Path(out) / "accuracy.json"
    payload = json.loads(path.read_text())
    rows = [r for r in payload["rows"] if r["family"] != "transmission"]
    kept = len(rows)

    def row(family, label, make, refs, scene_list):
        return measured_row(rows, family, label, make, refs, scene_list, args.repeats, scene_list[0][0])

    reference = transmission_rows(row, render, args.reference_spp)
    info = machine()
    payload["rows"] = rows
    payload["reference_own_rel_mse"]["glass"] = reference.own_rel_mse
    payload.setdefault("notes", []).append(
        f"The {len(rows) - kept} transmission rows and the glass's reference were re-run by `{command_line(ap, args)}` "
        f"at commit {info['commit']} ({info['date']}), after the path tracer learnt to refract; the other rows "
        "are the run above.")
    path.write_text(json.dumps(payload, indent=2) + "\n")
    rewrite(out)
    plot(payload["rows"], Path(out) / "accuracy.png")


def rewrite(directory=RESULTS):
    """Rewrite accuracy.md from accuracy.json, keeping the run's command, machine, commit and date
    (python -c "import accuracy; accuracy.rewrite()" in bench/)."""
    directory = Path(directory)
    payload = json.loads((directory / "accuracy.json").read_text())
    info = payload["machine"]
    header = (f"Command: `{payload['command']}`\n\nMachine: {info['cpu']}, {info['cores']} cores; Python "
              f"{info['python']}, warp {info['warp']}; commit {info['commit']}; {info['date']}.\n\n")
    (directory / "accuracy.md").write_text(header + report_markdown(payload))


def replot(directory=RESULTS):
    """Redraw accuracy.png from accuracy.json (python -c "import accuracy; accuracy.replot()" in bench/)."""
    directory = Path(directory)
    plot(json.loads((directory / "accuracy.json").read_text())["rows"], directory / "accuracy.png")


def pareto_front(points):
    """The (x, error, row) points no other point beats in both time and error, by increasing x."""
    front, best = [], float("inf")
    for p in sorted(points, key=lambda p: (p[0], p[1])):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def plot(rows, path):
    """relMSE against time, log axes, one panel per scene set; the Pareto front drawn and its
    points labelled."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed (pip install -e '.[bench]'): no plot", file=sys.stderr)
        return
    colours = {"preset": "black", "diffuse": "tab:green", "distribution": "tab:purple", "geometry": "tab:blue",
               "fresnel": "tab:orange", "energy": "tab:olive", "coupling": "tab:cyan", "model": "tab:pink",
               "metallic_mix": "gold", "sampling": "tab:red", "shadows": "tab:brown", "integrator": "darkred",
               "ibl": "tab:gray", "texture filter": "teal", "transmission": "tab:blue"}
    panels = (("report", "report scenes (sum of their frames)"), ("ibl scene", "environment light (vs path)"),
              ("brick floor", "texture filters (vs path)"),
              ("glass", "rough transmission (vs path, the glass's pixels)"))
    fig, axes = plt.subplots(1, len(panels), figsize=(8 + 6 * (len(panels) - 1), 6), dpi=110,
                             gridspec_kw={"width_ratios": [1.6] + [1] * (len(panels) - 1)})
    floor = 1e-8  # a row with error 0 sits on the floor of the log axis
    for ax, (scene, title) in zip(axes, panels):
        points = [(max(r["ms"], 0.1), max(r["rel_mse"], floor), r) for r in rows if r["scene"] == scene]
        if not points:
            continue
        for x, err, r in points:
            ax.scatter(x, err, color=colours[r["family"]], s=22, zorder=3)
        front = pareto_front(points)
        ax.plot([p[0] for p in front], [p[1] for p in front], color="grey", lw=1.0, ls="--", zorder=2, label="Pareto front")
        for x, err, r in front:
            ax.annotate(r["rung"], (x, err), fontsize=7, xytext=(4, 3), textcoords="offset points")
        for family in dict.fromkeys(r["family"] for _, _, r in points):
            ax.scatter([], [], color=colours[family], label=family)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time (ms, all cores)")
        ax.set_ylabel("relMSE vs reference (mean over scenes)")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="best")
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("pbrwarp: what accuracy costs in time (error against a path-traced ground truth)")
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    main()
