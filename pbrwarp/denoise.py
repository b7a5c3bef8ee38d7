"""Denoising a rendered frame: Intel Open Image Denoise (Áfra et al., OIDN 2), through the pyoidn
binding (the ``denoise`` extra), guided by the frame's albedo and normal outputs.

A denoiser is a rung of its own on the accuracy ladder: N samples per pixel and a denoise
against M samples without (docs/accuracy.md). It is biased (it blurs what it takes for noise),
so ground truths and tests never use it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .errors import InputError, InputTypeError
from .frame import Frame

QUALITIES = ("high", "balanced", "fast")


def _pyoidn():
    try:
        import pyoidn
    except ImportError as error:
        raise ImportError("denoising needs Intel Open Image Denoise's Python binding: "
                          "pip install 'pbrwarp[denoise]' (or pip install pyoidn)") from error
    return pyoidn


def denoise(frame: Frame, quality: str = "high", guides: bool = True) -> Frame:
    """A copy of ``frame`` whose ``rgb`` is denoised by OIDN's ray-tracing filter (HDR mode).

    - ``quality``: "high" (default), "balanced" or "fast": OIDN's filter quality, slower to faster.
    - ``guides``: True (default) feeds the frame's ``albedo`` and ``normal`` outputs to the filter
      where the frame has them (``normal`` needs ``albedo`` too, as OIDN requires), which keeps
      texture and geometric edges that noise alone would blur; False denoises the colour alone.

    The other outputs are the frame's own, but for ``variance`` (None: it measured the noise the
    denoiser removed, and nothing estimates the denoised image's error). Raises InputTypeError unless ``frame`` is a
    :class:`Frame`, InputError for an unknown ``quality`` or a frame with non-finite or negative
    radiance, and ImportError naming the extra to install when pyoidn is missing.
    """
    if not isinstance(frame, Frame):
        raise InputTypeError(f"denoise takes a pbrwarp Frame (what pw.render returns), got {type(frame).__name__}")
    if quality not in QUALITIES:
        raise InputError(f"denoise quality must be one of {', '.join(QUALITIES)}, got {quality!r}")
    colour = np.ascontiguousarray(frame.rgb, dtype=np.float32)
    if colour.ndim != 3 or colour.shape[2] != 3 or colour.size == 0:
        raise InputError(f"frame.rgb must be an (H, W, 3) image, got shape {colour.shape}")
    if not np.all(np.isfinite(colour)) or colour.min() < 0.0:
        raise InputError("denoise needs finite, non-negative radiance in frame.rgb")
    albedo = normal = None
    if guides and frame.albedo is not None:
        albedo = np.ascontiguousarray(np.clip(frame.albedo, 0.0, 1.0), dtype=np.float32)
        if frame.normal is not None:
            normal = np.ascontiguousarray(np.clip(frame.normal, -1.0, 1.0), dtype=np.float32)
    rgb = _pyoidn().denoise(colour, albedo, normal, hdr=True, quality=quality)
    # OIDN's network can leave tiny negative values near black; radiance is non-negative
    return dataclasses.replace(frame, rgb=np.maximum(np.asarray(rgb, dtype=np.float32), 0.0), variance=None)
