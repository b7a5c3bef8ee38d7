"""Batches of renders on Dask distributed: :func:`render_batch` and ``pbrwarp batch``.

A job is one image, a JSON object (one per line of a ``.jsonl`` file)::

    {"id": "bunny-000", "scene": "bunny.glb", "output": "out/bunny-000.png",
     "camera": {"eye": [0, 1, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
     "width": 512, "height": 512, "spp": 4, "environment": "sky.hdr",
     "lights": ["dir:-1,-1,-1:3"], "integrator": "path", "seed": 7}

It means what the ``pbrwarp render`` command with those options means, and is parsed by the
command's own parser (:mod:`pbrwarp.render_options`): ``width``/``height`` (``--size``, default 800 x
600), ``spp``, ``environment`` (``--env``, a path or null), ``env_intensity``, ``lights`` (a list
of ``--light`` specs; the file's own lights are kept), ``shadows`` (true or "rays", "map", false),
``background`` ([r, g, b]), ``quality``, ``visibility``, ``texture_filter``, ``integrator``,
``max_bounces`` (``--bounces``), ``threads``, and the image's ``tonemap``, ``exposure`` and
``transparent``. Every other :func:`pbrwarp.render` keyword (``seed``, ``aovs``,
``first_sample``, ``time_budget``, ...) is passed to it as is. ``camera`` is an object with
``eye`` and ``target`` (and optionally ``up``, default +Y, and ``fov_y`` in degrees, default 45);
or ``"frame"``, or an object with ``direction`` (and optionally ``up``, ``fov_y``, ``margin``),
for :meth:`pbrwarp.Camera.frame`; absent, the scene file's first camera, else one framing the
scene. ``id`` (a string or an integer) names the job in the manifest. Relative paths are
relative to the jobs file's folder; output folders are created.

Each job becomes one Dask task. A worker process keeps the scenes it loaded (keyed by path,
modification time and size; the :data:`KEPT_SCENES` most recently used), with everything a
render derived from them (``Scene.cache``), and the environments it read (prefiltered once);
Warp keeps compiled kernels on disk. A worker process renders one job at a time, with every
core (a render already spreads over the cores).
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import socket
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import render_options, validate
from .camera import Camera, field_of_view
from .errors import InputError, PbrwarpError
from .parallel import cores, progress_bar
from .render import render
from .scene_cache import Cache

INSTALL_HINT = 'pip install "pbrwarp[batch]"'
MANIFEST_SUFFIX = ".manifest.jsonl"
# Scenes and environments a worker process keeps loaded, the least recently used dropped first:
# jobs arrive roughly in the order they were written, so a few cover a batch grouped by scene.
KEPT_SCENES = 4
KEPT_ENVIRONMENTS = 4
# Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536, which also turns off glibc's
# adaptive mmap threshold: every frame-sized buffer is then mapped afresh and page-faulted on first
# touch, a quarter more time per 512² job (bench/results/batch.md). Local clusters start without it.
WORKER_MALLOC_SETTING = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"
# The Dask settings of the local clusters pbrwarp starts (docs/batch.md "Cost"):
LOCAL_CLUSTER_SETTINGS = {
    WORKER_MALLOC_SETTING: None,
    # a worker holds one job at a time, the one it renders: when a job kills its worker, Dask
    # counts the death against every job the worker held, and after allowed-failures + 1 deaths
    # fails them all; held one at a time, only the job that kills is an "error" (Dask's default,
    # 1.1, holds two per single-threaded worker; more would spare the next job's round trip
    # through the scheduler, bench/results/batch.md)
    "distributed.scheduler.worker-saturation": 1.0,
    # no statistical profiler: its thread takes the GIL every 10 ms, from a render's Python parts too
    "distributed.worker.profile.enabled": False,
}

# job key -> the `pbrwarp render` option that takes its value
_OPTION_FLAGS = {
    "spp": "--spp", "tonemap": "--tonemap", "exposure": "--exposure", "threads": "--threads",
    "background": "--background", "quality": "--quality", "visibility": "--visibility",
    "texture_filter": "--texture-filter", "integrator": "--integrator", "max_bounces": "--bounces",
    "env_intensity": "--env-intensity", "environment": "--env", "time_budget": "--time-budget",
    "target_error": "--target-error",
}
# keys read by the batch itself, or turned into `pbrwarp render` arguments in their own way
_OWN_KEYS = ("id", "scene", "output", "camera", "width", "height", "lights", "shadows", "transparent")
# pw.render keywords a job passes to it as they are (those the command line has no option for)
_RENDER_KEYWORDS = tuple(
    name for name in inspect.signature(render).parameters
    if name not in ("scene", "camera", "progress", "width", "height", "spp", "threads", "shadows", "background",
                    "quality", "visibility", "texture_filter", "integrator", "max_bounces", "time_budget",
                    "target_error"))
JOB_KEYS = _OWN_KEYS + tuple(_OPTION_FLAGS) + _RENDER_KEYWORDS
_SHADOW_FLAGS = {True: [], "rays": [], "map": ["--shadow-maps"], False: ["--no-shadows"], None: ["--no-shadows"]}
_RENDER_PARSER = render_options.render_parser()
_CAMERA_KEYS = {"look": ("eye", "target", "up", "fov_y"), "frame": ("direction", "up", "fov_y", "margin")}


@dataclass
class Job:
    """One image to render: the `pbrwarp render` command line it amounts to (parsed), its camera
    (None: the file's, else framing; a Camera; or Camera.frame's keywords) and further pw.render
    keywords."""

    id: str
    args: argparse.Namespace
    camera: object = None
    render_options: dict = field(default_factory=dict)

    @property
    def output(self) -> str:
        return self.args.output


def _record(job_id, status, output=None, seconds=0.0, worker=None, error=None, warnings_=()):
    """A manifest line."""
    return {"id": job_id, "status": status, "seconds": round(seconds, 3), "worker": worker, "error": error,
            "output": output, "warnings": list(warnings_)}


# ---------------------------------------------------------------------- reading jobs
def read_jobs(jobs, root=None) -> list:
    """The jobs of ``jobs`` (a path of a JSON-lines file, or an iterable of dicts), each a
    :class:`Job`, or the manifest record of its error if it cannot be rendered as written.
    Relative paths are relative to the file's folder (for dicts: ``root``, default the current
    folder)."""
    if isinstance(jobs, (str, os.PathLike)):
        path = os.fspath(jobs)
        root = os.path.dirname(os.path.abspath(path))
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().splitlines()
        except OSError as err:
            raise InputError(f"cannot read the jobs file {path}: {err.strerror or err}") from None
        except UnicodeDecodeError as err:
            raise InputError(f"the jobs file {path} is not UTF-8 text (byte {err.start})") from None
        label = "line"
        entries = []
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                entries.append((number, json.loads(line)))
            except json.JSONDecodeError as err:
                entries.append((number, InputError(f"line {number} of {path} is not JSON: {err.msg}")))
    else:
        root = os.path.abspath(os.getcwd() if root is None else os.fspath(root))
        label = "job"
        entries = list(enumerate(jobs, 1))
    parsed, ids, outputs = [], {}, {}
    for number, entry in entries:
        job_id = entry.get("id") if isinstance(entry, dict) else None
        name = str(job_id) if isinstance(job_id, (str, int)) and not isinstance(job_id, bool) else f"{label} {number}"
        try:
            if isinstance(entry, Exception):
                raise entry
            job = parse_job(entry, root)
            for seen, key, what in ((ids, job.id, "id"), (outputs, os.path.normcase(job.output), "output")):
                if key in seen:
                    raise InputError(f"its {what} is that of {label} {seen[key]}")
                seen[key] = number
            parsed.append(job)
        except (PbrwarpError, render_options.UsageError, OSError) as err:
            output = entry.get("output") if isinstance(entry, dict) else None
            output = os.path.normpath(os.path.join(root, output)) if isinstance(output, str) and output else None
            parsed.append(_record(name, "error", output, error=render_options.one_line(err)))
    return parsed


def parse_job(entry, root: str) -> Job:
    """A :class:`Job` from one job object (module docstring), its paths relative to ``root``.
    InputError naming the key for anything that cannot be rendered as written."""
    if not isinstance(entry, dict):
        raise InputError(f"a job must be a JSON object, got {type(entry).__name__}")
    job_id = entry.get("id")
    if isinstance(job_id, bool) or not isinstance(job_id, (str, int)):
        raise InputError(f"a job needs an \"id\", a string or an integer (got {job_id!r})")
    job_id = str(job_id)

    unknown = sorted(set(entry) - set(JOB_KEYS))
    if unknown:
        raise InputError(f"unknown key {unknown[0]!r} (a job's keys: {', '.join(JOB_KEYS)})")
    for key in ("scene", "output"):
        if not isinstance(entry.get(key), str) or not entry[key]:
            raise InputError(f"{key!r} must be a path")

    def path_of(key):
        return os.path.normpath(os.path.join(root, os.path.expanduser(entry[key])))

    argv = [path_of("scene"), "--output=" + path_of("output"),
            f"--size={entry.get('width', 800)}x{entry.get('height', 600)}"]
    for key, flag in _OPTION_FLAGS.items():
        value = entry.get(key)
        if value is None:
            continue
        if key == "environment":
            if not isinstance(value, str):
                raise InputError("'environment' must be a path or null")
            value = path_of(key)
        elif isinstance(value, list):
            value = ",".join(map(str, value))
        argv.append(f"{flag}={value}")
    lights = entry.get("lights") or []
    if not isinstance(lights, list) or not all(isinstance(spec, str) for spec in lights):
        raise InputError("'lights' must be a list of light specs as `pbrwarp render --light` takes them, "
                  "e.g. [\"dir:-1,-1,-1:3\"]")
    argv += [f"--light={spec}" for spec in lights]
    shadows = entry.get("shadows", True)
    if not isinstance(shadows, (bool, str, type(None))) or shadows not in _SHADOW_FLAGS:
        raise InputError(f"'shadows' must be true, \"rays\", \"map\" or false, got {shadows!r}")
    argv += _SHADOW_FLAGS[shadows]
    transparent = entry.get("transparent", False)
    if not isinstance(transparent, bool):
        raise InputError(f"'transparent' must be true or false, got {transparent!r}")
    if transparent:
        argv.append("--transparent")
    try:
        args = _RENDER_PARSER.parse_args(argv)
    except render_options.UsageError as err:
        raise InputError(_job_words(str(err))) from None
    for key in ("width", "height"):
        if isinstance(entry.get(key), bool):
            raise InputError(f"{key!r} must be a whole number of pixels")
    _check_paths(args)
    camera = _camera_spec(entry.get("camera"))
    return Job(job_id, args, camera, {key: entry[key] for key in _RENDER_KEYWORDS if key in entry})


def _job_words(message: str) -> str:
    """argparse's message about a `pbrwarp render` option, in the words of the job's keys."""
    for key, flag in {**_OPTION_FLAGS, "width/height": "--size", "lights": "--light"}.items():
        message = message.replace(f"argument {flag}:", f"{key!r}:")
    return message


def _check_paths(args) -> None:
    """The scene and environment exist and can be read as such; the output can be written (its
    folder is created)."""
    from .environment import LOADABLE as ENVIRONMENTS
    from .scene import LOADABLE as SCENES
    from .validate import readable_file

    readable_file(args.input, "scene file", SCENES, "meshes and glTF scenes")
    if args.env is not None:
        readable_file(args.env, "environment image", ENVIRONMENTS, "equirectangular HDR images")
    os.makedirs(os.path.dirname(args.output), exist_ok=True)
    render_options.check_output(args.output, args.transparent)


def _camera_spec(value):
    if value is None:
        return None
    if value == "frame":
        return {}
    if not isinstance(value, dict):
        raise InputError(f"'camera' must be an object with eye and target, \"frame\", or an object with direction; "
                  f"got {value!r}")
    kind = "frame" if "direction" in value else "look"
    unknown = sorted(set(value) - set(_CAMERA_KEYS[kind]))
    if unknown or (kind == "look" and not {"eye", "target"} <= set(value)):
        raise InputError(f"'camera' takes {', '.join(_CAMERA_KEYS['look'])} (eye and target required), or "
                  f"{', '.join(_CAMERA_KEYS['frame'])} (direction required) to frame the scene; got "
                  f"{', '.join(sorted(value))}")
    try:
        if kind == "frame":
            validate.unit_vector(value["direction"], "'camera' direction")
            validate.unit_vector(value.get("up", (0.0, 1.0, 0.0)), "'camera' up")
            field_of_view(value.get("fov_y", 45.0))
            return dict(value)
        eye = validate.finite_vector(value["eye"], 3, "'camera' eye")
        target = validate.finite_vector(value["target"], 3, "'camera' target")
        if "up" in value:
            return Camera.look_at(eye, target, up=value["up"], fov_y=value.get("fov_y", 45.0))
        return render_options.look_at(eye, target, value.get("fov_y", 45.0))
    except PbrwarpError as err:
        raise InputError(f"'camera': {err}") from None


# ---------------------------------------------------------------------- resuming
def finished(job: Job) -> bool:
    """Whether ``job``'s output exists and is a whole image of the job's size (Pillow decodes it;
    a .npy output loads as H x W x 4)."""
    width, height = job.args.size
    try:
        if job.output.lower().endswith(".npy"):
            import numpy as np

            array = np.load(job.output, mmap_mode="r", allow_pickle=False)
            return array.shape == (height, width, 4)
        from PIL import Image

        with Image.open(job.output) as image:
            image.load()
            return image.size == (width, height)
    except Exception:  # missing, truncated, corrupt: render it
        return False


# ---------------------------------------------------------------------- on the worker
_RENDER_LOCK = threading.Lock()  # one job at a time in a process: a render uses every core
_LOADED = Cache()  # ("scene", path) and ("environment", path): the last KEPT_* of each


def _file_key(path: str):
    status = os.stat(path)
    return status.st_mtime_ns, status.st_size


def _loaded_scene(path: str):
    """(scene, the file's own lights), loaded once per process while the file is unchanged."""
    from .scene import Scene

    def load():
        scene = Scene.load(path)
        return scene, tuple(scene.lights)

    return _LOADED.get(("scene", path), _file_key(path), load, keep=KEPT_SCENES)


def _loaded_environment(args):
    if args.env is None:
        return None
    key = (*_file_key(args.env), args.env_intensity)
    return _LOADED.get(("environment", args.env), key, lambda: render_options.load_environment(args),
                       keep=KEPT_ENVIRONMENTS)


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):  # not in a Dask worker
        return f"{socket.gethostname()}:{os.getpid()}"


def run_job(job: Job, threads: int | None = None) -> dict:
    """Render ``job`` and save its image atomically; its manifest record ("ok", or "error" with
    the message: never raises). ``threads``: render threads unless the job names them."""
    start = time.perf_counter()
    notes = []
    try:
        with _RENDER_LOCK, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                scene, own_lights = _loaded_scene(job.args.input)
                notes += scene.load_warnings
                scene.lights = list(own_lights)
                camera = _job_camera(scene, job)
                note = render_options.light_scene(scene, camera, job.args, _loaded_environment(job.args))
                keywords = {**job.render_options, "progress": False,
                            "threads": threads if job.args.threads is None else job.args.threads}
                render_options.render_and_save(scene, camera, job.args, job.args.background, **keywords)
            finally:  # pbrwarp's warnings (about the user's files and options), not libraries' deprecations
                notes += [str(w.message) for w in caught if issubclass(w.category, (UserWarning, RuntimeWarning))]
        if note is not None:
            notes.append(note.removeprefix("note: "))
        status, error = "ok", None
    except (PbrwarpError, OSError, ImportError, MemoryError) as err:
        status, error = "error", render_options.one_line(err)
    except Exception as err:
        status, error = "error", f"internal error: {type(err).__name__}: {render_options.one_line(err)}"
    return _record(job.id, status, job.output, time.perf_counter() - start, _worker_name(), error,
                   dict.fromkeys(" ".join(n.split()) for n in notes))


def _job_camera(scene, job: Job) -> Camera:
    if job.camera is None:
        return render_options.choose_camera(scene, job.args)
    if isinstance(job.camera, Camera):
        return job.camera
    width, height = job.args.size
    return Camera.frame(scene, aspect=width / height, **job.camera)


# ---------------------------------------------------------------------- the batch
def _distributed():
    try:
        import distributed
    except ImportError:
        raise ImportError(f"batch rendering runs on Dask distributed, which is not installed: {INSTALL_HINT}") from None
    return distributed


def default_manifest(jobs_path) -> str:
    """``JOBS.manifest.jsonl`` beside ``JOBS.jsonl``."""
    return os.path.splitext(os.fspath(jobs_path))[0] + MANIFEST_SUFFIX


def render_batch(jobs, client=None, manifest=None, *, workers: int | None = None, root=None,
                 progress: bool | None = None) -> list[dict]:
    """Render every job of ``jobs`` on Dask distributed; returns their manifest records, in the
    jobs' order.

    - ``jobs``: the path of a JSON-lines file of jobs (module docstring), or an iterable of job
      dicts (relative paths then relative to ``root``, default the current folder).
    - ``client``: a ``dask.distributed.Client``, or a scheduler's address (``"tcp://host:8786"``);
      None (the default) starts a local cluster of ``workers`` worker processes (default 1),
      each rendering with cores / ``workers`` threads, and closes it at the end.
    - ``manifest``: the file each finished job's record is appended to as one JSON line (id,
      status "ok", "skipped" or "error", seconds, worker, error, output, warnings); by default
      ``JOBS.manifest.jsonl`` beside a jobs file, none for dicts. The last line of an id is its
      latest state.
    - ``progress``: None or True shows a progress bar with the rate and the time left (if tqdm is
      installed); False never.

    A job whose output exists and is a whole image of its size is "skipped", so that running a
    batch again finishes what is left. A job that cannot be rendered (a missing or broken scene,
    a bad option) is an "error" record and never stops the others. Outputs are written
    atomically (a hidden temporary file renamed onto the output): should a worker die, Dask
    renders its jobs again elsewhere, and a job rendered twice writes the same complete image
    twice, never a partial one. A job whose worker dies ``distributed.scheduler.allowed-failures``
    + 1 times (default 4) is an "error". ImportError saying what to install without Dask."""
    distributed = _distributed()
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InputError(f"workers must be a whole number >= 1, got {workers!r}")
    if client is not None and workers is not None:
        raise InputError("workers sets the size of the local cluster; a client or scheduler address brings its own")
    if manifest is None and isinstance(jobs, (str, os.PathLike)):
        manifest = default_manifest(jobs)
    parsed = read_jobs(jobs, root)
    records = [None] * len(parsed)
    todo = []
    for index, job in enumerate(parsed):
        if not isinstance(job, Job):
            records[index] = job
        elif finished(job):
            records[index] = _record(job.id, "skipped", job.output)
        else:
            todo.append(index)
    out = open(manifest, "a", encoding="utf-8") if manifest is not None else None
    bar = progress_bar(progress, total=len(parsed), unit="image", desc="batch", file=sys.stderr,
                       dynamic_ncols=True)
    try:
        for record in records:
            if record is not None:
                _finish(record, out, bar)
        if todo:
            with _client(distributed, client, workers) as (dask_client, threads):
                # one message for every job: submitting them one by one costs a round trip each
                batch_tag = os.urandom(6).hex()
                keys = [job_key(index, parsed[index].id, batch_tag) for index in todo]
                submitted = dask_client.map(run_job, [parsed[i] for i in todo], threads=threads, pure=False, key=keys)
                futures = dict(zip(submitted, todo))
                for future in distributed.as_completed(futures):
                    index = futures.pop(future)
                    records[index] = _result(future, parsed[index])
                    _finish(records[index], out, bar)
    finally:
        if bar is not None:
            bar.close()
        if out is not None:
            out.close()
    return records


def job_key(index: int, job_id: str, batch_tag: str) -> str:
    """The Dask key of the job at ``index`` of a batch: "pbrwarp-render-INDEX-ID-TAG". Dask groups
    tasks by the key up to its first word that is not all letters (dask.utils.key_split), and queues
    on the scheduler only a group larger than twice the cluster's threads: the index keeps every
    job of a batch in the one group "pbrwarp-render" whatever its id (an id such as "front" would
    otherwise make a group of its own, sent to a worker at once beside the job it renders)."""
    return f"pbrwarp-render-{index}-{job_id}-{batch_tag}"


def _result(future, job: Job) -> dict:
    from distributed.scheduler import KilledWorker

    try:
        return future.result()
    except KilledWorker:
        return _record(job.id, "error", job.output,
                       error="every worker that rendered it died (out of memory? a crash in the renderer?)")
    except Exception as err:  # the task could not run at all (pbrwarp missing on the worker, ...)
        return _record(job.id, "error", job.output, error=f"{type(err).__name__}: {render_options.one_line(err)}")


def _finish(record: dict, out, bar) -> None:
    if out is not None:
        out.write(json.dumps(record) + "\n")
        out.flush()
    if bar is not None:
        bar.update(1)


def local_cluster(workers: int):
    """A dask.distributed.LocalCluster of ``workers`` worker processes of one Dask thread each, with
    LOCAL_CLUSTER_SETTINGS, its dashboard on a free port."""
    import logging

    import dask

    distributed = _distributed()
    with dask.config.set(LOCAL_CLUSTER_SETTINGS):
        # ":0": the scheduler's web server (the dashboard, with Bokeh) on a free port, clashing with no other
        return distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=":0", silence_logs=logging.ERROR)


class _client:
    """A context giving (client, render threads per job) for ``client`` (a Client, an address, or
    None for a local cluster of ``workers`` processes), closing what it opened."""

    def __init__(self, distributed, client, workers):
        self._distributed, self._given, self._workers = distributed, client, workers
        self._opened = []

    def __enter__(self):
        distributed = self._distributed
        if isinstance(self._given, distributed.Client):
            return self._given, None
        if self._given is not None:
            client = distributed.Client(self._given)
            self._opened.append(client)
            return client, None
        workers = self._workers or 1
        cluster = local_cluster(workers)
        self._opened.append(cluster)
        client = distributed.Client(cluster)
        self._opened.append(client)
        return client, max(1, cores() // workers)

    def __exit__(self, *exc):
        for opened in reversed(self._opened):
            opened.close()


# ---------------------------------------------------------------------- generators
def orbit_directions(views: int, elevation: float) -> list[tuple[float, float, float]]:
    """``views`` unit vectors from a target towards the eye, evenly spaced in azimuth around +Y
    from +Z (counter-clockwise seen from above), ``elevation`` degrees above the horizon."""
    if isinstance(views, bool) or not isinstance(views, int) or views < 1:
        raise InputError(f"views must be a whole number >= 1, got {views!r}")
    up = math.radians(validate.finite_scalar(elevation, "elevation"))
    if not abs(up) < math.pi / 2:
        raise InputError(f"elevation must lie strictly between -90 and 90 degrees, got {elevation}")
    return [(math.cos(up) * math.sin(2 * math.pi * i / views), math.sin(up),
             math.cos(up) * math.cos(2 * math.pi * i / views)) for i in range(views)]


def _view_names(views: int) -> list[str]:
    digits = max(3, len(str(views - 1)))
    return [f"view-{i:0{digits}d}" for i in range(views)]


def turntable_jobs(model, views: int, folder, elevation: float = 20.0, fov_y: float = 45.0, ext: str = ".png",
                   options: dict | None = None) -> list[dict]:
    """Jobs of ``views`` images of ``model`` from eyes evenly spaced on a circle around the
    centre of its bounds, ``elevation`` degrees above it, all at the distance at which the
    bounds' sphere fits the view (``fov_y`` vertically, and horizontally at the jobs' aspect),
    written to ``folder``/view-NNN``ext``; paths relative to ``folder`` (where the jobs file
    goes). ``options``: further job keys for every job (width, height, lights, ...)."""
    from .scene import Scene

    options = dict(options or {})
    scene = Scene.load(model)
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)
    half = math.radians(field_of_view(fov_y)) / 2.0
    aspect = options.get("width", 800) / options.get("height", 600)
    narrowest = min(half, math.atan(math.tan(half) * aspect))
    distance = radius / math.sin(narrowest)
    scene_path = os.path.relpath(os.path.abspath(model), os.path.abspath(folder))
    return [{"id": name, "scene": scene_path, "output": name + ext,
             "camera": {"eye": [float(c) for c in centre + distance * np.asarray(direction)],
                        "target": [float(c) for c in centre], "up": [0.0, 1.0, 0.0], "fov_y": float(fov_y)},
             **options}
            for name, direction in zip(_view_names(views), orbit_directions(views, elevation))]


def folder_jobs(source, views: int, folder, elevation: float = 20.0, ext: str = ".png",
                options: dict | None = None) -> list[dict]:
    """Jobs of ``views`` images of every scene file under ``source`` (sub-folders included,
    in name order), each framed by Camera.frame from directions evenly spaced around it,
    ``elevation`` degrees up; scene S's view NNN goes to ``folder``/S/view-NNN``ext`` (S the
    file's path under ``source``, extension kept). Paths relative to ``folder``. InputError if
    ``source`` holds no scene file."""
    from .scene import LOADABLE

    source = os.path.abspath(os.fspath(source))
    if not os.path.isdir(source):
        raise InputError(f"{source} is not a folder")
    scenes = sorted(os.path.join(parent, name) for parent, _, names in os.walk(source) for name in names
                    if os.path.splitext(name)[1].lower() in LOADABLE)
    if not scenes:
        raise InputError(f"no scene file ({' '.join(LOADABLE)}) under {source}")
    directions = orbit_directions(views, elevation)
    jobs = []
    for path in scenes:
        name = os.path.relpath(path, source).replace(os.sep, "/")
        jobs += [{"id": f"{name}/{view}", "scene": os.path.relpath(path, os.path.abspath(folder)),
                  "output": f"{name}/{view}{ext}", "camera": {"direction": list(direction)}, **(options or {})}
                 for view, direction in zip(_view_names(views), directions)]
    return jobs


def job_options(args, parser, folder) -> dict:
    """The job keys of the `pbrwarp render` options parsed into ``args`` by ``parser`` that
    differ from their defaults (``args.light``: the light specs as given), for a jobs file in
    ``folder`` (the environment's path made relative to it)."""
    found = {}
    for key, flag in _OPTION_FLAGS.items():
        dest = flag[2:].replace("-", "_")
        value = getattr(args, dest)
        if value != parser.get_default(dest):
            found[key] = list(value) if isinstance(value, tuple) else value
    if "environment" in found:
        found["environment"] = os.path.relpath(os.path.abspath(found["environment"]), os.path.abspath(folder))
    if args.size != parser.get_default("size"):
        found["width"], found["height"] = args.size
    if args.shadows is not True:
        found["shadows"] = args.shadows
    if args.transparent:
        found["transparent"] = True
    if args.light:
        found["lights"] = list(args.light)
    return found


def write_jobs(path, jobs) -> None:
    """Write ``jobs`` (dicts) to ``path`` as JSON lines, atomically."""
    path = os.fspath(path)
    temporary = f"{path}.{os.getpid()}.tmp"
    try:
        with open(temporary, "w", encoding="utf-8") as f:
            f.writelines(json.dumps(job) + "\n" for job in jobs)
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.unlink(temporary)
        raise
