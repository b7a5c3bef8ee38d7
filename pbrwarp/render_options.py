"""The options of ``pbrwarp render`` and what they mean for a render: the parsers of their
values, the argument parser, and the steps from parsed options to a saved image (camera, lights,
environment, render, save). The command line (pbrwarp.cli) and batch jobs (pbrwarp.batch, whose
jobs are these options written as JSON) share them, so that both mean the same by each option.
"""

from __future__ import annotations

import argparse
import math
import os
import re

import numpy as np

from .camera import Camera
from .emitters import emissive_materials
from .errors import InputError, PbrwarpError
from .features import DEFAULT_MAX_BOUNCES, MAX_BOUNCES
from .frame import MAX_EXPOSURE
from .lights import DirectionalLight, PointLight, RectLight, SphereLight, SpotLight
from .parallel import MAX_THREADS_PER_CORE

MAX_SIDE = 16384  # largest image side accepted from the command line
FLOAT32_MAX = float(np.finfo(np.float32).max)  # the kernels compute in float32
DEFAULT_KEY_LUX = 3.0


class UsageError(Exception):
    """A command-line value that cannot be used; the message is shown as is."""


class Parser(argparse.ArgumentParser):
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


def positive_int(what: str):
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


def finite_float(what: str, low: float = -FLOAT32_MAX, high: float = FLOAT32_MAX):
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


# ---------------------------------------------------------------------- the options
def add_output_options(p, default_size, default_spp) -> None:
    """The options of every rendering command: the image, its size and samples, and the render's."""
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output image; the extension picks the format (.png, .jpg, ... tone mapped; "
                        ".npy: linear float32 RGBA)")
    add_image_options(p, default_size, default_spp)
    p.add_argument("--explain", action="store_true",
                   help="print which effects are simulated and why the others are not, then render")


def add_image_options(p, default_size, default_spp) -> None:
    """``add_output_options``' options but the output's path and --explain: the image's size and
    samples, and the render's options (those a batch job can hold)."""
    p.add_argument("--size", type=parse_size, default=default_size, metavar="WxH",
                   help=f"image size in pixels, each side 1 to {MAX_SIDE} "
                        f"(default {default_size[0]}x{default_size[1]})")
    p.add_argument("--spp", type=positive_int("samples per pixel"), default=default_spp, metavar="N",
                   help=f"samples per pixel (default {default_spp})")
    p.add_argument("--tonemap", choices=("none", "reinhard", "aces"), default="aces",
                   help="tone map for 8-bit output (default aces)")
    p.add_argument("--exposure", type=finite_float("exposure", -MAX_EXPOSURE, MAX_EXPOSURE), default=0.0,
                   metavar="EV", help=f"exposure in stops from {-MAX_EXPOSURE:g} to {MAX_EXPOSURE:g}: "
                                      "radiance is scaled by 2^EV (default 0)")
    p.add_argument("--no-shadows", dest="shadows", action="store_const", const=False, default=True,
                   help="render no shadows")
    p.add_argument("--shadow-maps", dest="shadows", action="store_const", const="map",
                   help="look shadows up in shadow maps instead of tracing shadow rays (faster, approximate)")
    p.add_argument("--threads", type=positive_int("thread count"), default=None, metavar="N",
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
    p.add_argument("--env-intensity", type=finite_float("environment intensity", 0.0), default=1.0, metavar="X",
                   help="scale of the environment's radiance, >= 0 (default 1)")


def add_scene_options(p) -> None:
    """``pbrwarp render``'s own: the scene file, its camera and added lights."""
    p.add_argument("input", metavar="INPUT", help="scene file (.glb .gltf .obj .ply .stl .off)")
    p.add_argument("--camera", type=parse_camera, default=None, metavar="EX,EY,EZ,TX,TY,TZ",
                   help="eye and target positions (default: the file's first camera, else one framing the scene)")
    p.add_argument("--fov", type=parse_fov, default=None, metavar="DEG",
                   help="vertical field of view in degrees (default: the file camera's, else 45)")
    p.add_argument("--light", type=parse_light, action="append", default=[], metavar="SPEC",
                   help="add a light (repeatable); see the light specs below")


def render_parser() -> argparse.ArgumentParser:
    """A parser of ``pbrwarp render``'s arguments (after the command's name)."""
    parser = Parser(prog="pbrwarp render", add_help=False)
    add_scene_options(parser)
    add_output_options(parser, (800, 600), 1)
    return parser


# ---------------------------------------------------------------------- from options to an image
def check_output(path: str, transparent: bool) -> None:
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


def look_at(eye, target, fov):
    forward = np.subtract(target, eye)
    length = np.linalg.norm(forward)  # 0 for an eye on the target, which Camera.look_at refuses
    # looking (almost) straight up or down: world +Y cannot be the up vector
    up = (0.0, 1.0, 0.0)
    if length > 0.0 and np.linalg.norm(np.cross(forward / length, up)) < 1e-3:
        up = (0.0, 0.0, -1.0 if forward[1] < 0 else 1.0)
    return Camera.look_at(eye, target, up=up, fov_y=fov)


def choose_camera(scene, args) -> Camera:
    fov = args.fov
    if args.camera is not None:
        return look_at(*args.camera, 45.0 if fov is None else fov)
    if scene.cameras:
        cam = scene.cameras[0]
        return cam if fov is None else Camera(cam.eye, cam.forward, cam.up, fov_y=fov)
    width, height = args.size
    return Camera.frame(scene, fov_y=45.0 if fov is None else fov, aspect=width / height)


def _shoulder_light(camera: Camera) -> DirectionalLight:
    """A key light from above and to the right, behind the camera."""
    forward, up, right = (np.asarray(v) for v in (camera.forward, camera.up, camera.right))
    return DirectionalLight(direction=tuple(forward - 0.7 * up - 0.4 * right), intensity=DEFAULT_KEY_LUX)


def load_environment(args):
    """The ``--env`` environment at ``--env-intensity``, or None without ``--env``."""
    if args.env is None:
        return None
    from .environment import Environment

    return Environment.load(args.env, intensity=args.env_intensity)


def light_scene(scene, camera: Camera, args, environment) -> str | None:
    """Add the ``--light`` lights to ``scene`` and make ``environment`` (or None) its environment;
    a scene left unlit (no light, no environment, no emitter the path tracer sees) gets a key
    light over ``camera``'s shoulder, and the note saying so is returned (else None)."""
    for light in args.light:
        scene.add_light(light)
    scene.environment = environment
    lit_by_emitters = args.integrator == "path" and emissive_materials(scene) > 0
    if scene.lights or scene.environment is not None or lit_by_emitters:
        return None
    scene.add_light(_shoulder_light(camera))
    return (f"note: the scene has no lights; added a {DEFAULT_KEY_LUX:g} lux directional light "
            "from over the camera's shoulder (use --light to choose your own)")


def render_and_save(scene, camera, args, background, **keywords) -> None:
    """Render ``scene`` with the command line's options ``args`` (and ``keywords``, any other
    pw.render keywords; ``threads`` defaults to ``--threads``) and save the image to ``args.output``."""
    from .render import explain, render

    width, height = args.size
    options = dict(width=width, height=height, spp=args.spp, shadows=args.shadows, quality=args.quality,
                   visibility=args.visibility, background=background, texture_filter=args.texture_filter,
                   integrator=args.integrator, max_bounces=args.bounces, time_budget=args.time_budget,
                   target_error=args.target_error)
    if args.explain:
        print(explain(scene, **options))
    keywords.setdefault("threads", args.threads)
    frame = render(scene, camera, **options, **keywords)
    frame.save(args.output, exposure=args.exposure, tonemap=args.tonemap, transparent=args.transparent)


def one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__

