"""pw.Environment: loading .hdr and .exr, the uniform and sky constructors, and clear errors."""

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from pbrwarp.environment import Environment
from pbrwarp.errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError

from assets import hdr


def write_image(path, pixels):
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT))
    out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
    out.close()


def rgbe_pixel(value):
    """Radiance's RGBE encoding of one grey value (Ward 1991): mantissa byte and shared exponent."""
    mantissa, exponent = np.frexp(value)
    return bytes([int(mantissa * 256)] * 3 + [exponent + 128])


def test_load_radiance_hdr_decodes_rgbe(tmp_path):
    # a flat (non-RLE) 4 x 2 RGBE file written by hand, so the expected radiance is known exactly
    values = np.array([[0.5, 1.0, 2.0, 4.0], [8.0, 0.25, 0.75, 1.5]])
    body = b"".join(rgbe_pixel(v) for v in values.ravel())
    path = tmp_path / "tiny.hdr"
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n" + body)
    env = Environment.load(path, intensity=2.0, rotation=0.5)
    np.testing.assert_array_equal(env.texels, np.repeat(values[..., None], 3, axis=2).astype(np.float32))
    assert (env.width, env.height, env.intensity, env.rotation) == (4, 2, 2.0, 0.5)


def test_load_shared_hdr_and_exr_round_trip(tmp_path):
    env = Environment.load(hdr("venice_sunset"))
    height = env.texels.shape[0]  # 512 in the shared set, 128 in tests/assets
    assert height >= 128 and env.texels.shape == (height, 2 * height, 3) and env.texels.dtype == np.float32
    assert np.isfinite(env.texels).all() and env.texels.min() >= 0 and env.texels.max() > 100
    rgba = np.concatenate([env.texels[::8, ::8], np.ones((height // 8, height // 4, 1), np.float32)], axis=2)
    write_image(tmp_path / "env.exr", rgba)
    np.testing.assert_array_equal(Environment.load(tmp_path / "env.exr").texels, env.texels[::8, ::8])


def test_missing_file_folder_and_unsupported_extension():
    with pytest.raises(AssetNotFoundError, match="environment image not found"):
        Environment.load("/nonexistent/sky.hdr")
    with pytest.raises(AssetFormatError, match="folder"):
        Environment.load(hdr("venice_sunset").parent)
    with pytest.raises(AssetFormatError, match="unsupported extension '.png'"):
        Environment.load(Path(__file__).resolve().parents[1] / "bench" / "results" / "demo.png")


def test_non_hdr_content_truncated_and_wrong_aspect_files(tmp_path):
    from PIL import Image

    fake = tmp_path / "photo.hdr"
    Image.new("RGB", (20, 10)).save(tmp_path / "photo.png")
    fake.write_bytes((tmp_path / "photo.png").read_bytes())
    with pytest.raises(AssetFormatError, match="not a Radiance HDR or OpenEXR image"):
        Environment.load(fake)
    truncated = tmp_path / "cut.hdr"
    data = hdr("venice_sunset").read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(AssetFormatError, match="cannot read"):
        Environment.load(truncated)
    write_image(tmp_path / "square.exr", np.ones((16, 16, 3)))
    with pytest.raises(AssetFormatError, match="twice as wide as tall; got 16x16"):
        Environment.load(tmp_path / "square.exr")
    write_image(tmp_path / "negative.exr", -np.ones((4, 8, 3)))
    with pytest.raises(AssetFormatError, match="negative radiance"):
        Environment.load(tmp_path / "negative.exr")


def test_array_validation():
    with pytest.raises(InputError, match="twice as wide"):
        Environment(np.ones((4, 4, 3)))
    with pytest.raises(InputError, match=r"shape \(H, 2H, 3\)"):
        Environment(np.ones((4, 8)))
    bad = np.ones((4, 8, 3))
    bad[2, 5, 1] = np.nan
    with pytest.raises(InputError, match="row 2, column 5"):
        Environment(bad)
    with pytest.raises(InputError, match="beyond float32"):
        Environment(np.full((4, 8, 3), 1e39))
    with pytest.raises(InputTypeError):
        Environment("sky")
    env = Environment(np.ones((4, 8, 3)))
    with pytest.raises(InputError, match="intensity must be >= 0"):
        env.intensity = -1
    with pytest.raises(InputError, match="rotation must be finite"):
        env.rotation = float("inf")
    with pytest.raises(ValueError):
        env.texels[0, 0, 0] = 2.0  # read-only: derived data is computed once


def test_uniform_and_sky():
    np.testing.assert_array_equal(Environment.uniform(0.5).texels, 0.5)
    np.testing.assert_array_equal(Environment.uniform((1, 2, 3)).texels[1, 3], [1, 2, 3])
    with pytest.raises(InputError):
        Environment.uniform((1, -1, 0))
    sky = Environment.sky(zenith=(0, 0, 1), horizon=(1, 1, 1), ground=(0, 1, 0), height=64)
    assert sky.texels.shape == (64, 128, 3)
    # top row looks almost straight up, bottom row almost straight down, the middle at the horizon
    theta = np.pi * 0.5 / 64
    np.testing.assert_allclose(sky.texels[0, 0], [1 - np.cos(theta), 1 - np.cos(theta), 1], rtol=1e-6)
    np.testing.assert_allclose(sky.texels[-1, 0], [1 - np.cos(theta), 1, 1 - np.cos(theta)], rtol=1e-6)
    np.testing.assert_allclose(sky.texels[31:33].mean(axis=(0, 1)), 1.0, atol=0.03)
