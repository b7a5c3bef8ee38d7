"""Exceptions pbrwarp raises for bad input.

Every error is a subclass of both :class:`PbrwarpError` (catch everything from pbrwarp) and the
built-in exception that fits (``ValueError``, ``TypeError``, ``FileNotFoundError``), so callers
that already catch those keep working.
"""


class PbrwarpError(Exception):
    """Base class of every error pbrwarp raises on purpose."""


class InputError(PbrwarpError, ValueError):
    """A value is out of range, malformed or inconsistent (the message says which and where)."""


class InputTypeError(PbrwarpError, TypeError):
    """A value has the wrong type (the message says what was expected)."""


class AssetNotFoundError(PbrwarpError, FileNotFoundError):
    """A scene, texture or environment file does not exist."""


class AssetFormatError(PbrwarpError, ValueError):
    """A file exists but cannot be read as what it claims to be."""


class ResourceError(PbrwarpError, RuntimeError):
    """The system refused something a render needs (a thread); the message says what to change."""
