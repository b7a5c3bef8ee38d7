"""Texture image formats: every PNG mode Pillow reads becomes the right linear RGBA texels.

PNGs are written with Pillow in each mode, read back, and decoded by
``pw.textures.image_to_float_rgba`` (as Pillow images and as the numpy arrays Pillow gives); the
expected floats are computed here from the pixel values that were written. Then a quad textured
with each is rendered head-on under a directional light of E lux: a white Lambert surface
(``specular=0``) has radiance (E / pi) * srgb_to_linear(texel), computed here in float64.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

import pbrwarp as pw
from pbrwarp import textures
from pbrwarp.textures import image_to_float_rgba

LUX = 3.0


def srgb_eotf(c):
    """IEC 61966-2-1 in float64, written out here rather than taken from pbrwarp."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def write_png(path, image: Image.Image, **save_args) -> Image.Image:
    """``image`` saved as a PNG and opened again (so the test sees what a file on disk gives)."""
    image.save(path, format="PNG", **save_args)
    reopened = Image.open(path)
    reopened.load()
    return reopened


def palette_image(indices, palette_rgb) -> Image.Image:
    img = Image.fromarray(np.asarray(indices, dtype=np.uint8), "P")
    flat = [int(v) for rgb in palette_rgb for v in rgb]
    img.putpalette(flat + [0] * (768 - len(flat)))
    return img


# ---------------------------------------------------------------------------- decoding to floats
RNG = np.random.default_rng(5)
RGB8 = RNG.integers(0, 256, (7, 3, 3), dtype=np.uint8)          # 3 wide, 7 high: not a power of two
RGBA8 = RNG.integers(0, 256, (5, 6, 4), dtype=np.uint8)
GREY8 = RNG.integers(0, 256, (4, 9), dtype=np.uint8)
LA8 = RNG.integers(0, 256, (3, 7, 2), dtype=np.uint8)
GREY16 = np.array([[0, 1, 40000], [65535, 32768, 255]], dtype=np.uint16)
PALETTE = [(255, 0, 0), (0, 128, 255), (17, 34, 51), (250, 250, 250)]
PAL_INDEX = RNG.integers(0, 4, (6, 5), dtype=np.uint8)


def expected_rgba(rgb, alpha=None):
    """(H, W, 4) float64 from (H, W, 3) colour in [0, 1] and an optional (H, W) alpha."""
    rgb = np.asarray(rgb, dtype=np.float64)
    out = np.ones(rgb.shape[:2] + (4,))
    out[..., :3] = rgb
    if alpha is not None:
        out[..., 3] = alpha
    return out


def grey(values, scale):
    v = np.asarray(values, dtype=np.float64) / scale
    return np.repeat(v[..., None], 3, axis=-1)


CASES = {
    # name: (Pillow image to write, save options, expected float RGBA from the written pixels)
    "rgb8": (lambda: Image.fromarray(RGB8, "RGB"), {}, lambda: expected_rgba(RGB8 / 255.0)),
    "rgba8": (lambda: Image.fromarray(RGBA8, "RGBA"), {},
              lambda: expected_rgba(RGBA8[..., :3] / 255.0, RGBA8[..., 3] / 255.0)),
    "grey8": (lambda: Image.fromarray(GREY8, "L"), {}, lambda: expected_rgba(grey(GREY8, 255.0))),
    "grey-alpha8": (lambda: Image.fromarray(LA8, "LA"), {},
                    lambda: expected_rgba(grey(LA8[..., 0], 255.0), LA8[..., 1] / 255.0)),
    "palette": (lambda: palette_image(PAL_INDEX, PALETTE), {},
                lambda: expected_rgba(np.array(PALETTE)[PAL_INDEX] / 255.0)),
    # tRNS with one alpha per palette entry: entry 1 fully transparent, entry 2 half
    "palette-transparency": (lambda: palette_image(PAL_INDEX, PALETTE), {"transparency": bytes([255, 0, 128, 255])},
                             lambda: expected_rgba(np.array(PALETTE)[PAL_INDEX] / 255.0,
                                                   np.array([255, 0, 128, 255])[PAL_INDEX] / 255.0)),
    "grey16": (lambda: Image.fromarray(GREY16), {}, lambda: expected_rgba(grey(GREY16, 65535.0))),
    "one-pixel-rgb": (lambda: Image.fromarray(np.array([[[200, 10, 90]]], np.uint8), "RGB"), {},
                      lambda: expected_rgba(np.array([[[200, 10, 90]]]) / 255.0)),
    "one-pixel-grey16": (lambda: Image.fromarray(np.array([[40000]], np.uint16)), {},
                         lambda: expected_rgba(grey([[40000]], 65535.0))),
    # tRNS colour keys on greyscale and RGB PNGs: pixels of the key colour are transparent
    "grey8-transparency": (lambda: Image.fromarray(GREY8, "L"), {"transparency": int(GREY8[1, 2])},
                           lambda: expected_rgba(grey(GREY8, 255.0), (GREY8 != GREY8[1, 2]).astype(float))),
    "rgb8-transparency": (lambda: Image.fromarray(RGB8, "RGB"), {"transparency": tuple(int(c) for c in RGB8[3, 1])},
                          lambda: expected_rgba(RGB8 / 255.0, np.any(RGB8 != RGB8[3, 1], axis=-1).astype(float))),
}


@pytest.mark.parametrize("name", CASES)
def test_png_modes_decode_to_the_written_values(tmp_path, name):
    make, save_args, expected = CASES[name]
    img = write_png(tmp_path / f"{name}.png", make(), **save_args)
    rgba = image_to_float_rgba(img)
    assert rgba.dtype == np.float32 and rgba.shape == expected().shape
    np.testing.assert_allclose(rgba, expected(), rtol=0, atol=1e-7)  # float32 rounding of v / 255


def test_sixteen_bit_value_is_divided_by_65535(tmp_path):
    img = write_png(tmp_path / "grey16.png", Image.fromarray(np.full((3, 2), 40000, np.uint16)))
    assert img.mode.startswith("I")  # Pillow keeps all 16 bits (I;16 or I), not an 8-bit L
    assert image_to_float_rgba(img)[0, 0, 0] == np.float32(40000 / 65535)


@pytest.mark.parametrize("array, expected", [
    (RGB8, lambda: expected_rgba(RGB8 / 255.0)),
    (RGBA8, lambda: expected_rgba(RGBA8[..., :3] / 255.0, RGBA8[..., 3] / 255.0)),
    (GREY8, lambda: expected_rgba(grey(GREY8, 255.0))),
    (GREY8[..., None], lambda: expected_rgba(grey(GREY8, 255.0))),
    (LA8, lambda: expected_rgba(grey(LA8[..., 0], 255.0), LA8[..., 1] / 255.0)),
    (GREY16, lambda: expected_rgba(grey(GREY16, 65535.0))),
    (np.dstack([GREY16] * 3), lambda: expected_rgba(grey(GREY16, 65535.0))),
    (RGB8 / 255.0, lambda: expected_rgba(RGB8 / 255.0)),
    (np.array([[[0.25, 0.5, 0.75]]], np.float32), lambda: expected_rgba([[[0.25, 0.5, 0.75]]])),
], ids=["rgb8", "rgba8", "grey8", "grey8-1ch", "la8", "grey16", "rgb16", "float64", "float32-1px"])
def test_numpy_arrays_decode_to_their_values(array, expected):
    np.testing.assert_allclose(image_to_float_rgba(array), expected(), rtol=0, atol=1e-7)


def test_pillow_arrays_match_pillow_images(tmp_path):
    """The raw numpy path (np.asarray of the opened PNG) gives what the Pillow image gives."""
    for name in ("rgb8", "rgba8", "grey8", "grey-alpha8", "grey16", "one-pixel-rgb"):
        make, save_args, expected = CASES[name]
        img = write_png(tmp_path / f"{name}.png", make(), **save_args)
        np.testing.assert_allclose(image_to_float_rgba(np.asarray(img)), image_to_float_rgba(img), rtol=0, atol=0)


def test_rows_are_image_rows():
    """Row 0 of the array is the top row of the image, column 0 its left column."""
    img = Image.new("RGB", (3, 7))
    img.putpixel((2, 0), (255, 0, 0))   # top right
    img.putpixel((0, 6), (0, 255, 0))   # bottom left
    rgba = image_to_float_rgba(img)
    assert rgba.shape == (7, 3, 4)
    assert tuple(rgba[0, 2, :3]) == (1, 0, 0) and tuple(rgba[6, 0, :3]) == (0, 1, 0)


@pytest.mark.parametrize("mode, pixel, expected", [
    ("PA", None, None),                               # palette + alpha: the palette colour, not the index
    ("RGBX", (10, 20, 30, 0), (10, 20, 30, 255)),     # X is padding, not alpha
    ("RGBa", (50, 100, 0, 128), (99, 199, 0, 128)),   # premultiplied: un-premultiplied by Pillow
    ("La", (64, 128), (127, 128)),
    ("1", 1, (255, 255, 255, 255)),
    ("CMYK", (0, 255, 0, 0), (255, 0, 255, 255)),
])
def test_other_pillow_modes(mode, pixel, expected):
    if mode == "PA":
        img = palette_image([[0, 1]], [(255, 0, 0), (0, 0, 255)]).convert("PA")
        img.putpixel((1, 0), (1, 100))
        want = np.array([[[1, 0, 0, 1], [0, 0, 1, 100 / 255]]])
    else:
        img = Image.new(mode, (1, 1), pixel)
        want = np.asarray(expected, dtype=np.float64)[None, None] / 255.0
        if want.shape[-1] == 2:
            want = expected_rgba(grey(np.array([[expected[0]]]), 255.0), expected[1] / 255.0)
    np.testing.assert_allclose(image_to_float_rgba(img), want, rtol=0, atol=1e-7)


# ---------------------------------------------------------------------------- rendered
def textured_quad(material, uvs=None, size=2.0):
    """A square in z = 0 facing +z; glTF UVs, (0, 0) at its top-left corner (-x, +y)."""
    h = size / 2.0
    positions = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], dtype=np.float64)
    if uvs is None:
        uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], dtype=np.float64)
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    return pw.Primitive(positions, np.array([[0, 1, 2], [0, 2, 3]]), material, normals, uvs)


def white_lambert(**textures):
    return pw.Material(base_color=(1, 1, 1), roughness=1, specular=0, **textures)


def render_head_on(material, uvs=None, size=9, brdf=None):
    """The quad filling the view, lit head-on by LUX lux; spp = 1 so pixel centres are sampled."""
    scene = pw.Scene()
    scene.add_mesh(textured_quad(material, uvs, size=4.0))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=LUX))
    cam = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), up=(0, 1, 0), fov_y=30.0)
    frame = pw.render(scene, cam, width=size, height=size, spp=1, progress=False, brdf=brdf)
    report = pw.check(frame)
    assert report.ok, report
    assert frame.alpha.min() == 1.0
    return frame


UNIFORM = {
    # name: (image written to PNG, its uniform texel as written, the full-scale value of its type)
    "rgb8": (lambda: Image.fromarray(np.full((4, 4, 3), (200, 90, 30), np.uint8), "RGB"), (200, 90, 30), 255.0),
    "rgba8": (lambda: Image.fromarray(np.full((2, 8, 4), (10, 250, 128, 77), np.uint8), "RGBA"), (10, 250, 128), 255.0),
    "grey8": (lambda: Image.fromarray(np.full((3, 5), 173, np.uint8), "L"), (173, 173, 173), 255.0),
    "grey-alpha8": (lambda: Image.fromarray(np.full((5, 3, 2), (61, 200), np.uint8), "LA"), (61, 61, 61), 255.0),
    "palette": (lambda: palette_image(np.full((4, 4), 1), PALETTE), PALETTE[1], 255.0),
    "palette-transparency": (lambda: palette_image(np.full((4, 4), 2), PALETTE), PALETTE[2], 255.0),
    "grey16": (lambda: Image.fromarray(np.full((6, 6), 40000, np.uint16)), (40000,) * 3, 65535.0),
    "one-pixel": (lambda: Image.fromarray(np.array([[[120, 220, 5]]], np.uint8), "RGB"), (120, 220, 5), 255.0),
    "three-by-seven": (lambda: Image.fromarray(np.full((7, 3, 3), (33, 66, 99), np.uint8), "RGB"), (33, 66, 99), 255.0),
}


@pytest.mark.parametrize("source", ["pillow", "numpy"])
@pytest.mark.parametrize("name", UNIFORM)
def test_uniform_texture_radiance_is_e_over_pi_times_decoded_texel(tmp_path, name, source):
    make, texel, scale = UNIFORM[name]
    save_args = {"transparency": bytes([255, 0, 128, 255])} if name == "palette-transparency" else {}
    img = write_png(tmp_path / f"{name}.png", make(), **save_args)
    texture = img if source == "pillow" else np.asarray(img.convert("RGBA") if img.mode == "P" else img)
    frame = render_head_on(white_lambert(base_color_texture=texture))
    expected = LUX / math.pi * srgb_eotf(np.asarray(texel, dtype=np.float64) / scale)
    np.testing.assert_allclose(frame.rgb[4, 4], expected, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(frame.rgb, np.broadcast_to(expected, frame.rgb.shape), rtol=1e-4, atol=1e-7)


def test_texture_top_left_lands_on_the_quads_top_left(tmp_path):
    """glTF UVs: (0, 0) is the image's first row and column, on the quad's top-left corner."""
    quadrants = np.zeros((64, 64, 3), np.uint8)
    colours = {(0, 0): (255, 0, 0), (0, 1): (0, 255, 0), (1, 0): (0, 0, 255), (1, 1): (255, 255, 0)}
    for (row, col), rgb in colours.items():
        quadrants[row * 32:(row + 1) * 32, col * 32:(col + 1) * 32] = rgb
    img = write_png(tmp_path / "quadrants.png", Image.fromarray(quadrants, "RGB"))
    scene = pw.Scene()
    scene.add_mesh(textured_quad(white_lambert(base_color_texture=img), size=2.0))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=LUX))
    # 2 tan(15 deg) * 3 = 1.6 < 2: the quad fills the view
    frame = pw.render(scene, pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=30.0),
                      width=16, height=16, progress=False)
    assert pw.check(frame).ok
    for (row, col), rgb in colours.items():
        pixel = frame.rgb[3 + row * 10, 3 + col * 10]
        np.testing.assert_allclose(pixel, LUX / math.pi * srgb_eotf(np.array(rgb) / 255.0), rtol=1e-4, atol=1e-7)


@pytest.mark.parametrize("uv", [1e6, -1e6, 1e6 + 0.5, -123456.25])
def test_huge_repeating_uvs_sample_the_uniform_colour(uv):
    texture = np.full((4, 4, 3), (40, 160, 220), np.uint8)
    uvs = np.array([[uv, uv + 1], [uv + 1, uv + 1], [uv + 1, uv], [uv, uv]])
    frame = render_head_on(white_lambert(base_color_texture=pw.Texture(texture, wrap_s="repeat", wrap_t="repeat")),
                           uvs=uvs)
    expected = LUX / math.pi * srgb_eotf(np.array([40, 160, 220]) / 255.0)
    np.testing.assert_allclose(frame.rgb, np.broadcast_to(expected, frame.rgb.shape), rtol=1e-4, atol=1e-7)


def test_uvs_spanning_minus_to_plus_a_million_sample_the_uniform_colour():
    texture = np.full((3, 7, 3), (90, 30, 200), np.uint8)
    uvs = np.array([[-1e6, 1e6], [1e6, 1e6], [1e6, -1e6], [-1e6, -1e6]])
    frame = render_head_on(white_lambert(base_color_texture=texture), uvs=uvs)
    expected = LUX / math.pi * srgb_eotf(np.array([90, 30, 200]) / 255.0)
    np.testing.assert_allclose(frame.rgb, np.broadcast_to(expected, frame.rgb.shape), rtol=1e-4, atol=1e-7)


# ---------------------------------------------------------------------------- texels in memory
def uploaded_texels(material):
    from pbrwarp.gpu_scene import upload

    scene = pw.Scene()
    scene.add_mesh(textured_quad(material))
    return upload(scene).data


def test_8bit_images_stay_8bit_once_however_many_slots_use_them():
    """Stored as uploaded: 4 bytes a texel, level 0 once for an sRGB slot and a linear slot alike
    (the kernel decodes each as its slot asks); each slot's mip levels past it follow (8-bit too,
    averaged in linear space as the slot decodes them)."""
    from pbrwarp.kernels.textures import TEXELS_SRGB8, TEXELS_UNORM8

    texture = pw.Texture(RNG.integers(0, 256, (64, 32, 3), dtype=np.uint8))
    assert texture.rgba8.dtype == np.uint8 and texture.rgba8.shape == (64, 32, 4)
    data = uploaded_texels(white_lambert(base_color_texture=texture, occlusion_texture=texture))
    rows = data.textures.numpy()
    assert sorted(rows["texel_format"].tolist()) == [TEXELS_UNORM8, TEXELS_SRGB8]
    assert rows["offset"].tolist() == [0, 0]
    levels = 32 * 16 + 16 * 8 + 8 * 4 + 4 * 2 + 2 * 1 + 1 * 1  # 64 x 32 halved down to 1 x 1
    assert data.texels.unorm8.shape == (64 * 32 + 2 * levels,) and data.texels.floats.shape == (1,)  # one unused float texel
    np.testing.assert_array_equal(data.texels.unorm8.numpy()[:64 * 32], texture.rgba8.reshape(-1, 4))
    assert sorted(rows["mip_offset"].tolist()) == [64 * 32, 64 * 32 + levels]


def test_16bit_and_float_images_keep_linear_float_texels():
    for image in (GREY16, np.full((3, 5, 3), 0.25, np.float32)):
        texture = pw.Texture(image)
        assert texture.rgba8 is None
        data = uploaded_texels(white_lambert(base_color_texture=texture))
        h, w = texture.shape
        assert data.texels.floats.shape == (textures.mip_texel_count(h, w)[1],) and data.texels.unorm8.shape == (1,)
        np.testing.assert_array_equal(data.texels.floats.numpy()[:h * w], texture.texels(True).reshape(-1, 4))


def test_read_only_rgba_images_are_kept_without_a_copy():
    """What the glTF loader hands over: its decoded images, made read-only."""
    for dtype in (np.uint8, np.float32):
        image = np.zeros((4, 4, 4), dtype)
        image.flags.writeable = False
        assert pw.Texture(image).image is image and np.shares_memory(pw.Texture(image)._rgba, image)
        writable = np.zeros((4, 4, 4), dtype)
        assert not np.shares_memory(pw.Texture(writable)._rgba, writable)


# ---------------------------------------------------------------------------- colour vs data textures
def test_colour_slots_decode_srgb_and_data_slots_do_not():
    image = np.full((2, 2, 3), 128, np.uint8)
    material = pw.Material(base_color_texture=image, metallic_roughness_texture=image, normal_texture=image,
                           occlusion_texture=image, emissive_texture=image)
    decoded = {slot: tex.texels(srgb)[0, 0, :3] for slot, tex, srgb in material.textures()}
    colour, data = srgb_eotf(128 / 255), 128 / 255
    for slot in ("base_color_texture", "emissive_texture"):
        np.testing.assert_allclose(decoded[slot], colour, rtol=1e-6)
    for slot in ("metallic_roughness_texture", "normal_texture", "occlusion_texture"):
        np.testing.assert_allclose(decoded[slot], data, rtol=1e-6)


def head_on_radiance(metallic, roughness=1.0, specular=0.0):
    """Radiance / E of a white surface seen and lit head-on (n = v = l = h), from the BRDF of
    Karis 2013 (rendered with its f0 mix and coupling="fresnel", where metallic darkens the diffuse
    lobe twice, which separates the two decodings best): f0 = mix(0.04 specular, 1, m), F = f0 at v.h = 1; diffuse (1 - F)(1 - m) / pi;
    GGX D = 1 / (pi alpha^2) at n.h = 1 with alpha = roughness^2; Smith G = 1 at n.v = n.l = 1."""
    f0 = 0.04 * specular * (1 - metallic) + metallic
    alpha2 = max(roughness**4, 1e-7)
    return (1 - f0) * (1 - metallic) / math.pi + f0 / (4 * math.pi * alpha2)


def test_metallic_roughness_texture_is_read_linear_in_the_render():
    """B = 128 in a metallic-roughness texture means metallic 128/255 = 0.502, not the sRGB
    decoding 0.216: the head-on radiance tells the two apart by almost a factor 2."""
    texture = np.zeros((4, 4, 3), np.uint8)
    texture[..., 1] = 255  # roughness 1
    texture[..., 2] = 128  # metallic
    material = pw.Material(base_color=(1, 1, 1), metallic=1.0, roughness=1.0, specular=0.0,
                           metallic_roughness_texture=texture)
    frame = render_head_on(material, brdf=pw.BRDF(coupling="fresnel", metallic_mix="f0"))
    linear, srgb = head_on_radiance(128 / 255), head_on_radiance(float(srgb_eotf(128 / 255)))
    assert abs(linear - srgb) > 0.5 * linear
    np.testing.assert_allclose(frame.rgb[4, 4], LUX * linear, rtol=1e-4)


def test_same_image_as_colour_and_as_data_renders_differently():
    """One grey image as the base colour texture, decoded from sRGB by default and taken as linear
    values when the Texture says ``srgb=False``."""
    image = np.full((4, 4, 3), 128, np.uint8)
    as_colour = render_head_on(white_lambert(base_color_texture=image)).rgb[4, 4]
    as_linear = render_head_on(white_lambert(base_color_texture=pw.Texture(image, srgb=False))).rgb[4, 4]
    np.testing.assert_allclose(as_colour, LUX / math.pi * srgb_eotf(128 / 255), rtol=1e-4)
    np.testing.assert_allclose(as_linear, LUX / math.pi * 128 / 255, rtol=1e-4)
