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


# --- the kernels' trilinear lookup and level selection against float64 references ---------

import warp as wp  # noqa: E402

from pbrwarp.kernels.textures import (TEXELS_FLOAT, WRAP_REPEAT, Texels, TextureData,  # noqa: E402
                                      mip_lod, sample_texture_lod, texel_store)
from test_kernels_misc import bilinear_reference  # noqa: E402


@wp.kernel(enable_backward=False)
def trilinear_at(tex: TextureData, texels: Texels, uv: wp.array(dtype=wp.vec2), lod: wp.array(dtype=float),
                 out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = sample_texture_lod(tex, texels, uv[i], lod[i])


@wp.kernel(enable_backward=False)
def lod_of(tex: TextureData, dx: wp.array(dtype=wp.vec2), dy: wp.array(dtype=wp.vec2), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = mip_lod(tex, dx[i], dy[i])


def mipped_row(chain, uv_matrix=((1, 0, 0), (0, 1, 0))):
    row = TextureData()
    row.offset, row.height, row.width = 0, chain[0].shape[0], chain[0].shape[1]
    row.wrap_s = row.wrap_t = WRAP_REPEAT
    row.texel_format = TEXELS_FLOAT
    row.levels = len(chain)
    row.mip_offset = row.height * row.width  # level 1 right after level 0
    row.uv_row0, row.uv_row1 = wp.vec3(*uv_matrix[0]), wp.vec3(*uv_matrix[1])
    return row, texel_store([level.reshape(-1, 4).astype(np.float32) for level in chain])


def trilinear_reference(chain, u, v, lod):
    level = np.clip(lod, 0, len(chain) - 1)
    l0 = np.floor(level).astype(int)
    l1 = np.minimum(l0 + 1, len(chain) - 1)
    t = (level - l0)[:, None]
    out = np.empty((len(u), 4))
    for i in range(len(u)):
        a = bilinear_reference(chain[l0[i]], u[i:i + 1], v[i:i + 1], 0)[0]
        b = bilinear_reference(chain[l1[i]], u[i:i + 1], v[i:i + 1], 0)[0]
        out[i] = a * (1 - t[i]) + b * t[i]
    return out


@pytest.mark.parametrize("shape", [(16, 16), (9, 6), (1, 8)])
def test_trilinear_lookup_matches_reference(shape):
    rng = np.random.default_rng(7)
    chain = [lv.astype(np.float32).astype(np.float64) for lv in textures.mip_chain(rng.random(shape + (4,)))]
    row, store = mipped_row(chain)
    n = 400
    uv = rng.uniform(-2, 3, (n, 2))
    lod = rng.uniform(-1, len(chain) + 1, n)
    lod[:4] = [0.0, len(chain) - 1, np.nan, 1e30]
    out = wp.zeros(n, dtype=wp.vec4)
    wp.launch(trilinear_at, dim=n, inputs=[row, store, wp.array(uv.astype(np.float32), dtype=wp.vec2),
                                           wp.array(lod.astype(np.float32), dtype=float), out])
    got = out.numpy()
    assert np.all(np.isfinite(got))
    lod_ref = np.where(np.isnan(lod), 0.0, lod)
    uv32 = uv.astype(np.float32).astype(np.float64)
    np.testing.assert_allclose(got, trilinear_reference(chain, uv32[:, 0], uv32[:, 1], lod_ref), atol=2e-5)


def test_lod_is_log2_of_the_footprint_in_texels():
    """N texels a pixel step -> level log2 N; magnification (a texel over k pixels) -> level 0,
    clamped to the pyramid; the texture transform's scale and rotation scale the footprint."""
    chain = textures.mip_chain(np.zeros((64, 64, 4)))  # 7 levels
    row, _ = mipped_row(chain)
    n_texels = np.array([1, 2, 4, 8, 3, 1 / 4, 64, 4096, 0])
    dx = np.stack([n_texels / 64, np.zeros_like(n_texels)], 1)
    dy = np.stack([np.zeros_like(n_texels), n_texels / 128], 1)  # the shorter side: x decides
    specials_dx = np.array([[np.nan, 0], [np.inf, 0], [0, 0]])
    dx = np.concatenate([dx, specials_dx])
    dy = np.concatenate([dy, np.zeros((3, 2))])
    out = wp.zeros(len(dx), dtype=float)
    wp.launch(lod_of, dim=len(dx), inputs=[row, wp.array(dx.astype(np.float32), dtype=wp.vec2),
                                           wp.array(dy.astype(np.float32), dtype=wp.vec2), out])
    got = out.numpy()
    expected = np.clip(np.log2(np.maximum(n_texels, 1)), 0, 6)
    np.testing.assert_allclose(got[:len(n_texels)], expected, atol=1e-5)
    np.testing.assert_array_equal(got[len(n_texels):], [6, 6, 0])
    # a uv scale of 4 (KHR_texture_transform) rotated by 30 degrees: the footprint grows 4 times
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    turned, _ = mipped_row(chain, ((4 * c, 4 * s, 0.3), (-4 * s, 4 * c, 0.1)))
    out = wp.zeros(1, dtype=float)
    wp.launch(lod_of, dim=1, inputs=[turned, wp.array([[1 / 64, 0]], dtype=wp.vec2),
                                     wp.array([[0, 0]], dtype=wp.vec2), out])
    assert out.numpy()[0] == pytest.approx(2.0, abs=1e-5)
