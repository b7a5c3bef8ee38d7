"""The render entry point: upload the scene, pick the kernel for its features, launch it once per
thread from a thread pool (Warp CPU launches run on one thread and release the GIL), every launch
taking rows from one shared counter."""

from __future__ import annotations

import functools
import inspect
import math
import threading

import numpy as np
import warp as wp

from . import huge_pages, validate
from .brdf import BRDF, brdf_for_quality
from .camera import Camera
from .errors import InputError, InputTypeError
from .emitters import light_table
from .features import (DEFAULT_MAX_BOUNCES, MAX_BOUNCES, Features, check_integrator, decide, describe, path_features,
                       scene_features)
from .frame import Frame
from .gpu_scene import back_face_culling, upload
from .ibl import IBL, ibl_for_quality
from .lights import AreaLighting, area_lighting_for_quality
from .parallel import progress_bar, run_all, thread_count
from .progressive import Accumulation, checked_positive
from .raster import reused_buffer, visibility_buffer
from .light_buffers import build as build_light_buffers, no_light_buffers
from .shadow_maps import build as build_shadow_maps, no_shadow_maps, shadow_mode
from .scene import Scene
from pbrwarp.kernels.camera import CameraData
from pbrwarp.kernels.loading import load_for_cpu
from pbrwarp.kernels.dfg import dfg_table
from pbrwarp.kernels.ibl import EnvironmentData
from pbrwarp.kernels.path import path_kernel
from pbrwarp.kernels.render import ROWS_TAKEN, STOP, WORK_SLOTS, render_kernel

# One launch per thread, each taking ROWS_PER_TAKE rows at a time from one shared counter until
# none are left, so that the threads finish together even where rows cost unevenly (fixed bands
# of rows per thread leave the threads with the cheap bands idle). Progress is read off the
# counter; an interrupt sets the stop flag beside it, which the launches check at every pixel
# (kernels/render.py).
ROWS_PER_TAKE = 4
# Seconds between progress bar updates.
PROGRESS_INTERVAL = 0.1


def _environment_arguments(scene: Scene, threads):
    """The render kernel's environment and DFG table: the scene's, or an inert black one for the
    all-effects kernel of a scene without an environment."""
    environment = scene.environment if scene.environment is not None else _black_environment()
    return environment.data(threads), dfg_table()


@functools.cache
def _black_environment():
    from .environment import Environment

    return Environment.uniform((0.0, 0.0, 0.0))


@functools.cache
def _no_environment():
    """Placeholders for kernels compiled without environment lighting (never read)."""
    return EnvironmentData(), wp.zeros((2, 2), dtype=wp.vec2, device="cpu")


def _stratification_grid(spp: int) -> tuple[int, int]:
    """(m, n) with m n = spp and m the largest divisor of spp not above sqrt(spp)."""
    m = max(d for d in range(1, math.isqrt(spp) + 1) if spp % d == 0)
    return m, spp // m


def _camera_data(camera: Camera, width: int, height: int) -> CameraData:
    tan_half = math.tan(math.radians(camera.fov_y) / 2.0)
    data = CameraData()
    data.eye = wp.vec3(*camera.eye)
    data.forward = wp.vec3(*camera.forward)
    data.right = wp.vec3(*(np.asarray(camera.right) * tan_half * width / height))
    data.up = wp.vec3(*(np.asarray(camera.up) * tan_half))
    data.width, data.height = width, height
    return data


def _run_with_progress(launch, workers: int, rows_taken: wp.array, height: int, progress):
    """launch(k) for k in range(workers) on as many threads, a progress bar (if enabled and tqdm
    is installed) following the rows taken from ``rows_taken`` meanwhile; an interrupt (or
    error) sets its stop flag, ending every launch at its next pixel."""
    counters = rows_taken.numpy()  # a view: the kernels' counter as they advance it, and the flag

    def stop():
        counters[int(STOP)] = 1

    # delay: the bar appears only for renders that take more than about a second
    bar = progress_bar(progress, total=height, unit="row", desc="render", delay=1.0, leave=False)
    if bar is None:
        run_all(launch, range(workers), workers, cancel=stop)
        return
    done = threading.Event()

    def follow():
        finished = False
        while not finished:
            finished = done.wait(PROGRESS_INTERVAL)
            bar.update(min(int(counters[int(ROWS_TAKEN)]) * ROWS_PER_TAKE, height) - bar.n)

    follower = threading.Thread(target=follow, daemon=True)
    follower.start()
    try:
        run_all(launch, range(workers), workers, cancel=stop)
    finally:
        done.set()
        follower.join()
        bar.close()


def render(
    scene: Scene,
    camera: Camera | None = None,
    width: int = 800,
    height: int = 600,
    spp: int = 1,
    threads: int | None = None,
    shadows=True,
    background=None,
    seed: int = 0,
    progress: bool | None = None,
    aovs: bool = True,
    specialize: bool = True,
    quality: str | None = None,
    brdf: BRDF | None = None,
    visibility: str = "auto",
    ibl: IBL | None = None,
    texture_filter: str = "trilinear",
    integrator: str = "direct",
    max_bounces: int | None = None,
    first_sample: int = 0,
    area_lighting: AreaLighting | None = None,
    time_budget: float | None = None,
    target_error: float | None = None,
) -> Frame:
    """Render ``scene`` seen by ``camera`` into a :class:`Frame` of linear radiance.

    - ``camera``: a :class:`Camera`; by default the scene file's first camera, else one framing
      the whole scene (``Camera.frame(scene, aspect=width / height)``).
    - ``width`` x ``height``: the image in pixels (default 800 x 600), each at most 65536.
    - ``spp``: samples per pixel (default 1: pixel centres), multi-jittered, at most 46340. A
      frame holds at most 2^31 - 1 samples (width * height * spp) and 2^28 - 1 in a row
      (width * spp), and its buffers (44 bytes a pixel, 16 with ``aovs=False``, plus 16 bytes a
      sample where primary visibility is rasterized) at most half the memory the process may use
      (less under a ``ulimit``). docs/limits.md says why.
    - ``threads``: pool threads running the launches, 1 to 4 per core (default: one per core);
      the image does not depend on it.
    - ``shadows``: True or "rays" (default) traces a shadow ray per light and hit (the reference)
      through the light's light buffer, or Warp's BVH where the buffer cannot tell; "map" or a
      :class:`ShadowMap` looks shadows up in depth maps rasterized from each light (faster,
      approximate); False or None renders none.
    - ``background``: linear RGB radiance where no surface is hit (``frame.alpha`` records the
      coverage); by default the scene's environment where it has one, else black.
    - ``seed``: an integer (default 0, taken modulo 2^31) choosing the random sample positions
      (spp > 1) and Monte Carlo environment directions; frames rendered with different seeds
      average to one with more samples.
    - ``progress``: None or True shows a progress bar (if tqdm is installed) for renders longer
      than about a second; False never.
    - ``aovs``: False skips the depth, normal and albedo outputs (``frame.depth``, ``frame.normal``
      and ``frame.albedo`` are then None); default True.
    - ``specialize``: False runs the kernel with every effect compiled in, and ray-cast primary
      visibility, instead of the one built for this scene (same image, slower; for comparison).
    - ``quality``: "fast", "balanced" (None, the default), "accurate" or "reference", a preset of
      BRDF, environment-lighting and area-light rungs (pbrwarp.brdf.PRESETS; docs/accuracy.md).
      ``brdf`` (:class:`BRDF`), ``ibl`` (:class:`IBL`) and ``area_lighting``
      (:class:`AreaLighting`) choose those rungs themselves and win over it.
    - ``visibility``: how each camera sample finds its surface: "raycast" (a BVH query per
      sample), "raster" (a rasterized visibility buffer, then the ray caster's own ray-triangle
      test on the triangle it names, so both shade identically where they pick the same
      triangle), or "auto" (the default: the cheaper by the cost model bench/visibility.py fits,
      and ray casting where the buffer would exceed 1 GiB).
    - ``texture_filter``: "trilinear" (the default) filters each texture lookup over the sample's
      footprint on the surface (ray differentials of one pixel, or of one of ``spp`` strata), from
      the texture's mip levels; "bilinear" reads the full-resolution image only (cheaper; textures
      finer than the pixels alias). docs/materials.md says how.
    - ``integrator``: "direct" (the default) shades the first surface each camera sample meets
      with the light of the lights and the environment, reflected once; "path" traces paths
      through the scene (docs/integrators.md): light bouncing between surfaces, emissive
      materials as lights, next-event estimation with multiple importance sampling, ground truth
      for the direct integrator's approximations. The path tracer traces its own shadow rays
      (``shadows`` must be True or "rays"), ray casts primary visibility, ignores ``ibl`` (BRDF
      rungs still apply), filters textures over one pixel's footprint at the first surface and
      at full resolution after a bounce. It passes light through smooth thin transmissive walls,
      but does not simulate clear coat, sheen or volumes yet, and passes light straight through
      rough transmissive surfaces: a scene with them is rendered without them, with a warning
      naming them and what is rendered instead. Each pixel's ``spp`` samples are paths through
      random points of the pixel.
    - ``max_bounces``: with ``integrator="path"``, the most times light is scattered between an
      emitter and the eye (default 7: paths of up to 8 segments; 0 shows emission and the
      background only, 1 is direct lighting), a whole number from 0 to 1024.
    - ``first_sample``: with ``integrator="path"``, the index of the first sample per pixel
      (default 0). Sample s of a pixel depends on ``seed``, the pixel and s alone (counter-based
      random numbers), so a render of samples [a, b) continues one of [0, a): (a * frame_0_a.rgb
      + (b - a) * frame_a_b.rgb) / b is the render of ``spp=b``, up to rounding, for the same
      ``seed`` and options; renders with different seeds are independent.
    - ``area_lighting``: how sphere and rectangle lights are integrated, an :class:`AreaLighting`:
      the representative point (the default; noise-free, hard shadows) or Monte Carlo with N
      shadowed samples per light and hit (soft shadows; the "reference" preset's, with 64).
      docs/lighting.md says what each costs.
    - ``time_budget``: seconds (above 0), with ``integrator="path"``: render progressively, in
      passes of ``spp`` samples (continuing each other, from ``first_sample``), adding passes
      while another, at the mean duration of those so far, fits in the budget; the first pass
      always completes. The frame's ``spp`` says how many samples it holds, its ``variance`` how
      noisy each pixel still is (docs/integrators.md, "Progressive rendering"). Default None.
    - ``target_error``: with ``integrator="path"``, render in passes of ``spp`` samples as for
      ``time_budget``, and stop once ``frame.relative_error()`` (the mean relative standard error
      of the covered pixels) is at most this; without a ``time_budget``, at the latest after
      pbrwarp.progressive.MAX_SAMPLES_PER_CALL samples. Default None. :class:`Accumulator`
      accumulates across calls.

    Without ``time_budget`` and ``target_error`` a render holds exactly ``spp`` samples per pixel
    (``frame.spp``) and has no ``variance``.

    Raises InputTypeError for a scene, camera or option of the wrong type, InputError for a value
    out of range, a scene without meshes, a frame past a limit (before anything is allocated) or
    a time budget or target error with the direct integrator,
    ResourceError when the system refuses a thread. A KeyboardInterrupt (Ctrl-C) stops every
    launch of the render at once and propagates; the next render in the process is unaffected.
    :func:`explain` says what is simulated; the scene's derived data (uploaded geometry, light
    buffers, ...) is kept in ``scene.cache`` for the next render, and a ``Scene`` may be rendered
    from several threads at once.
    """
    time_budget = checked_positive(time_budget, "time_budget")
    target_error = checked_positive(target_error, "target_error")
    progressive = time_budget is not None or target_error is not None
    run = _renderer(scene, camera, width, height, spp, threads, shadows, background, seed, aovs, specialize, quality,
                    brdf, visibility, ibl, texture_filter, integrator, max_bounces, first_sample, area_lighting,
                    progressive=progressive)
    if not progressive:
        return run(spp, first_sample, progress)
    return Accumulation(run, (width, height), spp, first_sample, progress).add(time_budget=time_budget,
                                                                               target_error=target_error)


class Accumulator(Accumulation):
    """A path-traced image refined by adding samples, call after call.

    ``pw.Accumulator(scene, camera=None, width=800, height=600, spp=1, **options)`` takes
    :func:`render`'s options (``integrator`` defaults to "path", the only one that can be
    continued; ``first_sample`` is the index the first pass starts at, default 0; ``progress`` is
    that of :meth:`add`'s passes). ``spp`` is the samples per pixel of each pass. Options are
    checked and the kernel chosen once, here: InputError for integrator="direct",
    InputTypeError for ``time_budget`` or ``target_error`` (:meth:`add`'s) or an unknown option.

    :meth:`add` (``spp=None``, ``time_budget=None``, ``target_error=None``) renders passes and
    returns the frame of all samples so far, also kept as :attr:`frame`; :attr:`spp` is their
    count per pixel. Sample indices continue where the last pass ended, so the frame equals one
    render of :attr:`spp` samples (up to float rounding), and ``frame.variance`` estimates each
    pixel's variance from the passes' spread (docs/integrators.md, "Progressive rendering").

    Thread-safe: :meth:`add` calls from several threads run one after another (a lock), each
    adding its passes to the same image. An interrupted pass (Ctrl-C) adds nothing.
    """

    def __init__(self, scene: Scene, camera: Camera | None = None, width: int = 800, height: int = 600,
                 spp: int = 1, integrator: str = "path", first_sample: int = 0, progress: bool | None = None,
                 **options):
        unknown = sorted(set(options) - (set(inspect.signature(_renderer).parameters) - {"progressive"}))
        if unknown:
            raise InputTypeError(f"Accumulator got {', '.join(map(repr, unknown))}, which it does not take "
                                 "(render's options but time_budget and target_error, which are add's)")
        run = _renderer(scene, camera, width, height, spp, integrator=integrator, first_sample=first_sample,
                        progressive=True, **options)
        super().__init__(run, (width, height), spp, first_sample, progress)


def _renderer(scene, camera, width, height, spp, threads=None, shadows=True, background=None, seed=0, aovs=True,
              specialize=True, quality=None, brdf=None, visibility="auto", ibl=None, texture_filter="trilinear",
              integrator="direct", max_bounces=None, first_sample=0, area_lighting=None, progressive=False):
    """render's options (but ``progress``, ``time_budget`` and ``target_error``) checked and its
    kernel's features decided: a function (spp, first_sample, progress) -> Frame rendering those samples. The path
    tracer's renders any count from any first sample (checked by the caller); the direct
    integrator's the ``spp`` given only. ``progressive`` asks for the path tracer (InputError
    for the direct integrator, whose samples are stratified per render)."""
    if not isinstance(scene, Scene):
        raise InputTypeError(f"render takes a pbrwarp.Scene, got {type(scene).__name__}")
    width, height, spp = validate.render_size(width, height, spp, aovs=bool(aovs),
                                              rasterized=bool(specialize) and visibility != "raycast",
                                              progressive=progressive)
    if threads is not None:
        threads = thread_count(threads)  # bounded before any work starts
    background_given = background is not None
    background = validate.colour(background if background_given else (0.0, 0.0, 0.0), "background")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputTypeError(f"seed must be an integer, got {seed!r}")
    if camera is None:
        camera = scene.cameras[0] if scene.cameras else Camera.frame(scene, aspect=width / height)
    elif not isinstance(camera, Camera):
        raise InputTypeError(f"camera must be a pbrwarp.Camera, got {type(camera).__name__}")

    path, max_bounces, first_sample = _path_options(integrator, max_bounces, first_sample, spp, shadows)
    if progressive and not path:
        raise _progressive_needs_path()

    ibl = ibl_for_quality(quality, ibl)
    brdf = brdf_for_quality(quality, brdf)
    area_lighting = area_lighting_for_quality(quality, area_lighting)
    gpu = upload(scene)
    options = dict(shadows=shadows, spp=spp, aovs=aovs, brdf=brdf, visibility=visibility, samples=width * height * spp,
                   ibl=ibl, background_given=background_given, texture_filter=texture_filter, integrator=integrator,
                   max_bounces=max_bounces, area_lighting=area_lighting)
    features = scene_features(scene, gpu, **options)
    if not specialize:
        features = Features.everything(spp, aovs, brdf, shadows, ibl, features.environment_background, texture_filter,
                                       area_lighting)
    if path:
        return functools.partial(_render_path, scene, gpu, path_features(features), camera, width, height, seed,
                                 max_bounces, threads, background)
    return functools.partial(_render_direct, scene, gpu, features, camera, width, height, seed, threads, background,
                             shadows)


def _output_buffers(width: int, height: int, aovs: bool):
    """The kernels' outputs: rgb, alpha, and the depth, normal and albedo AOVs ((1, 1) placeholders
    without aovs), on huge pages: fresh pages would fault one by one as the threads first write
    them."""
    aov_shape = (height, width) if aovs else (1, 1)
    return (huge_pages.empty((height, width), wp.vec3), huge_pages.empty((height, width), float),
            huge_pages.empty(aov_shape, float), huge_pages.empty(aov_shape, wp.vec3),
            huge_pages.empty(aov_shape, wp.vec3))


def _render_direct(scene: Scene, gpu, features: Features, camera: Camera, width: int, height: int, seed, threads,
                   background, shadows, spp: int, first_sample: int, progress) -> Frame:
    """render(..., integrator="direct") once its options are checked and its features decided
    (first_sample is 0)."""
    kernel = render_kernel(features)
    grid_m, grid_n = _stratification_grid(spp)
    cam = _camera_data(camera, width, height)
    out_rgb, out_alpha, out_depth, out_normal, out_albedo = _output_buffers(width, height, features.aovs)
    bg = wp.vec3(*background)
    seed = int(seed) % (2**31)
    maps = (build_shadow_maps(scene, gpu, shadow_mode(shadows)[1], threads) if features.shadows == "map"
            else no_shadow_maps())
    buffers = build_light_buffers(scene, gpu, threads) if features.shadows == "rays" else no_light_buffers()
    env, dfg = _environment_arguments(scene, threads) if features.environment else _no_environment()
    if features.visibility == "raster":
        cull, _ = back_face_culling(scene, gpu, camera.eye)
        vbuffer = visibility_buffer(gpu.data.positions, gpu.data.indices, cam, spp, grid_m, grid_n, seed, threads,
                                    out=reused_buffer("camera", height, width * spp), cull_back_faces=cull,
                                    clusters=gpu.clusters)
    else:
        vbuffer = wp.empty((1, 1), dtype=wp.uint64, device="cpu")

    rows_taken = wp.zeros(WORK_SLOTS, dtype=wp.int32, device="cpu")

    def launch(_):
        wp.launch(kernel, dim=1, device="cpu",
                  inputs=[gpu.data, cam, spp, grid_m, grid_n, seed, rows_taken, ROWS_PER_TAKE, bg,
                          out_rgb, out_alpha, out_depth, out_normal, out_albedo, vbuffer, maps, buffers, env, dfg])

    # compile or load the kernel once, before many threads would all try at once
    load_for_cpu(kernel)
    _run_with_progress(launch, thread_count(threads), rows_taken, height, progress)
    return _frame(out_rgb, out_alpha, out_depth, out_normal, out_albedo, features.aovs, width, height, background,
                  spp)


def _progressive_needs_path() -> InputError:
    return InputError("progressive rendering (time_budget, target_error, pw.Accumulator) needs integrator='path': "
                      "the direct integrator's samples are stratified per render, so a render cannot be continued; "
                      "pass integrator='path', or average direct renders of different seeds")


def _path_options(integrator, max_bounces, first_sample, spp: int, shadows):
    """(whether the path tracer renders, max_bounces, first_sample), checked: the last two apply
    to integrator="path" only, as do its shadows (traced)."""
    path = check_integrator(integrator) == "path"
    if not path:
        if max_bounces is not None:
            raise InputError("max_bounces applies to integrator='path'; the direct integrator reflects light once")
        if not (isinstance(first_sample, (int, np.integer)) and not isinstance(first_sample, bool)
                and first_sample == 0):
            raise InputError(f"first_sample applies to integrator='path' (got {first_sample!r}); the direct "
                             "integrator's samples are stratified per render: use seed= for independent renders")
        return False, None, 0
    if max_bounces is None:
        max_bounces = DEFAULT_MAX_BOUNCES
    for name, value, high in (("max_bounces", max_bounces, MAX_BOUNCES), ("first_sample", first_sample, None)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise InputTypeError(f"{name} must be a whole number, got {value!r}")
        if value < 0 or (high is not None and value > high):
            raise InputError(f"{name} must be a whole number from 0 to {high if high is not None else 2**31 - 1 - spp}"
                             f", got {value}")
    if first_sample + spp > 2**31 - 1:
        raise InputError(f"first_sample + spp must be below 2^31, got {first_sample} + {spp}")
    mode, _ = shadow_mode(shadows)
    if mode != "rays":
        raise InputError(f"the path tracer traces its own shadow rays: shadows must be True or 'rays' with "
                         f"integrator='path', got {shadows!r}")
    return True, int(max_bounces), int(first_sample)


def _render_path(scene: Scene, gpu, features: Features, camera: Camera, width: int, height: int, seed,
                 max_bounces: int, threads, background, spp: int, first_sample: int, progress) -> Frame:
    """render(..., integrator="path") once its options are checked and its features decided."""
    kernel = path_kernel(features)
    cam = _camera_data(camera, width, height)
    out_rgb, out_alpha, out_depth, out_normal, out_albedo = _output_buffers(width, height, features.aovs)
    env = _environment_arguments(scene, threads)[0] if features.environment else _no_environment()[0]
    lights = light_table(scene, gpu, environment_lights=bool(features.environment))
    rows_taken = wp.zeros(WORK_SLOTS, dtype=wp.int32, device="cpu")
    inputs = [gpu.data, cam, spp, first_sample, int(seed) % (2**31), max_bounces, rows_taken, ROWS_PER_TAKE,
              wp.vec3(*background), out_rgb, out_alpha, out_depth, out_normal, out_albedo, env, lights]

    def launch(_):
        wp.launch(kernel, dim=1, device="cpu", inputs=inputs)

    load_for_cpu(kernel)  # compiled or loaded once, before many threads would all try at once
    _run_with_progress(launch, thread_count(threads), rows_taken, height, progress)
    return _frame(out_rgb, out_alpha, out_depth, out_normal, out_albedo, features.aovs, width, height, background,
                  spp)


def _frame(out_rgb, out_alpha, out_depth, out_normal, out_albedo, aovs: bool, width: int, height: int,
           background, spp: int) -> Frame:
    """The Frame a render kernel's output arrays hold (depth, normal and albedo only with ``aovs``)."""
    return Frame(
        rgb=out_rgb.numpy().reshape(height, width, 3),
        depth=out_depth.numpy() if aovs else None,
        normal=out_normal.numpy().reshape(height, width, 3) if aovs else None,
        alpha=out_alpha.numpy(),
        background=background,
        albedo=out_albedo.numpy().reshape(height, width, 3) if aovs else None,
        spp=spp,
    )


def explain(scene: Scene, camera: Camera | None = None, shadows=True, spp: int = 1, aovs: bool = True, quality: str | None = None,
            brdf: BRDF | None = None, visibility: str = "auto", width: int = 800, height: int = 600,
            ibl: IBL | None = None, background=None, texture_filter: str = "trilinear", integrator: str = "direct",
            max_bounces: int | None = None, area_lighting: AreaLighting | None = None, **_render_options) -> str:
    """The text saying which effects :func:`render` with these options simulates for ``scene``,
    and why each absent one was dropped (e.g. "no shadow rays: one convex mesh cannot shadow
    itself ..."), with the estimated cost of each primary visibility path, and, last, what the
    scene's file asks for that pbrwarp does not honour (``scene.load_warnings``). Takes render's options
    (those that decide nothing it says, like ``camera`` or ``threads``, are accepted and ignored)
    and raises as render does for bad ones, and for a keyword render does not take. ``camera`` is
    taken in the place render takes it, so that ``explain(scene, camera, ...)`` reads as the
    render call it describes; what is simulated does not depend on it."""
    if not isinstance(scene, Scene):
        raise InputTypeError(f"explain takes a pbrwarp.Scene, got {type(scene).__name__}")
    if camera is not None and not isinstance(camera, Camera):
        raise InputTypeError(f"camera must be a pbrwarp.Camera, got {type(camera).__name__}")
    unknown = sorted(set(_render_options) - set(inspect.signature(render).parameters))
    if unknown:
        raise InputTypeError(f"explain got {', '.join(map(repr, unknown))}, which render does not take "
                             f"(render's options: {', '.join(list(inspect.signature(render).parameters)[1:])})")
    progressive = [checked_positive(_render_options.get(name), name) for name in ("time_budget", "target_error")]
    progressive = progressive != [None, None]
    width, height, spp = validate.render_size(width, height, spp, aovs=bool(aovs),
                                              rasterized=bool(_render_options.get("specialize", True))
                                              and visibility != "raycast", progressive=progressive)
    samples = width * height * spp
    path, bounces, _ = _path_options(integrator, max_bounces, _render_options.get("first_sample", 0), spp, shadows)
    if not path and progressive:
        raise _progressive_needs_path()
    return describe(decide(scene, upload(scene), shadows=shadows, spp=spp, aovs=aovs, brdf=brdf_for_quality(quality, brdf),
                           visibility=visibility, samples=samples, ibl=ibl_for_quality(quality, ibl),
                           background_given=background is not None, texture_filter=texture_filter,
                           integrator=integrator, max_bounces=DEFAULT_MAX_BOUNCES if bounces is None else bounces,
                           area_lighting=area_lighting_for_quality(quality, area_lighting)),
                    scene.load_warnings)
