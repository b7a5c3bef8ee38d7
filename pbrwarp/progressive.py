"""Progressive rendering with the path tracer: samples added in passes, within a call (a time
budget, a target error) or across calls (:class:`pbrwarp.Accumulator`), with each pixel's variance
estimated from the spread of the passes' means.

Sample s of a pixel depends only on the seed, the pixel and s (kernels/random.py), so passes of
samples [a, b), [b, c), ... weighted by their counts add up to one render of [a, c): the
accumulated image is the one a single render of as many samples gives, up to float rounding.
docs/integrators.md ("Progressive rendering") says how the variance and the error are estimated.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from . import validate
from .errors import InputError, InputTypeError
from .frame import Frame
from .parallel import progress_bar

# The most samples per pixel one call adds when no time budget bounds it (target_error alone).
MAX_SAMPLES_PER_CALL = validate.MAX_SPP
# Sample indices are int32 (kernels/random.py).
MAX_SAMPLE_INDEX = 2**31 - 1


def checked_positive(value, name: str) -> float | None:
    """``value`` (None, or a finite number above 0) as a float; InputTypeError, InputError otherwise."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputTypeError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{name} must be a finite number above 0, got {value!r}")
    return value


class _Sums:
    """Running sums over passes of n_k samples with per-pixel means m_k: sum n_k m_k and
    sum n_k m_k^2 of the radiance (float64), the count-weighted sums of coverage, albedo and
    hit-weighted normals, the nearest depth."""

    def __init__(self, frame: Frame):
        n = frame.spp
        rgb = frame.rgb.astype(np.float64)
        self.samples, self.passes = n, 1
        self.rgb = n * rgb
        self.rgb_squared = n * rgb * rgb
        self.alpha = n * frame.alpha.astype(np.float64)
        self.depth = None if frame.depth is None else frame.depth.copy()
        self.normal = None if frame.normal is None else frame.normal.astype(np.float64) * self.alpha[..., None]
        self.albedo = None if frame.albedo is None else n * frame.albedo.astype(np.float64)

    def add(self, frame: Frame):
        n = frame.spp
        rgb = frame.rgb.astype(np.float64)
        self.samples += n
        self.passes += 1
        self.rgb += n * rgb
        self.rgb_squared += n * rgb * rgb
        hits = n * frame.alpha.astype(np.float64)
        self.alpha += hits
        if self.depth is not None:
            np.minimum(self.depth, frame.depth, out=self.depth)
            self.normal += frame.normal.astype(np.float64) * hits[..., None]
            self.albedo += n * frame.albedo.astype(np.float64)

    def variance(self) -> np.ndarray:
        """The variance of each pixel's mean over all samples, per channel: sum n_k (m_k - m)^2
        / (K - 1) is unbiased for the variance of one sample (for any pass sizes n_k, the passes
        independent), and the mean of N samples has 1/N of it; inf with one pass."""
        if self.passes < 2:
            return np.full(self.rgb.shape, np.inf, dtype=np.float32)
        spread = np.maximum(self.rgb_squared - self.rgb * self.rgb / self.samples, 0.0)
        return (spread / ((self.passes - 1) * self.samples)).astype(np.float32)

    def frame(self, background) -> Frame:
        n = self.samples
        normal = None
        if self.normal is not None:
            length = np.linalg.norm(self.normal, axis=-1, keepdims=True)
            normal = np.divide(self.normal, length, out=np.zeros_like(self.normal), where=length > 0)
        return Frame(rgb=(self.rgb / n).astype(np.float32), depth=None if self.depth is None else self.depth.copy(),
                     normal=None if normal is None else normal.astype(np.float32),
                     alpha=(self.alpha / n).astype(np.float32), background=background,
                     albedo=None if self.albedo is None else (self.albedo / n).astype(np.float32), spp=n,
                     variance=self.variance())


class Accumulation:
    """Passes of a renderer's samples accumulated into one frame: the engine of
    :class:`pbrwarp.Accumulator` (which documents the contract) and of progressive renders.
    ``run`` is pbrwarp.render._renderer's function (spp, first_sample, progress) -> Frame for an
    image of ``size`` (width, height) pixels, its options checked; ``spp`` the samples of a pass,
    ``first_sample`` the first pass's first index, ``progress`` the progress option of passes."""

    def __init__(self, run, size: tuple[int, int], spp: int, first_sample: int, progress):
        self._run = run
        self._size = size
        self._pass_spp = int(spp)
        self._next_sample = int(first_sample)
        self._progress = progress
        self._sums = None
        # (frame, samples per pixel) after the last pass, replaced whole, so that readers never
        # wait for the add that holds the lock
        self._published = (None, 0)
        self._lock = threading.Lock()

    @property
    def spp(self) -> int:
        """Samples per pixel accumulated so far (0 before the first :meth:`add`); read without
        waiting for an :meth:`add` under way."""
        return self._published[1]

    @property
    def frame(self) -> Frame | None:
        """The frame of every sample added so far (None before the first :meth:`add`); read
        without waiting for an :meth:`add` under way (the frame of the passes done so far)."""
        return self._published[0]

    def add(self, spp: int | None = None, time_budget: float | None = None,
            target_error: float | None = None) -> Frame:
        """Render more samples and return the frame of all of them (:attr:`frame`).

        - ``spp``: samples per pixel of each pass (default: the Accumulator's).
        - ``time_budget``: seconds; passes are added while another, at the mean duration of this
          call's passes so far, fits in it. Without it, one pass (or, with ``target_error``,
          passes until the target is met or the call has added MAX_SAMPLES_PER_CALL samples).
        - ``target_error``: stop as soon as ``frame.relative_error()`` is at most this (above 0).

        The first pass always completes, so a call adds at least ``spp`` samples. InputError for
        values out of range, or when sample indices would pass 2^31 - 1.
        """
        budget = checked_positive(time_budget, "time_budget")
        target = checked_positive(target_error, "target_error")
        with self._lock:
            n = self._pass_spp
            if spp is not None:  # the path tracer ray casts: no per-sample buffers
                n = validate.render_size(*self._size, spp, rasterized=False, progressive=True)[2]
            start = time.perf_counter()
            added = 0
            bar = progress_bar(self._progress if budget or target else False, unit="spp", desc="render", delay=1.0,
                               leave=False)
            try:
                while True:
                    if self._next_sample + n > MAX_SAMPLE_INDEX:
                        if added:
                            break
                        raise InputError(f"cannot add {n} samples after sample {self._next_sample}: sample "
                                         "indices end at 2^31 - 1; start a new Accumulator with another seed")
                    # a single pass shows its own progress bar of rows; several, one of samples
                    frame = self._run(n, self._next_sample, self._progress if bar is None else False)
                    self._next_sample += n
                    added += n
                    if self._sums is None:
                        self._sums = _Sums(frame)
                    else:
                        self._sums.add(frame)
                    accumulated = self._sums.frame(frame.background)
                    self._published = (accumulated, self._sums.samples)
                    error = accumulated.relative_error()
                    if bar is not None:
                        bar.update(n)
                        bar.set_postfix(error=f"{error:.3g}")
                    if target is not None and error <= target:
                        break
                    if budget is not None:
                        elapsed = time.perf_counter() - start
                        if elapsed * (added + n) / added > budget:  # the next pass would not fit
                            break
                    elif target is None or added + n > MAX_SAMPLES_PER_CALL:
                        break
            finally:
                if bar is not None:
                    bar.close()
            return accumulated
