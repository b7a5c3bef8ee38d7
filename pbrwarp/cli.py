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
import math
import os
import re
import signal
import sys
import threading
import traceback
import warnings

import numpy as np

from . import startup
from .camera import Camera
from .emitters import emissive_materials
from .errors import InputError, PbrwarpError
from .features import DEFAULT_MAX_BOUNCES, MAX_BOUNCES
from .frame import MAX_EXPOSURE
from .lights import DirectionalLight, PointLight, RectLight, SphereLight, SpotLight
from .parallel import MAX_THREADS_PER_CORE

PROG = "pbrwarp"
EXIT_INTERNAL_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 128 + signal.SIGINT  # 130, as a shell reports a process Ctrl-C ended
EXIT_TERMINATED = 128 + signal.SIGTERM  # 143
MAX_SIDE = 16384  # largest image side accepted from the command line
FLOAT32_MAX = float(np.finfo(np.float32).max)  # the kernels compute in float32
DEFAULT_KEY_LUX = 3.0

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


class UsageError(Exception):
    """A command-line value that cannot be used; the message is shown as is."""


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that the command unwinds as from Ctrl-C: a save under
    way removes its temporary file. A BaseException, like KeyboardInterrupt, so that no
    ``except Exception`` on the way swallows it."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage and exiting, so every error is one line."""

    def error(self, message):
        raise UsageError(message)


# ---------------------------------------------------------------------- value parsers
def _numbers(text: str, count: int | tuple, what: str, example: str) -> list[float]:
    counts = (count,) if isinstance(count, int) else count
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = None
    if values is None or len(values) not in counts or not all(abs(v) <= FLOAT32_MAX for v in values):
        n = " or ".join(map(str, counts))
        raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: expected {n} comma-separated finite numbers "
                                         f"(|x| <= {FLOAT32_MAX:.3g}), e.g. {example}")
    return values


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), both whole numbers in 1..MAX_SIDE."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"invalid size {text!r}: expected WIDTHxHEIGHT in pixels, e.g. 640x480")
    w, h = int(m.group(1)), int(m.group(2))
    if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
        raise argparse.ArgumentTypeError(
            f"invalid size {text!r}: width and height must be whole numbers from 1 to {MAX_SIDE}, e.g. 640x480")
    return w, h


def _positive_int(what: str):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = 0
        if value < 1:
            raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: expected a whole number >= 1")
        return value

    return parse


def _positive_float(what: str):
    """A parser of finite numbers above 0."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not 0.0 < value < math.inf:
            raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: expected a number above 0")
        return value

    return parse


def _whole_number(what: str, high: int):
    """A parser of whole numbers from 0 to ``high``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = -1
        if not 0 <= value <= high:
            raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: expected a whole number from 0 to {high}")
        return value

    return parse


def _finite_float(what: str, low: float = -FLOAT32_MAX, high: float = FLOAT32_MAX):
    """A parser of numbers from ``low`` to ``high`` (by default, any float32 value)."""

    expected = ("a finite number" if (low, high) == (-FLOAT32_MAX, FLOAT32_MAX)
                else f"a number from {low:.3g} to {high:.3g}")

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: expected {expected}")
        return value

    return parse


def parse_fov(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value < 180.0:
        raise argparse.ArgumentTypeError(f"invalid field of view {text!r}: expected degrees strictly between 0 and 180")
    return value


def parse_camera(text: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """'ex,ey,ez,tx,ty,tz' -> (eye, target)."""
    v = _numbers(text, 6, "camera", "0,1,5,0,0,0 (eye x,y,z then target x,y,z)")
    eye, target = tuple(v[:3]), tuple(v[3:])
    if eye == target:
        raise argparse.ArgumentTypeError(f"invalid camera {text!r}: the eye and the target must differ")
    return eye, target


def parse_colour(text: str) -> tuple[float, float, float]:
    v = _numbers(text, 3, "colour", "0.1,0.1,0.1 (linear RGB)")
    if any(c < 0 for c in v):
        raise argparse.ArgumentTypeError(f"invalid colour {text!r}: components must be >= 0")
    return tuple(v)


def parse_light(spec: str):
    """A light from 'point:...', 'dir:...', 'spot:...', 'sphere:...' or 'rect:...' (see LIGHT_HELP)."""
    fields = spec.split(":")
    kind = fields[0].strip().lower()

    def bad(reason: str):
        return argparse.ArgumentTypeError(f"invalid light {spec!r}: {reason}")

    def intensity(text: str, unit: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise bad(f"intensity {text!r} is not a number ({unit})") from None
        if not math.isfinite(value) or value < 0:
            raise bad(f"intensity must be a finite number >= 0 ({unit}), got {text}")
        return value

    try:
        if kind == "point":
            if len(fields) not in (3, 4):
                raise bad("expected point:X,Y,Z:CANDELA[:R,G,B]")
            colour = parse_colour(fields[3]) if len(fields) == 4 else (1.0, 1.0, 1.0)
            return PointLight(position=_numbers(fields[1], 3, "position", "0,4,3"), color=colour,
                              intensity=intensity(fields[2], "candela"))
        if kind in ("dir", "directional"):
            if len(fields) not in (3, 4):
                raise bad("expected dir:DX,DY,DZ:LUX[:R,G,B]")
            direction = _numbers(fields[1], 3, "direction", "-1,-1,-1")
            if not any(direction):
                raise bad("the direction must not be 0,0,0")
            colour = parse_colour(fields[3]) if len(fields) == 4 else (1.0, 1.0, 1.0)
            return DirectionalLight(direction=direction, color=colour, intensity=intensity(fields[2], "lux"))
        if kind == "spot":
            if len(fields) not in (4, 5, 6):
                raise bad("expected spot:X,Y,Z:DX,DY,DZ:CANDELA[:INNER,OUTER[:R,G,B]]")
            direction = _numbers(fields[2], 3, "direction", "0,-1,0")
            if not any(direction):
                raise bad("the direction must not be 0,0,0")
            inner, outer = 0.0, 45.0
            if len(fields) >= 5:
                inner, outer = _numbers(fields[4], 2, "cone angles", "20,30 (inner, outer half-angles in degrees)")
                if not 0.0 <= inner <= outer <= 90.0:
                    raise bad(f"cone angles must satisfy 0 <= INNER <= OUTER <= 90 degrees, got {inner:g},{outer:g}")
            colour = parse_colour(fields[5]) if len(fields) == 6 else (1.0, 1.0, 1.0)
            return SpotLight(position=_numbers(fields[1], 3, "position", "0,5,0"), direction=direction,
                             color=colour, intensity=intensity(fields[3], "candela"),
                             inner_cone=math.radians(inner), outer_cone=math.radians(outer))
        if kind == "sphere":
            if len(fields) not in (4, 5):
                raise bad("expected sphere:X,Y,Z:RADIUS:NITS[:R,G,B]")
            colour = parse_colour(fields[4]) if len(fields) == 5 else (1.0, 1.0, 1.0)
            return SphereLight(position=_numbers(fields[1], 3, "position", "0,3,0"),
                               radius=_numbers(fields[2], 1, "radius", "0.25")[0], color=colour,
                               intensity=intensity(fields[3], "nits"))
        if kind == "rect":
            if len(fields) not in (5, 6):
                raise bad("expected rect:X,Y,Z:UX,UY,UZ:VX,VY,VZ:NITS[:R,G,B]")
            colour = parse_colour(fields[5]) if len(fields) == 6 else (1.0, 1.0, 1.0)
            return RectLight(position=_numbers(fields[1], 3, "position", "0,3,0"),
                             edge_u=_numbers(fields[2], 3, "edge", "1,0,0"),
                             edge_v=_numbers(fields[3], 3, "edge", "0,0,1"), color=colour,
                             intensity=intensity(fields[4], "nits"))
    except argparse.ArgumentTypeError as err:
        message = str(err)
        if message.startswith("invalid light"):
            raise
        raise bad(message.removeprefix("invalid ")) from None
    except PbrwarpError as err:
        raise bad(str(err)) from None
    raise bad(f"unknown light type {kind!r}: expected point, dir, spot, sphere or rect")


# ---------------------------------------------------------------------- argument parser
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Physically based rendering of triangle meshes on the CPU (NVIDIA Warp).",
                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    parser.add_argument("-v", "--verbose", action="store_true", help=VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def output_options(p, default_size, default_spp):
        p.add_argument("-o", "--output", required=True, metavar="OUT",
                       help="output image; the extension picks the format (.png, .jpg, ... tone mapped; "
                            ".npy: linear float32 RGBA)")
        p.add_argument("--size", type=parse_size, default=default_size, metavar="WxH",
                       help=f"image size in pixels, each side 1 to {MAX_SIDE} "
                            f"(default {default_size[0]}x{default_size[1]})")
        p.add_argument("--spp", type=_positive_int("samples per pixel"), default=default_spp, metavar="N",
                       help=f"samples per pixel (default {default_spp})")
        p.add_argument("--tonemap", choices=("none", "reinhard", "aces"), default="aces",
                       help="tone map for 8-bit output (default aces)")
        p.add_argument("--exposure", type=_finite_float("exposure", -MAX_EXPOSURE, MAX_EXPOSURE), default=0.0,
                       metavar="EV", help=f"exposure in stops from {-MAX_EXPOSURE:g} to {MAX_EXPOSURE:g}: "
                                          "radiance is scaled by 2^EV (default 0)")
        p.add_argument("--no-shadows", dest="shadows", action="store_const", const=False, default=True,
                       help="render no shadows")
        p.add_argument("--shadow-maps", dest="shadows", action="store_const", const="map",
                       help="look shadows up in shadow maps instead of tracing shadow rays (faster, approximate)")
        p.add_argument("--threads", type=_positive_int("thread count"), default=None, metavar="N",
                       help=f"worker threads, at most {MAX_THREADS_PER_CORE} per core (default: one per core)")
        p.add_argument("--background", type=parse_colour, default=None, metavar="R,G,B",
                       help="linear radiance where no surface is hit (default: the --env environment, else 0,0,0)")
        p.add_argument("--transparent", action="store_true",
                       help="write coverage as alpha (PNG, WebP, TIFF) instead of the background")
        p.add_argument("--quality", choices=("fast", "balanced", "accurate", "reference"), default=None,
                       help="BRDF preset (default balanced; docs/accuracy.md gives each one's error and cost)")
        p.add_argument("--visibility", choices=("auto", "raycast", "raster"), default="auto",
                       help="primary visibility: ray cast, rasterized, or the cheaper by a cost model (default)")
        p.add_argument("--texture-filter", choices=("trilinear", "bilinear"), default="trilinear",
                       help="texture filtering: mip-mapped over each pixel's footprint (default), or the "
                            "full-resolution image only (faster, aliases)")
        p.add_argument("--integrator", choices=("direct", "path"), default="direct",
                       help="light transport: direct lighting (default), or path tracing (light bouncing between "
                            "surfaces, emissive materials as lights; the ground truth, slower)")
        p.add_argument("--bounces", type=_whole_number("bounces", MAX_BOUNCES), default=None, metavar="N",
                       help=f"with --integrator path: the most bounces, 0 to {MAX_BOUNCES} (default "
                            f"{DEFAULT_MAX_BOUNCES}: paths of up to {DEFAULT_MAX_BOUNCES + 1} segments)")
        p.add_argument("--time-budget", type=_positive_float("time budget"), default=None, metavar="SECONDS",
                       help="with --integrator path: add passes of --spp samples while another fits in this "
                            "many seconds")
        p.add_argument("--target-error", type=_positive_float("target error"), default=None, metavar="E",
                       help="with --integrator path: add passes of --spp samples until the mean relative "
                            "standard error of the pixels is at most E (e.g. 0.02)")
        p.add_argument("--env", metavar="HDR", default=None,
                       help="light the scene with an equirectangular .hdr/.exr environment, also shown as the "
                            "background unless --background is given (needs pip install 'pbrwarp[env]')")
        p.add_argument("--env-intensity", type=_finite_float("environment intensity", 0.0), default=1.0, metavar="X",
                       help="scale of the environment's radiance, >= 0 (default 1)")
        p.add_argument("--explain", action="store_true",
                       help="print which effects are simulated and why the others are not, then render")
        # also after the command; SUPPRESS keeps a --verbose given before it
        p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP)

    render = sub.add_parser("render", help="render a scene file (.glb .gltf .obj .ply .stl .off)",
                            formatter_class=argparse.RawDescriptionHelpFormatter, epilog=LIGHT_HELP + EXIT_STATUS_HELP)
    render.add_argument("input", metavar="INPUT", help="scene file (.glb .gltf .obj .ply .stl .off)")
    output_options(render, (800, 600), 1)
    render.add_argument("--camera", type=parse_camera, default=None, metavar="EX,EY,EZ,TX,TY,TZ",
                        help="eye and target positions (default: the file's first camera, else one framing the scene)")
    render.add_argument("--fov", type=parse_fov, default=None, metavar="DEG",
                        help="vertical field of view in degrees (default: the file camera's, else 45)")
    render.add_argument("--light", type=parse_light, action="append", default=[], metavar="SPEC",
                        help="add a light (repeatable); see the light specs below")

    demo = sub.add_parser("demo", help="render the built-in demo scene (sphere grid and brick torus)",
                          formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXIT_STATUS_HELP)
    output_options(demo, (960, 540), 4)
    return parser


def _version() -> str:
    from . import __version__

    return __version__


# ---------------------------------------------------------------------- commands
def _check_output(path: str, transparent: bool) -> None:
    """Fail before rendering, not after, for outputs that cannot be written."""
    ext = os.path.splitext(path)[1].lower()
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise InputError(f"cannot save {path}: folder {directory} does not exist")
    if os.path.isdir(path):
        raise InputError(f"cannot save {path}: it is a folder")
    if ext == ".npy":
        return
    from PIL import Image

    fmt = Image.registered_extensions().get(ext)
    if fmt is None or fmt not in Image.SAVE:
        raise InputError(f"cannot save {path}: unknown image extension {ext!r} (try .png or .npy)")
    if transparent and fmt not in ("PNG", "WEBP", "TIFF"):
        raise InputError(f"{fmt} cannot store transparency; save as .png")


def _note(message: str) -> None:
    print(f"{PROG}: {message}", file=sys.stderr)


def _look_at(eye, target, fov):
    forward = np.subtract(target, eye)
    # looking (almost) straight up or down: world +Y cannot be the up vector
    up = (0.0, 1.0, 0.0)
    if np.linalg.norm(np.cross(forward / np.linalg.norm(forward), up)) < 1e-3:
        up = (0.0, 0.0, -1.0 if forward[1] < 0 else 1.0)
    return Camera.look_at(eye, target, up=up, fov_y=fov)


def _choose_camera(scene, args) -> Camera:
    fov = args.fov
    if args.camera is not None:
        return _look_at(*args.camera, 45.0 if fov is None else fov)
    if scene.cameras:
        cam = scene.cameras[0]
        return cam if fov is None else Camera(cam.eye, cam.forward, cam.up, fov_y=fov)
    width, height = args.size
    return Camera.frame(scene, fov_y=45.0 if fov is None else fov, aspect=width / height)


def _shoulder_light(camera: Camera) -> DirectionalLight:
    """A key light from above and to the right, behind the camera."""
    forward, up, right = (np.asarray(v) for v in (camera.forward, camera.up, camera.right))
    return DirectionalLight(direction=tuple(forward - 0.7 * up - 0.4 * right), intensity=DEFAULT_KEY_LUX)


def _load_environment(scene, args) -> None:
    if args.env is not None:
        from .environment import Environment

        scene.environment = Environment.load(args.env, intensity=args.env_intensity)


def _render_and_save(scene, camera, args, background) -> None:
    from .render import explain, render

    width, height = args.size
    options = dict(width=width, height=height, spp=args.spp, shadows=args.shadows, quality=args.quality,
                   visibility=args.visibility, background=background, texture_filter=args.texture_filter,
                   integrator=args.integrator, max_bounces=args.bounces, time_budget=args.time_budget,
                   target_error=args.target_error)
    if args.explain:
        print(explain(scene, **options))
    frame = render(scene, camera, threads=args.threads, **options)
    frame.save(args.output, exposure=args.exposure, tonemap=args.tonemap, transparent=args.transparent)


def cmd_render(args) -> int:
    from .scene import Scene

    _check_output(args.output, args.transparent)
    scene = Scene.load(args.input)
    camera = _choose_camera(scene, args)
    for light in args.light:
        scene.add_light(light)
    _load_environment(scene, args)
    lit_by_emitters = args.integrator == "path" and emissive_materials(scene) > 0
    if not scene.lights and scene.environment is None and not lit_by_emitters:
        scene.add_light(_shoulder_light(camera))
        _note(f"note: the scene has no lights; added a {DEFAULT_KEY_LUX:g} lux directional light "
              "from over the camera's shoulder (use --light to choose your own)")
    _render_and_save(scene, camera, args, args.background)
    return 0


def cmd_demo(args) -> int:
    from pbrwarp.meshes import DEMO_BACKGROUND, demo_scene

    _check_output(args.output, args.transparent)
    scene, camera = demo_scene()
    _load_environment(scene, args)
    _render_and_save(scene, camera, args, args.background or (None if scene.environment else DEMO_BACKGROUND))
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


def _main(argv) -> int:
    parser = build_parser()
    argv = _glue_negative_values(list(sys.argv[1:] if argv is None else argv))
    verbose = startup.verbose_from_environment()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exit_:  # --help and --version
            return exit_.code if isinstance(exit_.code, int) else 0
        verbose = verbose or args.verbose
        with _warp_messages(verbose):
            command = {"render": cmd_render, "demo": cmd_demo}[args.command]
            return command(args)
    except (UsageError, PbrwarpError, OSError, ImportError) as err:
        return _fail(EXIT_USAGE, f"error: {_one_line(err)}", verbose)
    except MemoryError as err:
        return _fail(EXIT_USAGE, _out_of_memory(err), verbose)
    except KeyboardInterrupt:
        return _fail(EXIT_INTERRUPTED, "interrupted", verbose)
    except Terminated:
        return _fail(EXIT_TERMINATED, "terminated", verbose)
    except Exception as err:
        if isinstance(err, RuntimeError) and str(err).startswith("Failed to allocate"):  # Warp's wording
            return _fail(EXIT_USAGE, _out_of_memory(err), verbose)
        return _fail(EXIT_INTERNAL_ERROR, f"internal error: {type(err).__name__}: {_one_line(err)} "
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


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__


def _out_of_memory(err: BaseException) -> str:
    return (f"error: not enough memory ({_one_line(err)}): try a smaller --size or --spp, "
            "or a scene with fewer triangles and smaller textures")


def _fail(status: int, message: str, verbose: bool) -> int:
    """Print ``message`` as one line (after the traceback, if ``verbose``) and return ``status``."""
    if verbose:
        traceback.print_exc()
    print(f"{PROG}: {message}", file=sys.stderr)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
