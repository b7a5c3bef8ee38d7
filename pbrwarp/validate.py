"""Checks that turn bad user input into clear errors before anything reaches Warp."""

from __future__ import annotations

import functools
import math
import os
import stat
import urllib.parse

import numpy as np

from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError
from pbrwarp.kernels.triangle_setup import MAX_IMAGE_SIZE

FLOAT32_MAX = float(np.finfo(np.float32).max)


def finite_vector(value, length: int, what: str) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` finite floats."""
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} must be {length} numbers, got {value!r}") from None
    if arr.shape != (length,):
        raise InputError(f"{what} must have {length} components, got {arr.size}: {value!r}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be finite, got {value!r}")
    return tuple(float(x) for x in arr)


def float32_vector(value, length: int, what: str) -> tuple[float, ...]:
    """``value`` as a tuple of ``length`` floats within float32's range, which the kernels compute
    in (a position of 1e39 would reach them as Inf)."""
    vector = finite_vector(value, length, what)
    if max(abs(x) for x in vector) > FLOAT32_MAX:
        raise InputError(f"{what} {vector} exceeds the float32 range (|x| < 3.4e38) the kernels compute in")
    return vector


def unit_vector(value, what: str) -> tuple[float, float, float]:
    """``value`` (3 finite numbers, not all zero) scaled to unit length."""
    v = np.asarray(finite_vector(value, 3, what))
    length = np.linalg.norm(v)
    if length == 0.0:
        raise InputError(f"{what} must not be the zero vector")
    return tuple(float(c) for c in v / length)


def finite_scalar(value, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise InputError(f"{what} must be finite, got {value!r}")
    return x


def non_negative(value, what: str) -> float:
    x = finite_scalar(value, what)
    if x < 0.0:
        raise InputError(f"{what} must be >= 0, got {x}")
    return x


def unit_interval(value, what: str) -> float:
    """A factor in [0, 1]. Out-of-range values are rejected, not clamped: a roughness of 1.5
    is far more often a bug (a percentage, a wrong channel) than an intent."""
    x = finite_scalar(value, what)
    if not 0.0 <= x <= 1.0:
        raise InputError(f"{what} must lie in [0, 1], got {x}")
    return x


def colour(value, what: str, allow_alpha: bool = False) -> tuple[float, ...]:
    """An RGB (or RGBA) colour of non-negative finite components."""
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} must be an RGB triple, got {value!r}") from None
    sizes = (3, 4) if allow_alpha else (3,)
    if arr.size not in sizes:
        raise InputError(f"{what} must have {' or '.join(map(str, sizes))} components, got {value!r}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise InputError(f"{what} must be finite and non-negative, got {value!r}")
    return tuple(float(x) for x in arr)


def positive_int(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{what} must be a whole number, got {value!r}")
    if value <= 0:
        raise InputError(f"{what} must be > 0, got {value}")
    return int(value)


def readable_file(path, what: str, extensions: tuple, kinds: str) -> tuple[str, str]:
    """(path, lower-case extension) of an existing file whose extension is one of ``extensions``;
    ``what`` names the file in messages ("scene file") and ``kinds`` describes what it should be."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise AssetNotFoundError(f"{what} not found: {path}")
    if os.path.isdir(path):
        raise AssetFormatError(f"cannot load {path}: it is a folder, not a {what}")
    ext = os.path.splitext(path)[1].lower()
    if ext not in extensions:
        raise AssetFormatError(f"cannot load {path}: unsupported extension {ext!r} for a {what} "
                               f"(supported: {', '.join(extensions)}, {kinds})")
    return path, ext


# ---------------------------------------------------------------------- render sizes (docs/limits.md)
# Pixels a side: the rasterizer's fixed-point edge functions are exact up to this size, and every
# render may rasterize.
MAX_IMAGE_SIDE = MAX_IMAGE_SIZE
# Samples per pixel: the multi-jittered sampler (kernels/sampling.py) permutes strata of up to spp
# as i -> (a i + b) mod n in int32, with a <= n + 1, i and b < n <= spp: exact while
# spp^2 + spp - 2 < 2^31.
MAX_SPP = 46340
# Samples in a frame (width * height * spp): the kernels number them, and the sample-position and
# visibility-buffer launches index them, with int32.
MAX_SAMPLES = 2**31 - 1
# Samples in a row (width * spp): a Warp array's strides are int32 bytes, and the visibility
# buffer and the sample positions hold 8 bytes a sample in rows of width * spp.
MAX_ROW_SAMPLES = (2**31 - 1) // 8
# Share of the machine's memory one frame's buffers may take.
MEMORY_SHARE = 0.5
# Bytes a frame keeps per pixel (radiance and coverage; depth, normal and albedo with AOVs) and per
# sample where primary visibility is rasterized (the visibility buffer and the sample positions).
PIXEL_BYTES = 12 + 4
AOV_PIXEL_BYTES = 4 + 12 + 12
SAMPLE_BYTES = 8 + 8
# Bytes a progressive render (pbrwarp/progressive.py) keeps per pixel beside each pass's outputs:
# the float64 sums of radiance, squared radiance and coverage and the accumulated frame's
# radiance, coverage and variance; with AOVs, the sums of depth (float32), normal and albedo
# (float64) and the accumulated frame's depth, normal and albedo.
PROGRESSIVE_PIXEL_BYTES = 24 + 24 + 8 + 12 + 4 + 12
PROGRESSIVE_AOV_PIXEL_BYTES = 4 + 24 + 24 + 4 + 12 + 12


def frame_bytes(width: int, height: int, spp: int, aovs: bool = True, rasterized: bool = True,
                progressive: bool = False) -> int:
    """Bytes of the buffers a width x height render at ``spp`` allocates: its outputs, the
    per-sample buffers of rasterized primary visibility (``rasterized``), and the sums and
    accumulated frame of a progressive render (``progressive``)."""
    per_pixel = PIXEL_BYTES + (AOV_PIXEL_BYTES if aovs else 0) + (SAMPLE_BYTES * spp if rasterized else 0)
    if progressive:
        per_pixel += PROGRESSIVE_PIXEL_BYTES + (PROGRESSIVE_AOV_PIXEL_BYTES if aovs else 0)
    return width * height * per_pixel


def _proc_status_bytes(field: str) -> int | None:
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


@functools.cache
def _physical_memory() -> int | None:
    """Bytes of memory this process may use: the machine's, or its control group's if smaller."""
    sizes = []
    try:
        sizes.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as limit:
                sizes.append(int(limit.read().split()[0]))
        except (OSError, ValueError, IndexError):
            continue
    sizes = [s for s in sizes if s > 0]
    return min(sizes) if sizes else None


def memory_limit() -> tuple[int | None, str]:
    """(bytes one frame's buffers may take, None for no limit known; what the bound is): MEMORY_SHARE
    of the memory this process may use, and no more than the room left under its address-space or
    data-segment limit (``ulimit -v``, ``ulimit -d``)."""
    bounds = []
    physical = _physical_memory()
    if physical is not None:
        bounds.append((int(MEMORY_SHARE * physical),
                       f"{MEMORY_SHARE:.0%} of the {_bytes_text(physical)} of memory this process may use"))
    try:
        import resource

        for name, field, option in (("RLIMIT_AS", "VmSize", "-v"), ("RLIMIT_DATA", "VmData", "-d")):
            soft = resource.getrlimit(getattr(resource, name))[0]
            used = _proc_status_bytes(field)
            if soft != resource.RLIM_INFINITY and used is not None:
                bounds.append((max(soft - used, 0), f"the room left under this process's ulimit {option}"))
    except (ImportError, AttributeError, OSError, ValueError):
        pass
    if not bounds:
        return None, "no memory limit known"
    return min(bounds)


def _bytes_text(n: float) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024


def render_size(width, height, spp, aovs: bool = True, rasterized: bool = True,
                progressive: bool = False) -> tuple[int, int, int]:
    """(width, height, spp) of a render, checked before anything is allocated: whole numbers >= 1
    within MAX_IMAGE_SIDE, MAX_SPP, MAX_SAMPLES and MAX_ROW_SAMPLES, and the frame's buffers
    (:func:`frame_bytes`, with a progressive render's sums where ``progressive``) within
    :func:`memory_limit`. One error names every limit exceeded."""
    width = positive_int(width, "width")
    height = positive_int(height, "height")
    spp = positive_int(spp, "spp")
    problems = []
    if max(width, height) > MAX_IMAGE_SIDE:
        problems.append(f"more than {MAX_IMAGE_SIDE} pixels a side")
    if spp > MAX_SPP:
        problems.append(f"more than {MAX_SPP} samples per pixel")
    if width * height * spp > MAX_SAMPLES:
        problems.append(f"{width * height * spp:.3g} samples, more than 2^31 - 1")
    if width * spp > MAX_ROW_SAMPLES:
        problems.append(f"{width * spp:.3g} samples a row, more than 2^28 - 1")
    needed = frame_bytes(width, height, spp, aovs, rasterized, progressive)
    limit, bound = memory_limit()
    if limit is not None and needed > limit:
        problems.append(f"{_bytes_text(needed)} of buffers, more than the {_bytes_text(limit)} allowed ({bound})")
    if problems:
        advice = "render fewer pixels or samples per pixel (or average frames rendered with different seeds)"
        if rasterized and limit is not None and needed > limit:
            advice += ", or use visibility=\"raycast\", which keeps no per-sample buffers"
        raise InputError(f"cannot render {width}x{height} pixels at spp {spp}: {'; '.join(problems)}. "
                         f"{advice.capitalize()}; docs/limits.md lists the limits and their reasons")
    return width, height, spp


# ---------------------------------------------------------------------- fields checked on assignment
class Checked:
    """Base of the scene objects (dataclasses) whose fields are checked whenever they are set: by
    the constructor and by any later assignment, with the same check, so that an object never
    holds a value the kernels cannot take (``light.position = (nan, 0, 0)`` raises as
    ``PointLight(position=(nan, 0, 0))`` does).

    A subclass maps field names to checks in ``_checks``, ``{name: check(obj, value) -> the value
    to store}``, in the order the constructor runs them, and may override
    :meth:`_check_together` for rules linking several fields. An assignment that breaks such a
    rule is undone before the error propagates."""

    _checks: dict = {}
    # Checked assignments since construction: caches that key an object by identity (a
    # Primitive's geometry, a Texture's texels) key it by (object, revision) too.
    _revision = 0

    def __post_init__(self):
        # the dataclass __init__ has stored every field unchecked (see __setattr__)
        for name, check in self._checks.items():
            object.__setattr__(self, name, check(self, getattr(self, name)))
        self._check_together()

    def __setattr__(self, name, value):
        check = self._checks.get(name)
        if check is None or name not in self.__dict__:
            # not a checked field, or its first assignment, by __init__: __post_init__ checks it
            # once every field is there, so that a check may read the others
            object.__setattr__(self, name, value)
            return
        old = self.__dict__[name]
        object.__setattr__(self, name, check(self, value))
        try:
            self._check_together()
        except BaseException:
            object.__setattr__(self, name, old)
            raise
        object.__setattr__(self, "_revision", self._revision + 1)

    def _check_together(self):
        """Check (and derive) what depends on several fields; raise InputError if they disagree."""


def revision(obj) -> tuple:
    """(``obj``, how many checked assignments it has had): a cache key for an object compared by
    identity that no longer matches once one of its fields was set anew (:class:`Checked`)."""
    return obj, obj._revision


# ---------------------------------------------------------------------------- files a model names
def allowed_roots(roots, what: str = "allowed_roots") -> tuple[str, ...]:
    """``roots`` (folders, or None) as a tuple of existing folders' real paths."""
    if roots is None:
        return ()
    if isinstance(roots, (str, bytes, os.PathLike)):
        roots = (roots,)
    try:
        paths = [os.fspath(r) for r in roots]
    except TypeError:
        raise InputTypeError(f"{what} must be a list of folders, got {roots!r}") from None
    out = []
    for path in paths:
        if not os.path.isdir(path):
            raise AssetNotFoundError(f"{what}: {path!r} is not a folder")
        out.append(os.path.realpath(path))
    return tuple(out)


def confined_path(uri: str, base_dir: str, roots: tuple[str, ...], what: str, model: str,
                  percent_encoded: bool = True) -> str:
    """The real path of the file a model's relative ``uri`` names, refused unless it lies inside
    the model's folder ``base_dir`` or one of ``roots`` (real paths, see :func:`allowed_roots`).

    The URI is percent-decoded once (unless ``percent_encoded`` is False: an OBJ's plain path)
    and resolved against ``base_dir`` with every ``..`` and
    symbolic link followed, and only then compared with the folders; nothing is opened. Refused
    outright: a scheme (``file:``, ``http:``, a drive letter), a host (``//server/...``), a NUL
    byte or a backslash, percent-encoded or not (a separator on Windows, a name character
    elsewhere: refused so a file means the same everywhere). ``what`` names the URI's user ("image
    3"), ``model`` the file, in messages."""
    def refuse(reason: str):
        return AssetFormatError(f"cannot load {model}: {what} has URI {uri!r}, which {reason}; pbrwarp reads "
                                "only files inside the model's folder (see docs/loading.md)")

    if not isinstance(uri, str):
        raise AssetFormatError(f"cannot load {model}: {what} has URI {uri!r}, which is not a string")
    parsed = urllib.parse.urlsplit(uri)
    if parsed.scheme:
        raise refuse(f"has the scheme {parsed.scheme + ':'!r} (only relative paths and data: URIs are read)")
    if parsed.netloc:
        raise refuse(f"names the host {parsed.netloc!r}")
    try:
        path = urllib.parse.unquote(uri, errors="strict") if percent_encoded else uri
    except UnicodeDecodeError:
        raise refuse("is not percent-encoded UTF-8") from None
    for char, name in (("\0", "a NUL byte"), ("\\", "a backslash")):
        if char in uri or char in path:
            raise refuse(f"contains {name}")
    if not path:
        raise refuse("is empty")
    real = os.path.realpath(os.path.join(base_dir, path))
    root = os.path.realpath(base_dir)
    for folder in (root, *roots):
        try:
            if os.path.commonpath([real, folder]) == folder:
                return real
        except ValueError:  # on Windows, paths on different drives
            continue
    kind = "is an absolute path" if os.path.isabs(path) else "leads"
    raise refuse(f"{kind} outside {root} (to {real})"
                 + (" and outside every folder of allowed_roots" if roots else ""))


def read_confined(real: str, what: str, model: str, max_bytes: int | None = None) -> bytes:
    """The bytes (at most ``max_bytes``) of the regular file ``real`` (a :func:`confined_path`).
    The file opened must be the one checked: its final component is not followed if it became a
    symbolic link, a FIFO or device is refused rather than read (which could block forever), and
    its device and inode must match the checked path's."""
    try:
        checked = os.stat(real)
    except FileNotFoundError:
        raise AssetNotFoundError(f"cannot load {model}: {what} file not found: {real}") from None
    except OSError as err:
        raise AssetFormatError(f"cannot load {model}: {what} file {real} cannot be read: {err.strerror}") from None
    if not stat.S_ISREG(checked.st_mode):
        raise AssetFormatError(f"cannot load {model}: {what} names {real}, which is not a regular file")
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(real, flags)
    except OSError as err:
        raise AssetFormatError(f"cannot load {model}: {what} file {real} cannot be opened: {err.strerror}") from None
    with os.fdopen(fd, "rb") as f:
        opened = os.fstat(f.fileno())
        if (opened.st_dev, opened.st_ino) != (checked.st_dev, checked.st_ino):
            raise AssetFormatError(f"cannot load {model}: {what} file {real} changed while it was being opened")
        return f.read() if max_bytes is None else f.read(max_bytes)
