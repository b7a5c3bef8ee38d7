"""Rendered frames: linear radiance plus depth, normal and coverage, and their conversion to images."""

from __future__ import annotations

import math
import os
import secrets
from dataclasses import dataclass

import numpy as np
import warp as wp

from .errors import InputError, InputTypeError

from pbrwarp.kernels.tonemap import TONEMAPS, tonemap_kernel


MAX_EXPOSURE = 64.0
"""Largest |exposure| in stops: 2^64 spans any scene's radiance (the sun's disc is ~2^31 nits)
and keeps the scale, and its reciprocal, finite in the float32 the tone map computes in."""

# A new file only (O_EXCL: never one that exists, nor a symbolic link's target), mode 0o666 less
# the process's umask, which the kernel applies: the same mode as any file the user creates.
_NEW_FILE_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)


def _checked_exposure(value) -> float:
    try:
        exposure = float(value)
    except OverflowError:  # an integer beyond the float range
        exposure = math.inf
    except (TypeError, ValueError):
        raise InputTypeError(f"exposure must be a number of stops, got {value!r}") from None
    if not abs(exposure) <= MAX_EXPOSURE:
        raise InputError(f"exposure must be from {-MAX_EXPOSURE:g} to {MAX_EXPOSURE:g} stops, got {exposure:g}")
    return exposure


def _create_hidden_file(directory: str, ext: str, created: list) -> int:
    """Open a new file named ``.pbrwarp-<random><ext>`` in ``directory`` for writing; its name is
    put in ``created`` just before it is made, so a caller unwinding from an exception (Ctrl-C, or
    SIGTERM made one) in any instant after can remove it."""
    name = os.path.join(directory, f".pbrwarp-{secrets.token_hex(8)}{ext}")
    created.append(name)
    try:
        return os.open(name, _NEW_FILE_FLAGS, 0o666)
    except FileExistsError:  # not ours to remove (a 64-bit name taken by chance or by design)
        created.pop()
        raise


@dataclass
class Frame:
    """The result of :func:`pbrwarp.render`.

    - ``rgb``: (H, W, 3) float32 linear radiance (nits for white), composited over the background.
    - ``depth``: (H, W) float32 distance from the eye along the ray (the nearest over the pixel's
      samples), ``inf`` where nothing was hit.
    - ``normal``: (H, W, 3) world-space shading normal (mean over the pixel's hit samples), 0 on miss.
    - ``alpha``: (H, W) fraction of the pixel's samples that hit a surface.
    - ``background``: the linear RGB radiance ``rgb`` was composited over.
    - ``albedo``: (H, W, 3) float32 in [0, 1], the base colour of the first surface each sample
      meets (the diffuse colour of a dielectric, the normal-incidence reflectance of a metal, as
      Open Image Denoise asks of its albedo guide), the mean over the pixel's samples with 0 for
      a miss; what :func:`pbrwarp.denoise` guides the denoiser with.
    - ``spp``: the samples per pixel the frame holds (None for a frame not made by a render).
    - ``variance``: (H, W, 3) float32, per channel the estimated variance of ``rgb`` (the variance
      of each pixel's mean over its samples; its square root is the pixel's standard error),
      ``inf`` where it is not known yet (a single pass); None unless rendered progressively
      (``render(time_budget=...)``, ``render(target_error=...)``, :class:`pbrwarp.Accumulator`).
      docs/integrators.md says how it is estimated.

    ``depth``, ``normal`` and ``albedo`` are None for ``render(aovs=False)``.
    """

    rgb: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    alpha: np.ndarray
    background: tuple = (0.0, 0.0, 0.0)
    albedo: np.ndarray | None = None
    spp: int | None = None
    variance: np.ndarray | None = None

    def relative_error(self) -> float | None:
        """The frame's relative standard error: over the pixels a surface covers (``alpha`` > 0;
        all pixels if none), the mean of sqrt(mean over channels of ``variance``) / (mean over
        channels of ``rgb`` + eps), with eps 1% of those pixels' mean radiance, so that dark
        pixels count without dominating. 0.01 means noise of about 1% of each pixel's value; inf
        while the variance is unknown (one pass), None for a frame without ``variance``."""
        if self.variance is None:
            return None
        covered = self.alpha > 0.0
        if not covered.any():
            covered = np.ones_like(covered)
        mean = self.rgb[covered].astype(np.float64).mean(axis=-1)
        sigma = np.sqrt(self.variance[covered].astype(np.float64).mean(axis=-1))
        eps = max(0.01 * float(mean.mean()), float(np.finfo(np.float32).tiny))
        return float(np.mean(sigma / (mean + eps)))

    @property
    def foreground(self) -> np.ndarray:
        """Radiance of the surfaces alone, premultiplied by coverage (rgb minus the background)."""
        bg = np.asarray(self.background, dtype=np.float32)
        return self.rgb - bg * (1.0 - self.alpha[..., None])

    def to_srgb8(self, exposure: float = 0.0, tonemap: str = "aces", rgb: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) uint8 sRGB: radiance (``rgb``, default the frame's) scaled by 2^exposure
        (EV stops, from -64 to 64, default 0), tone mapped (``tonemap``: "none" clips,
        "reinhard", "aces", the default), then sRGB-encoded. NaN maps to black, Inf to white.
        InputError for an unknown tone map or an exposure out of range."""
        if tonemap not in TONEMAPS:
            raise InputError(f"tonemap must be one of {', '.join(TONEMAPS)}, got {tonemap!r}")
        exposure = _checked_exposure(exposure)
        source = self.rgb if rgb is None else rgb
        h, w = source.shape[:2]
        src = wp.array(np.ascontiguousarray(source, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device="cpu")
        out = wp.zeros((h * w, 3), dtype=wp.uint8, device="cpu")
        wp.launch(tonemap_kernel(tonemap), dim=h * w, inputs=[src, float(2.0**exposure), out], device="cpu")
        return out.numpy().reshape(h, w, 3)

    def to_rgba8(self, exposure: float = 0.0, tonemap: str = "aces") -> np.ndarray:
        """(H, W, 4) uint8 sRGB of the surfaces alone (``foreground``) with straight (unassociated)
        alpha from coverage, as PNG stores it; ``exposure`` and ``tonemap`` as for ``to_srgb8``."""
        a = self.alpha[..., None]
        straight = np.divide(self.foreground, a, out=np.zeros_like(self.rgb), where=a > 0)
        rgb8 = self.to_srgb8(exposure, tonemap, rgb=straight)
        alpha8 = np.round(np.clip(self.alpha, 0.0, 1.0) * 255.0).astype(np.uint8)
        return np.concatenate([rgb8, alpha8[..., None]], axis=2)

    def save(self, path, exposure: float = 0.0, tonemap: str = "aces", transparent: bool = False) -> None:
        """Write the frame atomically: into a new hidden file ``.pbrwarp-<random><ext>`` beside
        ``path`` (mode 0o666 less the umask, as any file the user creates), renamed onto ``path``
        once complete; an error or an interrupt removes it, so no half-written file is left.
        The extension picks the format: ``.png``/``.jpg``/... (any Pillow writes) are tone mapped
        as by ``to_srgb8`` (``exposure`` in stops from -64 to 64, default 0; ``tonemap`` default
        "aces"); ``.npy`` stores linear float32 RGBA (radiance + coverage) for further processing.
        ``transparent`` (default False) writes alpha from coverage instead of the background
        colour (PNG, WebP, TIFF). InputError for a folder that does not exist, an unknown
        extension, a format without alpha for ``transparent``, or a bad exposure or tone map;
        OSError from the file system as it is."""
        path = os.fspath(path)
        _checked_exposure(exposure)
        ext = os.path.splitext(path)[1].lower()
        directory = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(directory):
            raise InputError(f"cannot save {path}: folder {directory} does not exist")
        if ext == ".npy":
            def write(f):
                np.save(f, np.concatenate([self.rgb, self.alpha[..., None]], axis=2).astype(np.float32))
        else:
            from PIL import Image

            fmt = Image.registered_extensions().get(ext)
            if fmt is None or fmt not in Image.SAVE:
                raise InputError(f"cannot save {path}: unknown image extension {ext!r} (try .png or .npy)")
            if transparent and fmt not in ("PNG", "WEBP", "TIFF"):
                raise InputError(f"{fmt} cannot store transparency; save as .png")
            pixels = self.to_rgba8(exposure, tonemap) if transparent else self.to_srgb8(exposure, tonemap)
            image = Image.fromarray(pixels)

            def write(f):
                image.save(f, format=fmt)
        created = []  # the temporary file, once it exists
        try:
            fd = _create_hidden_file(directory, ext, created)
            with os.fdopen(fd, "wb") as f:
                write(f)
            os.replace(created[0], path)
        except BaseException:
            for name in created:
                try:
                    os.unlink(name)
                except FileNotFoundError:
                    pass
            raise
