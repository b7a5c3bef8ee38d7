"""The ``pbrwarp`` command line.

    pbrwarp render model.glb -o out.png --size 1280x720 --spp 4 --light dir:-1,-1,-1:3
    pbrwarp demo -o demo.png

Nothing but the command's own output and one-line notes reaches the terminal: Warp's start-up
messages are held back (``--verbose`` or ``PBRWARP_VERBOSE=1`` shows them) and no error prints a
traceback. Every failure is one line on stderr and an exit status (see ``EXIT_STATUS_HELP``).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import sys
import threading
import traceback
import warnings

from . import startup
from .errors import PbrwarpError
from .render_options import (Parser, UsageError, add_image_options, add_output_options, add_scene_options,
                             check_output, choose_camera, finite_float, light_scene, load_environment, one_line,
                             parse_fov, parse_light, positive_int, render_and_save)
from .render_options import MAX_SIDE  # noqa: F401 - cli.MAX_SIDE, as docs/limits.md names it

PROG = "pbrwarp"
EXIT_INTERNAL_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 128 + signal.SIGINT  # 130, as a shell reports a process Ctrl-C ended
EXIT_TERMINATED = 128 + signal.SIGTERM  # 143

EXIT_STATUS_HELP = f"""\
exit status:
  0    the image was written
  {EXIT_INTERNAL_ERROR}    internal error, a bug in pbrwarp: run again with --verbose for the traceback
  {EXIT_USAGE}    bad input: a missing or unreadable file, an invalid option, or an image or scene
       too large for this machine's memory
  {EXIT_INTERRUPTED}  interrupted (Ctrl-C)
  {EXIT_TERMINATED}  terminated (SIGTERM)
  Every failure prints one line to stderr and leaves no output file, whole or partial.
environment:
  {startup.VERBOSE_ENV}=1  as --verbose
"""
VERBOSE_HELP = "show Warp's start-up and kernel-module messages, and the traceback of any error"

LIGHT_HELP = """\
light specs (--light may repeat; lights from the file are kept):
  point:X,Y,Z:CANDELA[:R,G,B]                      point light at X,Y,Z
  dir:DX,DY,DZ:LUX[:R,G,B]                         directional light travelling along DX,DY,DZ
  spot:X,Y,Z:DX,DY,DZ:CANDELA[:INNER,OUTER[:R,G,B]] spot light, cone half-angles in degrees
                                                   (default 0,45)
  sphere:X,Y,Z:RADIUS:NITS[:R,G,B]                 sphere light centred at X,Y,Z
  rect:X,Y,Z:UX,UY,UZ:VX,VY,VZ:NITS[:R,G,B]        rectangle light centred at X,Y,Z with perpendicular
                                                   edges U and V, lighting the side U x V points to
  colours are linear RGB, e.g. 1,0.9,0.8; "directional" is accepted for "dir".
examples:
  --light dir:-1,-1,-1:3   --light point:0,4,3:50:1,0.8,0.6   --light spot:0,5,0:0,-1,0:200:20,30
  --light sphere:0,3,0:0.25:800   --light rect:0,3,0:1,0,0:0,0,1:200
"""

BATCH_HELP = """\
a job is one image, one JSON object a line, with `pbrwarp render`'s options under pw.render's names:
  {"id": "v0", "scene": "bunny.glb", "output": "out/v0.png", "width": 512, "height": 512, "spp": 4,
   "camera": {"eye": [0, 1, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40},
   "environment": null, "lights": ["dir:-1,-1,-1:3"], "seed": 1}
  camera: {eye, target[, up, fov_y]}, "frame", or {direction[, up, fov_y, margin]} (Camera.frame);
  relative paths are relative to the jobs file. Jobs whose output is already a whole image are
  skipped; each finished job appends a line (id, status ok/skipped/error, seconds, worker, error)
  to the manifest; the exit status is 2 if any job failed. docs/batch.md runs batches on a cluster.
"""


# The jobs file the batch generators write into their output folder.
GENERATED_JOBS = "jobs.jsonl"
GENERATORS = ("turntable", "folder")


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the command unwinds as from Ctrl-C: a save under
    way removes its temporary file. A BaseException, like KeyboardInterrupt, so that no
    ``except Exception`` on the way swallows it."""



# ---------------------------------------------------------------------- argument parser
def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog=PROG, description="Physically based rendering of triangle meshes on the CPU (NVIDIA Warp).",
                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    parser.add_argument("-v", "--verbose", action="store_true", help=VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def output_options(p, default_size, default_spp):
        add_output_options(p, default_size, default_spp)
        # also after the command; SUPPRESS keeps a --verbose given before it
        p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP)

    render = sub.add_parser("render", help="render a scene file (.glb .gltf .obj .ply .stl .off)",
                            formatter_class=argparse.RawDescriptionHelpFormatter, epilog=LIGHT_HELP + EXIT_STATUS_HELP)
    add_scene_options(render)
    output_options(render, (800, 600), 1)

    def batch_options(p):
        p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="a Dask scheduler's address, e.g. tcp://10.0.0.5:8786 (default: a local cluster)")
        p.add_argument("--workers", type=positive_int("worker count"), default=None, metavar="N",
                       help="worker processes of the local cluster, sharing the cores (default 1)")
        p.add_argument("--manifest", metavar="PATH", default=None,
                       help="where each finished job's record is appended (default JOBS.manifest.jsonl)")
        p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP)

    batch = sub.add_parser("batch", help="render the jobs of a JSON-lines file on Dask (pip install 'pbrwarp[batch]')",
                           formatter_class=argparse.RawDescriptionHelpFormatter, epilog=BATCH_HELP + EXIT_STATUS_HELP)
    batch.add_argument("jobs", metavar="JOBS.jsonl", help="the jobs, one JSON object (one image) a line")
    batch_options(batch)

    def generator_options(p, what):
        p.add_argument("-o", "--output", required=True, metavar="DIR",
                       help=f"folder of the images and of the jobs file, {GENERATED_JOBS} (created if missing)")
        p.add_argument("--views", type=positive_int("view count"), required=True, metavar="N",
                       help=f"views of {what}, evenly spaced around it")
        p.add_argument("--elevation", type=finite_float("elevation", -90.0, 90.0), default=20.0, metavar="DEG",
                       help="height of the views above the horizon in degrees, -90 to 90 exclusive (default 20)")
        p.add_argument("--format", choices=("png", "jpg", "webp", "tiff", "npy"), default="png",
                       help="image format (default png; npy: linear float32 RGBA)")
        p.add_argument("--light", type=light_spec, action="append", default=[], metavar="SPEC",
                       help="add a light to every view (repeatable); see `pbrwarp render --help`")
        p.add_argument("--plan", action="store_true", help="write the jobs file only, render nothing")
        add_image_options(p, (512, 512), 1)
        batch_options(p)
        p.set_defaults(generator=p)  # for its options' defaults

    turntable = sub.add_parser("batch turntable", help="render N views around a model (a turntable) on Dask",
                               formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    turntable.add_argument("model", metavar="MODEL", help="scene file (.glb .gltf .obj .ply .stl .off)")
    generator_options(turntable, "the model, all at the distance at which its bounds fit the view")
    turntable.add_argument("--fov", type=parse_fov, default=45.0, metavar="DEG",
                           help="vertical field of view in degrees (default 45)")
    folder = sub.add_parser("batch folder", help="render N views of every scene file under a folder on Dask",
                            formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    folder.add_argument("source", metavar="DIR", help="folder of scene files (sub-folders included)")
    generator_options(folder, "each scene, each framing the scene")

    demo = sub.add_parser("demo", help="render the built-in demo scene (sphere grid and brick torus)",
                          formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    output_options(demo, (960, 540), 4)
    return parser


def _version() -> str:
    from . import __version__

    return __version__


# ---------------------------------------------------------------------- commands

def _note(message: str) -> None:
    print(f"{PROG}: {message}", file=sys.stderr)



def cmd_render(args) -> int:
    from .scene import Scene

    check_output(args.output, args.transparent)
    scene = Scene.load(args.input)
    camera = choose_camera(scene, args)
    note = light_scene(scene, camera, args, load_environment(args))
    if note is not None:
        _note(note)
    render_and_save(scene, camera, args, args.background)
    return 0


def cmd_demo(args) -> int:
    from pbrwarp.meshes import DEMO_BACKGROUND, demo_scene

    check_output(args.output, args.transparent)
    scene, camera = demo_scene()
    if args.env is not None:
        scene.environment = load_environment(args)
    render_and_save(scene, camera, args, args.background or (None if scene.environment else DEMO_BACKGROUND))
    return 0


def light_spec(text: str) -> str:
    """A --light spec as given, once parse_light accepts it (a job holds the spec)."""
    parse_light(text)
    return text


def cmd_batch(args) -> int:
    return _run_batch(args.jobs, args)


def cmd_generate(args) -> int:
    from . import batch

    os.makedirs(args.output, exist_ok=True)
    options = batch.job_options(args, args.generator, args.output)
    ext = "." + args.format
    if args.command == "batch turntable":
        jobs = batch.turntable_jobs(args.model, args.views, args.output, args.elevation, args.fov, ext, options)
    else:
        jobs = batch.folder_jobs(args.source, args.views, args.output, args.elevation, ext, options)
    path = os.path.join(args.output, GENERATED_JOBS)
    batch.write_jobs(path, jobs)
    _note(f"wrote {len(jobs)} jobs to {path}")
    return 0 if args.plan else _run_batch(path, args)


def _run_batch(jobs, args) -> int:
    from .batch import default_manifest, render_batch

    if args.scheduler is not None and args.workers is not None:
        raise UsageError("--workers sets the size of the local cluster; with --scheduler the cluster has its own")
    manifest = args.manifest or default_manifest(jobs)
    records = render_batch(jobs, client=args.scheduler, manifest=manifest, workers=args.workers)
    counts = {status: sum(r["status"] == status for r in records) for status in ("ok", "skipped", "error")}
    _note(f"{counts['ok']} rendered, {counts['skipped']} skipped (already done), {counts['error']} failed; "
          f"manifest: {manifest}")
    failed = [r for r in records if r["status"] == "error"]
    if failed:
        _note(f"error: job {failed[0]['id']}: {failed[0]['error']}"
              + (f" (and {len(failed) - 1} more failed jobs: see the manifest)" if len(failed) > 1 else ""))
        return EXIT_USAGE
    return 0


def main(argv=None) -> int:
    """Run the command line; returns the exit status (see ``EXIT_STATUS_HELP``)."""
    with _sigterm_raises_terminated(), warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _main(argv)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning (something in the user's files that pbrwarp does not honour) as one line."""
    print(f"{PROG}: warning: {' '.join(str(message).split())}", file=sys.stderr if file is None else file)


@contextlib.contextmanager
def _sigterm_raises_terminated():
    """SIGTERM raises :class:`Terminated` while the command runs (signals reach the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # one is enough: let the unwinding finish
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


# Options whose values may start with "-" (negative coordinates): argparse would take
# "--camera -3,0,0,0,0,0" for two options, so such values are glued on as "--camera=-3,...".
_SIGNED_OPTIONS = ("--camera", "--background", "--exposure")


def _glue_negative_values(argv: list[str]) -> list[str]:
    out, i = [], 0
    while i < len(argv):
        token = argv[i]
        if token in _SIGNED_OPTIONS and i + 1 < len(argv) and re.match(r"-[\d.]", argv[i + 1]):
            out.append(f"{token}={argv[i + 1]}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


def _join_generator_commands(argv: list[str]) -> list[str]:
    """"batch turntable ..." as the command "batch turntable" (likewise folder): `batch` alone
    takes a jobs file in the same place."""
    first = next((i for i, token in enumerate(argv) if not token.startswith("-")), len(argv))
    if first + 1 < len(argv) and argv[first] == "batch" and argv[first + 1] in GENERATORS:
        return argv[:first] + [f"batch {argv[first + 1]}"] + argv[first + 2:]
    return argv


def _main(argv) -> int:
    parser = build_parser()
    argv = _join_generator_commands(_glue_negative_values(list(sys.argv[1:] if argv is None else argv)))
    verbose = startup.verbose_from_environment()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exit_:  # --help and --version
            return exit_.code if isinstance(exit_.code, int) else 0
        verbose = verbose or args.verbose
        with _warp_messages(verbose):
            command = {"render": cmd_render, "demo": cmd_demo, "batch": cmd_batch, "batch turntable": cmd_generate,
                       "batch folder": cmd_generate}[args.command]
            return command(args)
    except (UsageError, PbrwarpError, OSError, ImportError) as err:
        return _fail(EXIT_USAGE, f"error: {one_line(err)}", verbose)
    except MemoryError as err:
        return _fail(EXIT_USAGE, _out_of_memory(err), verbose)
    except KeyboardInterrupt:
        return _fail(EXIT_INTERRUPTED, "interrupted", verbose)
    except Terminated:
        return _fail(EXIT_TERMINATED, "terminated", verbose)
    except Exception as err:
        if isinstance(err, RuntimeError) and str(err).startswith("Failed to allocate"):  # Warp's wording
            return _fail(EXIT_USAGE, _out_of_memory(err), verbose)
        return _fail(EXIT_INTERNAL_ERROR, f"internal error: {type(err).__name__}: {one_line(err)} "
                                          "(this is a bug in pbrwarp: run again with --verbose to see where, "
                                          "and please report it)", verbose)


@contextlib.contextmanager
def _warp_messages(verbose: bool):
    """Warp's start-up and kernel-module messages, shown while the command runs if ``verbose``."""
    import warp as wp

    level = wp.config.log_level
    if verbose:
        startup.show_warp_messages()
    try:
        yield
    finally:
        wp.config.log_level = level



def _out_of_memory(err: BaseException) -> str:
    return (f"error: not enough memory ({one_line(err)}): try a smaller --size or --spp, "
            "or a scene with fewer triangles and smaller textures")


def _fail(status: int, message: str, verbose: bool) -> int:
    """Print ``message`` as one line (after the traceback, if ``verbose``) and return ``status``."""
    if verbose:
        traceback.print_exc()
    print(f"{PROG}: {message}", file=sys.stderr)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
