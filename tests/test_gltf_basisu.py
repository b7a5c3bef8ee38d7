"""KHR_texture_basisu (pbrwarp/gltf_basisu.py): KTX2 images decode to their texels, their headers
are checked against LoadLimits before decoding, hostile bytes are refused without harm to the
process, and without opengl-basisu the warning or error names KTX2 and the install command.

The KTX2 files are tests/assets/ktx2's gradients (SOURCES.md): texel (x, y) holds
(16x, 32y, 128, 255 - 8x), sRGB-encoded, row 0 at the top.
"""

from __future__ import annotations

import io
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import pbrwarp as pw
from pbrwarp.errors import AssetFormatError
from pbrwarp.gltf_basisu import EXTENSION, INSTALL

from assets import IN_REPO
from test_gltf import Builder
from test_hostile_files import damaged_copies, load_each_in_child

pytest.importorskip("opengl_basisu")

KTX2 = IN_REPO / "ktx2"
WIDTH, HEIGHT = 16, 8
FALLBACK_RGB = (10, 200, 30)


def gradient() -> np.ndarray:
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH]
    return np.stack([16 * x, 32 * y, np.full_like(x, 128), 255 - 8 * x], axis=-1)


def block_means(rgba) -> np.ndarray:
    """Means over the 4 x 4 blocks Basis Universal codes together."""
    return np.asarray(rgba, np.float64).reshape(HEIGHT // 4, 4, WIDTH // 4, 4, 4).mean(axis=(1, 3))


def textured_quad(path: Path, ktx2: bytes, fallback=True, required=False) -> Path:
    """A quad whose base colour texture has a KTX2 image (KHR_texture_basisu) and, with
    ``fallback``, a uniform PNG as its core source."""
    b = Builder()
    b.json["images"] = [{"bufferView": b.view(ktx2), "mimeType": "image/ktx2"}]
    texture = {"extensions": {EXTENSION: {"source": 0}}}
    if fallback:
        png = io.BytesIO()
        Image.new("RGB", (4, 4), FALLBACK_RGB).save(png, format="PNG")
        b.json["images"].append({"bufferView": b.view(png.getvalue()), "mimeType": "image/png"})
        texture["source"] = 1
    b.json["textures"] = [texture]
    b.json["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    b.node(mesh=b.quad(material=0))
    b.json["extensionsUsed"] = [EXTENSION]
    if required:
        b.json["extensionsRequired"] = [EXTENSION]
    return b.glb(path)


def base_color_texels(path: Path, **kwargs) -> np.ndarray:
    return pw.Scene.load(path, **kwargs).primitives[0].material.base_color_texture.rgba8.astype(np.int64)


# ---------------------------------------------------------------------------- decoding
@pytest.mark.parametrize("required", [False, True])
def test_uastc_image_decodes_to_its_texels_in_preference_to_the_fallback(tmp_path, required):
    """UASTC is near-lossless: every texel within 4 levels of the gradient, rows top first, the
    16 x 8 image not transposed. The PNG fallback (a uniform colour) is not what loads."""
    raw = (KTX2 / "gradient_uastc.ktx2").read_bytes()
    path = textured_quad(tmp_path / "uastc.glb", raw, fallback=not required, required=required)
    scene = pw.Scene.load(path)
    assert scene.load_warnings == ()
    texels = scene.primitives[0].material.base_color_texture.rgba8.astype(np.int64)
    assert texels.shape == (HEIGHT, WIDTH, 4)
    assert np.abs(texels - gradient()).max() <= 4


def test_etc1s_image_decodes_to_its_block_colours(tmp_path):
    """ETC1S (BasisLZ-supercompressed) keeps one colour pair per 4 x 4 block: each block's mean
    within 8 levels of the gradient's."""
    raw = (KTX2 / "gradient_etc1s.ktx2").read_bytes()
    texels = base_color_texels(textured_quad(tmp_path / "etc1s.glb", raw))
    assert texels.shape == (HEIGHT, WIDTH, 4)
    assert np.abs(block_means(texels) - block_means(gradient())).max() <= 8


# ---------------------------------------------------------------------------- limits and headers
def forged(field: int, value: int) -> bytes:
    """The UASTC file with header field ``field`` (0 vkFormat, 2 width, 3 height, 4 depth, 5
    layers, 6 faces, 7 levels) set to ``value``."""
    raw = bytearray((KTX2 / "gradient_uastc.ktx2").read_bytes())
    struct.pack_into("<I", raw, 12 + 4 * field, value)
    return bytes(raw)


def test_texture_side_and_texel_limits_apply_from_the_header(tmp_path):
    path = textured_quad(tmp_path / "t.glb", (KTX2 / "gradient_uastc.ktx2").read_bytes())
    with pytest.raises(AssetFormatError, match=r"t.glb: image 0 is 16 x 8 texels, outside 1..15 texels a side "
                                               r"\(LoadLimits.max_texture_side\)"):
        pw.Scene.load(path, limits=pw.LoadLimits(max_texture_side=15))
    with pytest.raises(AssetFormatError, match=r"image 0 \(16 x 8\) would bring .* 128, more than the 127 of "
                                               r"LoadLimits.max_texels"):
        pw.Scene.load(path, limits=pw.LoadLimits(max_texels=127))


@pytest.mark.parametrize("raw, message", [
    (forged(2, 1 << 20), "is 1048576 x 8 texels, outside 1..8192"),
    (forged(3, 0), "is 16 x 0 texels"),
    (forged(0, 37), "vkFormat 37"),
    (forged(6, 6), "6 faces"),
    (forged(5, 4), "4 layers"),
    (forged(7, 40), "declares 40 mip levels, more than a 16 x 8 image has"),
    (forged(2, 32), "cannot be decoded|the decoder reads"),
    ((KTX2 / "gradient_uastc.ktx2").read_bytes()[:60], "truncated KTX2 file"),
], ids=["huge_width", "zero_height", "vk_format", "cube", "array", "levels", "wrong_width", "truncated"])
def test_forged_headers_are_refused(tmp_path, raw, message):
    with pytest.raises(AssetFormatError, match=f"h.glb: image 0 .*({message})"):
        pw.Scene.load(textured_quad(tmp_path / "h.glb", raw))



def test_truncated_and_random_ktx2_bytes_are_refused_without_crashing(tmp_path):
    """Truncations, flipped bytes and random payloads after a valid header, for both codecs:
    each loads or is refused with an AssetFormatError, in a child process that must exit
    normally (a crash in the transcoder would kill it) under an address-space limit."""
    rng = np.random.default_rng(30)
    paths = []
    for name in ("gradient_uastc.ktx2", "gradient_etc1s.ktx2"):
        raw = (KTX2 / name).read_bytes()
        for variant in damaged_copies(raw, rng, header=80, copies=25):
            paths.append(textured_quad(tmp_path / f"hostile{len(paths)}.glb", variant, fallback=False))
    outcomes = load_each_in_child(paths)
    assert outcomes[str(paths[0])] == "refused"  # the empty image


# ---------------------------------------------------------------------------- without opengl-basisu
@pytest.fixture
def no_decoder(monkeypatch):
    """Import of opengl_basisu fails, as where the ktx2 extra is not installed."""
    monkeypatch.setitem(sys.modules, "opengl_basisu", None)


def test_without_the_decoder_the_fallback_is_used_with_a_warning(tmp_path, no_decoder):
    path = textured_quad(tmp_path / "f.glb", (KTX2 / "gradient_uastc.ktx2").read_bytes())
    with pytest.warns(UserWarning, match=rf"{EXTENSION} on texture 0 not decoded: opengl-basisu is not installed"):
        scene = pw.Scene.load(path)
    assert len(scene.load_warnings) == 1 and INSTALL in scene.load_warnings[0]
    texels = scene.primitives[0].material.base_color_texture.rgba8
    assert texels.shape == (4, 4, 4) and tuple(texels[0, 0, :3]) == FALLBACK_RGB


def test_without_the_decoder_a_ktx2_only_texture_names_the_format_and_the_command(tmp_path, no_decoder):
    path = textured_quad(tmp_path / "k.glb", (KTX2 / "gradient_uastc.ktx2").read_bytes(), fallback=False,
                         required=True)
    escaped = INSTALL.replace("[", r"\[").replace("]", r"\]")
    with pytest.raises(AssetFormatError, match=rf"k.glb: material 0 baseColorTexture: texture 0 has only a KTX2 image "
                                               rf"\({EXTENSION}, Basis Universal\) and no PNG or JPEG fallback; "
                                               rf"decoding KTX2 needs opengl-basisu: {escaped}"):
        pw.Scene.load(path)
