"""Debug helpers: is a frame numerically sound?"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Radiance (nits) above which a pixel counts as absurd: 20 orders of magnitude above the sun's
# disc (~1.6e9 nits) and 8 below float32's maximum, 3.4e38, where the render kernel clamps an
# overflow or a NaN (kernels/robust.py clamp_to_float32_max), which would otherwise pass as finite.
# Extreme but sound inputs stay below it: a 10 cd light 1e-12 m above a surface gives ~3e24 nits.
MAX_PLAUSIBLE_RADIANCE = 1e30


@dataclass(frozen=True)
class FrameCheck:
    """Counts of pixels with a NaN, an Inf or a negative value in any channel of a frame's
    radiance, normal, coverage or depth (depth may be +Inf where nothing was hit), and of pixels
    whose finite radiance exceeds MAX_PLAUSIBLE_RADIANCE (``absurd``). ``ok``: none of these."""

    pixels: int
    nan: int
    inf: int
    negative: int
    absurd: int = 0

    @property
    def ok(self) -> bool:
        return self.nan == 0 and self.inf == 0 and self.negative == 0 and self.absurd == 0

    def __str__(self) -> str:
        if self.ok:
            return f"ok: {self.pixels} pixels, all finite, non-negative and below {MAX_PLAUSIBLE_RADIANCE:g} nits"
        return (f"{self.nan} pixels with NaN, {self.inf} with Inf, {self.negative} negative, {self.absurd} with "
                f"radiance above {MAX_PLAUSIBLE_RADIANCE:g} nits (of {self.pixels})")


def check(frame) -> FrameCheck:
    """Count the pixels of ``frame`` whose values are NaN, Inf or negative, or whose radiance is
    absurdly high (above MAX_PLAUSIBLE_RADIANCE nits: an overflow, or a NaN clamped).

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
    absurd = (np.isfinite(rgb) & (rgb > MAX_PLAUSIBLE_RADIANCE)).any(-1)
    return FrameCheck(pixels=int(alpha.size), nan=int(nan.sum()), inf=int(inf.sum()), negative=int(negative.sum()),
                      absurd=int(absurd.sum()))
