"""Checks that turn bad user input into clear errors before anything reaches Warp."""

from __future__ import annotations

import math
import os

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

    def _check_together(self):
        """Check (and derive) what depends on several fields; raise InputError if they disagree."""
