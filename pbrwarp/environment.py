"""Environments: radiance arriving from every direction, from an equirectangular HDR image, a
uniform colour or a procedural sky, and the data image-based lighting needs from it.

Radiance is linear, in the same units as ``frame.rgb`` (a white Lambert surface under a uniform
environment of radiance 1 has radiance 1), times ``intensity``. ``rotation`` turns the
environment about the up axis +Y by that many radians (kernels/ibl.py gives the matrix).
Directions map to the image as three.js's ``equirectUv`` does (kernels/equirect.py): the top row
is +Y, the image's centre column looks along +X, the column a quarter of the width to its right
along +Z.

Files are read with OpenImageIO (the ``env`` extra: ``pip install 'pbrwarp[env]'``), the
Academy Software Foundation's image library: one ~8 MB wheel with only NumPy as a dependency
reads both Radiance .hdr and OpenEXR offline (OpenCV 5's wheels have no OpenEXR and OpenCV 4's
disable it by default; imageio needs FreeImage downloaded at run time for .hdr; the OpenEXR
bindings read only .exr). Its .hdr pixels are bit-identical to OpenCV's.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import AssetFormatError, InputError, InputTypeError
from .parallel import run, thread_count

LOADABLE = (".hdr", ".exr")
# OpenImageIO's names of the formats accepted (by content, whatever the extension says)
_FORMATS = {"hdr": "Radiance HDR", "openexr": "OpenEXR"}
# Rows of the rasterized procedural sky and uniform environments.
SKY_HEIGHT = 128
UNIFORM_HEIGHT = 4


class Environment:
    """Distant lighting from an equirectangular radiance image of (H, 2H, 3) linear RGB texels.

    ``Environment(texels, intensity=1.0, rotation=0.0, name="")`` takes an array of shape
    (H, 2H, 3), finite, non-negative and within float32's range (copied as float32);
    ``intensity`` (>= 0, default 1) scales the radiance and ``rotation`` turns it about +Y
    (radians, default 0); ``name`` is for messages. Bad texels or values raise InputError (texels
    that are not numbers, InputTypeError). ``load``, ``uniform`` and ``sky`` make one from a
    file, a colour or a gradient. The texels are kept read-only, so the prefiltered levels and SH
    coefficients derived from them (``data()``) are computed once per process, for every scene
    using this environment (pbrwarp.scene_cache.prefiltered_environment); ``intensity`` and
    ``rotation`` may be changed at any time without recomputing anything.
    """

    def __init__(self, texels, intensity: float = 1.0, rotation: float = 0.0, name: str = ""):
        self.name = name
        what = f"environment {name!r}" if name else "environment"
        try:
            arr = np.array(texels, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputTypeError(f"{what} texels must be a numeric (H, 2H, 3) array") from None
        if arr.ndim != 3 or arr.shape[2] != 3:
            raise InputError(f"{what} texels must have shape (H, 2H, 3) (linear RGB), got {arr.shape}")
        height, width = arr.shape[:2]
        if height < 1 or width != 2 * height:
            raise InputError(f"{what} must be an equirectangular image, twice as wide as tall; got {width}x{height}")
        with np.errstate(over="ignore"):
            texels32 = arr.astype(np.float32)
        bad = ~np.isfinite(texels32).all(axis=2)
        if bad.any():
            row, column = np.argwhere(bad)[0]
            raise InputError(f"{what} has {int(bad.sum())} texels that are NaN, Inf or beyond float32 "
                             f"(first at row {row}, column {column})")
        if (texels32 < 0).any():
            raise InputError(f"{what} has negative radiance (minimum {float(texels32.min())}); radiance must be >= 0")
        texels32.setflags(write=False)
        self.texels = texels32
        self.intensity = intensity
        self.rotation = rotation

    @property
    def intensity(self) -> float:
        return self._intensity

    @intensity.setter
    def intensity(self, value):
        self._intensity = validate.non_negative(value, "environment intensity")

    @property
    def rotation(self) -> float:
        """Radians about +Y."""
        return self._rotation

    @rotation.setter
    def rotation(self, value):
        self._rotation = validate.finite_scalar(value, "environment rotation")

    @property
    def height(self) -> int:
        return self.texels.shape[0]

    @property
    def width(self) -> int:
        return self.texels.shape[1]

    def __repr__(self):
        return (f"Environment({self.name or 'array'}, {self.width}x{self.height}, intensity={self.intensity}, "
                f"rotation={self.rotation})")

    # ------------------------------------------------------------------ making one
    @classmethod
    def load(cls, path, intensity: float = 1.0, rotation: float = 0.0) -> "Environment":
        """Read an equirectangular Radiance .hdr or OpenEXR .exr image (linear radiance, twice as
        wide as tall), with ``intensity`` and ``rotation`` as in the constructor. Needs the ``env``
        extra (OpenImageIO; ImportError saying so otherwise). AssetNotFoundError for a missing
        file, AssetFormatError for one that is not such an image or holds NaN, Inf or negative
        radiance."""
        path, _ = validate.readable_file(path, "environment image", LOADABLE, "equirectangular HDR images")
        pixels = _read_hdr_image(path)
        try:
            return cls(pixels, intensity=intensity, rotation=rotation, name=os.path.basename(path))
        except InputError as err:
            raise AssetFormatError(f"cannot use {path}: {err}") from None

    @classmethod
    def uniform(cls, color=(1.0, 1.0, 1.0), intensity: float = 1.0) -> "Environment":
        """The same radiance ``color`` (linear RGB >= 0, or one number for grey; default white)
        from every direction, times ``intensity`` (default 1)."""
        rgb = np.broadcast_to(np.asarray(color, dtype=np.float64), (3,)) if np.ndim(color) == 0 else color
        rgb = validate.colour(rgb, "uniform environment colour")
        texels = np.broadcast_to(np.array(rgb), (UNIFORM_HEIGHT, 2 * UNIFORM_HEIGHT, 3))
        return cls(texels, intensity=intensity, name="uniform")

    @staticmethod
    def sky_radiance(directions, zenith, horizon, ground) -> np.ndarray:
        """Float64 radiance of the procedural sky towards unit ``directions`` (N, 3) (image frame):
        linear in the height y from ``horizon`` at y = 0 to ``zenith`` at y = 1 above, and to
        ``ground`` at y = -1 below; continuous, with no sun."""
        y = np.asarray(directions, dtype=np.float64)[..., 1:2]
        zenith, horizon, ground = (np.asarray(c, dtype=np.float64) for c in (zenith, horizon, ground))
        return np.where(y >= 0.0, horizon + (zenith - horizon) * y, horizon + (ground - horizon) * -y)

    @classmethod
    def sky(cls, zenith=(0.3, 0.5, 1.0), horizon=(1.0, 1.0, 1.0), ground=(0.3, 0.27, 0.25),
            intensity: float = 1.0, rotation: float = 0.0, height: int = SKY_HEIGHT) -> "Environment":
        """A sun-less gradient sky (``sky_radiance``) of linear RGB ``zenith``, ``horizon`` and
        ``ground`` radiances, rasterized at its texel centres into ``height`` rows (default 128)
        of twice as many columns; ``intensity`` and ``rotation`` as in the constructor."""
        colours = [validate.colour(c, f"sky {what} colour") for c, what in
                   ((zenith, "zenith"), (horizon, "horizon"), (ground, "ground"))]
        height = validate.positive_int(height, "sky height")
        theta = np.pi * (np.arange(height) + 0.5) / height
        phi = 2.0 * np.pi * ((np.arange(2 * height) + 0.5) / (2 * height) - 0.5)
        directions = np.stack(np.broadcast_arrays(np.sin(theta)[:, None] * np.cos(phi), np.cos(theta)[:, None],
                                                  np.sin(theta)[:, None] * np.sin(phi)), axis=-1)
        return cls(cls.sky_radiance(directions, *colours), intensity=intensity, rotation=rotation, name="sky")

    # ------------------------------------------------------------------ what the kernels read
    def data(self, threads: int | None = None):
        """The environment as the render kernel reads it (kernels.ibl.EnvironmentData): the source
        and its GGX-prefiltered levels, its 9 SH coefficients, its importance sampler
        (``sampler()``), and the current intensity and rotation. The first call in the process prefilters (on ``threads`` threads, all cores by
        default) and projects; later calls, from any thread, share that work and make only a new
        struct (so a render never sees another's intensity or rotation change under it)."""
        from .kernels.ibl import EnvironmentData

        prefiltered = self._prefiltered(threads)
        data = EnvironmentData()
        data.radiance = prefiltered.radiance
        data.sh = prefiltered.sh
        data.sampler = self.sampler()
        data.intensity = self.intensity
        data.rotation_cos = float(np.cos(self.rotation))
        data.rotation_sin = float(np.sin(self.rotation))
        return data

    def sampler(self):
        """The importance sampler of the environment's radiance, as kernels read it
        (kernels.environment_sampling.EnvironmentSampler: directions drawn in proportion to
        luminance, with their densities). Built from the texels on the first call in the process,
        and shared by every later call from any thread; it does not depend on ``intensity`` or
        ``rotation``, which the kernels take from ``data()``."""
        from .kernels.environment_sampling import build_sampler
        from .scene_cache import environment_sampler

        return environment_sampler(self, lambda: build_sampler(self.texels))

    def sh_coefficients(self) -> np.ndarray:
        """(9, 3) float64 SH coefficients of the unscaled, unrotated radiance (order of kernels/sh.py)."""
        return self._prefiltered(None).coefficients.copy()

    def _prefiltered(self, threads) -> "_Prefiltered":
        from .scene_cache import prefiltered_environment

        return prefiltered_environment(self, lambda: _Prefiltered.of(self.texels, thread_count(threads)))


@dataclass(frozen=True)
class _Prefiltered:
    """Texels GGX-prefiltered (kernels/prefilter.py: ``radiance``, level 0 the source) and
    projected on 9 SH coefficients (kernels/sh.py: float64 ``coefficients``, and ``sh`` as the
    render kernel reads them)."""

    radiance: object
    coefficients: np.ndarray
    sh: object

    @classmethod
    def of(cls, texels: np.ndarray, workers: int) -> "_Prefiltered":
        import warp as wp

        from .kernels.prefilter import prefilter
        from .kernels.sh import project_sh

        def run_bands(launch, rows):
            bounds = np.linspace(0, rows, min(workers, rows) + 1).astype(int)
            bands = [(int(a), int(b - a)) for a, b in zip(bounds[:-1], bounds[1:])]
            list(run(lambda band: launch(*band), bands, workers))

        levels, _ = prefilter(texels, run_bands)
        # level 0, the source, starts the flat texel array
        coefficients = project_sh(levels.texels, texels.shape[1], texels.shape[0])
        return cls(levels, coefficients, wp.array(coefficients.astype(np.float32), dtype=wp.vec3, device="cpu"))


def _read_hdr_image(path: str) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of a Radiance .hdr or OpenEXR file (first subimage)."""
    try:
        import OpenImageIO as oiio
    except ImportError:
        raise ImportError("reading .hdr and .exr environments needs OpenImageIO: pip install 'pbrwarp[env]' "
                          "(or pass the texels to pw.Environment(array))") from None
    image = oiio.ImageInput.open(path)
    if image is None:
        raise AssetFormatError(f"cannot read {path}: {oiio.geterror() or 'not an image'}")
    try:
        fmt = image.format_name()
        if fmt not in _FORMATS:
            raise AssetFormatError(f"{path} is not a Radiance HDR or OpenEXR image (it reads as {fmt!r}); "
                                   "environments must be linear HDR images")
        names = list(image.spec().channelnames)
        pixels = image.read_image(oiio.FLOAT)
        if pixels is None:
            reason = image.geterror() or oiio.geterror() or "truncated or corrupt"
            raise AssetFormatError(f"cannot read {path}: {reason}")
    finally:
        image.close()
    pixels = np.asarray(pixels, dtype=np.float32).reshape(pixels.shape[0], pixels.shape[1], -1)
    if all(c in names for c in "RGB"):
        return pixels[..., [names.index(c) for c in "RGB"]]
    if pixels.shape[2] == 1:
        return np.repeat(pixels, 3, axis=2)
    raise AssetFormatError(f"{path} has channels {names}; an environment needs R, G and B (or one grey channel)")
