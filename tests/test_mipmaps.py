"""Mip pyramids: the box filter against a float64 reference written from its definition."""

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp import textures


def reference_downsample(img: np.ndarray) -> np.ndarray:
    """The box filter by definition: the source as a piecewise-constant function, refined m
    times per texel (exact), then each output texel the mean of its n / m-texel box."""
    h, w = img.shape[:2]
    mh, mw = max(1, h // 2), max(1, w // 2)
    fine = np.repeat(np.repeat(img.astype(np.float64), mh, axis=0), mw, axis=1)  # (h*mh, w*mw)
    return fine.reshape(mh, h, mw, w, -1).mean(axis=(1, 3))


@pytest.mark.parametrize("shape", [(8, 8), (7, 5), (1, 9), (6, 1), (3, 3), (16, 4), (1, 1)])
def test_chain_matches_reference_and_keeps_the_mean(shape):
    rng = np.random.default_rng(sum(shape))
    img = rng.random(shape + (4,))
    chain = textures.mip_chain(img)
    assert len(chain) == 1 + int(np.floor(np.log2(max(shape))))
    assert chain[-1].shape[:2] == (1, 1)
    for parent, child in zip(chain, chain[1:]):
        assert child.shape[:2] == (max(1, parent.shape[0] // 2), max(1, parent.shape[1] // 2))
        np.testing.assert_allclose(child, reference_downsample(parent), rtol=0, atol=1e-12)
        np.testing.assert_allclose(child.mean(axis=(0, 1)), img.mean(axis=(0, 1)), rtol=0, atol=1e-12)


def test_even_sides_average_2x2_blocks():
    img = np.arange(4 * 6 * 4, dtype=np.float64).reshape(4, 6, 4)
    blocks = img.reshape(2, 2, 3, 2, 4).mean(axis=(1, 3))
    np.testing.assert_allclose(textures.box_downsample(img), blocks, rtol=0, atol=1e-12)


def test_memory_grows_by_at_most_a_third():
    chain = textures.mip_chain(np.zeros((256, 256, 4)))
    extra = sum(level.shape[0] * level.shape[1] for level in chain[1:])
    assert extra <= 256 * 256 / 3


@pytest.mark.parametrize("srgb", [True, False])
def test_8bit_levels_average_linear_values(srgb):
    """A level of an 8-bit texture, decoded as the kernels decode it, has the mean of the linear
    level-0 texels (to the 8-bit rounding), not the mean of the encoded bytes."""
    rng = np.random.default_rng(3)
    # a black/white checker: the linear mean is 0.5 while the sRGB-byte mean would decode to ~0.21
    checker = (np.indices((32, 32)).sum(axis=0) % 2 * 255).astype(np.uint8)
    img = np.dstack([checker, checker, rng.integers(0, 256, (32, 32), dtype=np.uint8), checker])
    texture = pw.Texture(img)
    linear0 = texture.texels(srgb).astype(np.float64)
    levels = textures.mip_levels(texture, srgb)
    assert all(level.dtype == np.uint8 for level in levels)
    row = np.array([256, 256, 256, 0]) if srgb else 0
    for level in levels:
        decoded = textures.UNORM8_DECODE[level + row].astype(np.float64)
        # 8-bit rounding of a value near 0.5: at most half a step of the encoding's slope there
        np.testing.assert_allclose(decoded.mean(axis=(0, 1)), linear0.mean(axis=(0, 1)), atol=3e-3)
    if srgb:
        np.testing.assert_allclose(textures.UNORM8_DECODE[256 + levels[0][..., 0].astype(np.int64)], 0.5, atol=3e-3)


def test_float_levels_stay_float32():
    texture = pw.Texture(np.random.default_rng(1).random((5, 7, 4)).astype(np.float32))
    levels = textures.mip_levels(texture, srgb=False)
    assert [lv.shape[:2] for lv in levels] == [(2, 3), (1, 1)]
    assert all(lv.dtype == np.float32 for lv in levels)
    np.testing.assert_allclose(levels[-1][0, 0], texture.texels(False).mean(axis=(0, 1)), atol=1e-6)
