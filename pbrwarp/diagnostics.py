"""Debug helpers: is a frame numerically sound?"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FrameCheck:
    """Counts of pixels with a NaN, an Inf or a negative value in any channel of a frame's
    radiance, normal, coverage or depth (depth may be +Inf where nothing was hit)."""

    pixels: int
    nan: int
    inf: int
    negative: int

    @property
    def ok(self) -> bool:
        return self.nan == 0 and self.inf == 0 and self.negative == 0

    def __str__(self) -> str:
        if self.ok:
            return f"ok: {self.pixels} pixels, all finite and non-negative"
        return (f"{self.nan} pixels with NaN, {self.inf} with Inf, {self.negative} negative "
                f"(of {self.pixels})")


def check(frame) -> FrameCheck:
    """Count the pixels of ``frame`` whose values are NaN, Inf or negative.

    >>> report = pw.check(frame); assert report.ok, report
    """
    rgb, alpha = frame.rgb, frame.alpha
    # without AOVs (render(aovs=False)) there is no depth or normal to check
    normal = frame.normal if frame.normal is not None else np.zeros_like(rgb)
    depth = frame.depth if frame.depth is not None else np.zeros_like(alpha)
    hit = alpha > 0
    nan = np.isnan(rgb).any(-1) | np.isnan(normal).any(-1) | np.isnan(alpha) | np.isnan(depth)
    inf = np.isinf(rgb).any(-1) | np.isinf(normal).any(-1) | np.isinf(alpha) | (np.isinf(depth) & hit)
    negative = (rgb < 0).any(-1) | (alpha < 0) | (depth < 0)
    return FrameCheck(pixels=int(alpha.size), nan=int(nan.sum()), inf=int(inf.sum()), negative=int(negative.sum()))
