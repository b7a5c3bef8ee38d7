"""Upper bounds on what loading one file may build, checked before anything is allocated.

A small file can describe a huge load: a 141 KB PNG that decodes to 12,000 x 12,000 texels, an
accessor whose ``count`` is 2^26 with no data behind it, a node graph that places one mesh a
million times. The loaders compare every such size, read from headers and the glTF JSON, with
these limits first and refuse a file past them with an ``AssetFormatError`` naming the limit.
docs/loading.md explains each one and how to raise it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from .errors import InputError, InputTypeError


@dataclass(frozen=True)
class LoadLimits:
    """Limits on one file's load (``Scene.load(path, limits=LoadLimits(...))``).

    - ``max_texture_side``: texels along either side of one image (default 8192: an "8K"
      texture, 256 MiB as 8-bit RGBA). Checked from the image header, before decoding.
    - ``max_texels``: texels of all the file's decoded images together (default 2^29, 2 GiB as
      8-bit RGBA).
    - ``max_node_depth``: nesting depth of the glTF node hierarchy (default 1024).
    - ``max_instances``: meshes placed in the scene, counting each primitive of each mesh node
      once (default 65,536).
    - ``max_vertices`` / ``max_triangles``: vertices and triangles of the whole scene after node
      instancing (default 2^25, ~33.5 million, each). An accessor without data (a bufferView) may
      not hold more than ``max_vertices`` elements either.

    Each limit is a positive whole number (InputError, or InputTypeError for a non-integer,
    otherwise); raise one when a trusted file needs it.
    """

    max_texture_side: int = 8192
    max_texels: int = 2**29
    max_node_depth: int = 1024
    max_instances: int = 65536
    max_vertices: int = 2**25
    max_triangles: int = 2**25

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise InputTypeError(f"LoadLimits.{f.name} must be a whole number, got {value!r}")
            if value <= 0:
                raise InputError(f"LoadLimits.{f.name} must be > 0, got {value}")

    @classmethod
    def of(cls, limits) -> "LoadLimits":
        """``limits`` itself, or the defaults for None."""
        if limits is None:
            return cls()
        if not isinstance(limits, cls):
            raise InputTypeError(f"limits must be a pbrwarp.LoadLimits or None, got {type(limits).__name__}")
        return limits
