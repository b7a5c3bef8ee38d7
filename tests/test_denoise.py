"""pw.denoise: OIDN through pyoidn, against analytic images (a flat field, an edge)."""

import builtins

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp.errors import InputError, InputTypeError

pytest.importorskip("pyoidn")


def noisy_frame(truth, sigma, albedo=None, normal=None, seed=0):
    """A frame whose radiance is ``truth`` plus Gaussian noise of standard deviation ``sigma``
    (clipped at 0, as radiance is), with the given guides."""
    rng = np.random.default_rng(seed)
    rgb = np.maximum(truth + rng.normal(0.0, sigma, truth.shape), 0.0).astype(np.float32)
    h, w = truth.shape[:2]
    return pw.Frame(rgb=rgb, depth=np.ones((h, w), np.float32), normal=normal, alpha=np.ones((h, w), np.float32),
                    albedo=albedo)


def rms(a, b):
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2)))


def test_flat_field_noise_is_removed():
    """A uniform field of radiance 0.5 with noise of 0.1: the denoised image is within a fifth of
    the noise of the truth, and keeps its mean (no darkening or brightening)."""
    truth = np.full((64, 96, 3), 0.5)
    frame = noisy_frame(truth, 0.1)
    out = pw.denoise(frame)
    assert rms(frame.rgb, truth) > 0.09
    assert rms(out.rgb, truth) < 0.02
    assert abs(out.rgb.mean() - 0.5) < 0.01


def test_guides_keep_an_edge_the_colour_alone_would_blur():
    """Radiance 0.2 | 0.8 across a vertical edge that the albedo and normal guides also show:
    guided, the denoised edge stays sharp (the columns beside it keep their values)."""
    h, w = 48, 64
    truth = np.full((h, w, 3), 0.2)
    truth[:, w // 2:] = 0.8
    albedo = (truth / 0.8).astype(np.float32)
    normal = np.zeros((h, w, 3), np.float32)
    normal[..., 2] = 1.0
    frame = noisy_frame(truth, 0.15, albedo=albedo, normal=normal)
    guided = pw.denoise(frame)
    unguided = pw.denoise(frame, guides=False)
    near = slice(w // 2 - 2, w // 2 + 2)
    assert rms(guided.rgb[:, near], truth[:, near]) < 0.05
    assert rms(guided.rgb, truth) <= rms(unguided.rgb, truth) + 1e-3
    assert rms(guided.rgb, truth) < 0.25 * rms(frame.rgb, truth)


def test_other_outputs_and_the_input_are_kept():
    truth = np.full((16, 16, 3), 1.0)
    frame = noisy_frame(truth, 0.05)
    before = frame.rgb.copy()
    out = pw.denoise(frame, quality="fast")
    assert out is not frame and out.depth is frame.depth and out.alpha is frame.alpha
    np.testing.assert_array_equal(frame.rgb, before)
    assert out.rgb.dtype == np.float32 and out.rgb.shape == frame.rgb.shape
    assert np.all(np.isfinite(out.rgb)) and out.rgb.min() >= 0.0


def test_bad_input_gets_a_clear_error():
    frame = noisy_frame(np.full((8, 8, 3), 0.5), 0.05)
    with pytest.raises(InputTypeError, match="Frame"):
        pw.denoise(frame.rgb)
    with pytest.raises(InputError, match="quality"):
        pw.denoise(frame, quality="best")
    frame.rgb[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="finite"):
        pw.denoise(frame)


def test_missing_binding_names_the_extra(monkeypatch):
    real_import = builtins.__import__

    def no_pyoidn(name, *args, **kwargs):
        if name == "pyoidn":
            raise ImportError("No module named 'pyoidn'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pyoidn)
    with pytest.raises(ImportError, match=r"pbrwarp\[denoise\]"):
        pw.denoise(noisy_frame(np.full((8, 8, 3), 0.5), 0.05))
