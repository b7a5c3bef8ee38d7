"""Checks that turn bad user input into clear errors before anything reaches Warp."""

from __future__ import annotations

import math
import os
import stat
import urllib.parse

import numpy as np

from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError


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
