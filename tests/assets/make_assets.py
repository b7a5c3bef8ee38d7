"""Rebuild the test assets in this folder from the shared asset set (SOURCES.md says what each is).

    python tests/assets/make_assets.py ../shared/assets

Copies the small files unchanged (among them the small Khronos test boards of ``gltf-ext/``, whole:
model, README and licence); re-encodes the textures of the four models whose 1024² and 2048²
maps make up nearly all of their size at a smaller side (an area average: Pillow's box filter),
leaving their geometry, tangents, materials and samplers byte for byte; and shrinks three 1024 x 512
HDR environments to 256 x 128 (one to 512 x 256) by solid-angle-weighted 2 x 2 averages
(``pbrwarp.kernels.equirect.downsample``, which keeps each image's integral over the sphere),
written as Radiance RGBE with OpenImageIO. The decimated bunny that ``pbrwarp.meshes.bunny()``
loads lives in ``meshes/`` (the installed package), not here.
"""

from __future__ import annotations

import io
import json
import shutil
import struct
import sys
from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent

COPIED = [
    "gltf/LICENSES/CC-BY-4.0.txt", "gltf/LICENSES/CC0-1.0.txt", "gltf/LICENSES/LicenseRef-CC-BY-TM.txt",
    "gltf/LICENSES/SCEA.txt",
    "gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
    "gltf/Duck/glTF-Binary/Duck.glb",
    "gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
    "gltf/NegativeScaleTest/glTF-Binary/NegativeScaleTest.glb",
    "gltf/OrientationTest/glTF-Binary/OrientationTest.glb",
    "gltf/TextureCoordinateTest/glTF-Binary/TextureCoordinateTest.glb",
    "gltf/TextureEncodingTest/glTF-Binary/TextureEncodingTest.glb",
    "gltf/TextureSettingsTest/glTF-Binary/TextureSettingsTest.glb",
    "gltf/TwoSidedPlane/glTF/TwoSidedPlane.gltf", "gltf/TwoSidedPlane/glTF/TwoSidedPlane.bin",
    "gltf/TwoSidedPlane/glTF/TwoSidedPlane_BaseColor.png", "gltf/TwoSidedPlane/glTF/TwoSidedPlane_MetallicRoughness.png",
    "gltf/TwoSidedPlane/glTF/TwoSidedPlane_Normal.png",
    "gltf/Suzanne/glTF/Suzanne.gltf", "gltf/Suzanne/glTF/Suzanne.bin",
    "gltf/WaterBottle/glTF/WaterBottle.gltf", "gltf/WaterBottle/glTF/WaterBottle.bin",
    "meshes/spot/spot_triangulated.obj", "meshes/spot/spot_texture.png",
    "meshes/spot/README.txt",
]
MODELS = ["BoxTextured", "Duck", "MetalRoughSpheresNoTextures", "NegativeScaleTest", "NormalTangentMirrorTest",
          "NormalTangentTest", "OrientationTest", "Suzanne", "TextureCoordinateTest", "TextureEncodingTest",
          "TextureSettingsTest", "TwoSidedPlane", "WaterBottle"]
# Khronos test boards (one feature each), copied whole: every file of their model folders, their
# README (what a correct render shows) and LICENSE.md.
BOARDS = ["AnimatedMorphCube", "Box", "ClearCoatTest", "EmissiveStrengthTest", "MeshPrimitiveModes",
          "MorphPrimitivesTest", "MultiUVTest", "SimpleSkin", "SimpleSparseAccessor", "SpecularTest", "UnlitTest"]
# Binary models whose embedded images are re-encoded, with the largest side kept: the normal maps
# of the two normal-mapping tests at a quarter, so each bump still spans many texels in a test view.
GLB_TEXTURES = {"gltf/NormalTangentMirrorTest/glTF-Binary/NormalTangentMirrorTest.glb": 512,
                "gltf/NormalTangentTest/glTF-Binary/NormalTangentTest.glb": 512}
PNG_TEXTURES = {f"gltf/Suzanne/glTF/Suzanne_{slot}.png": 256 for slot in ("BaseColor", "MetallicRoughness")}
PNG_TEXTURES.update({f"gltf/WaterBottle/glTF/WaterBottle_{slot}.png": 256
                     for slot in ("baseColor", "normal", "occlusionRoughnessMetallic", "emissive")})
# HDR environments and the width each is shrunk to: the park at 512, because test_ibl prefilters
# it at 256 rows, where its small, very bright sun is the hard case.
HDRS = {"hdr/venice_sunset_1k.hdr": 256, "hdr/rooitou_park_1k.hdr": 512, "hdr/studio_small_03_1k.hdr": 256}


def shrunk_png(data: bytes, side: int) -> bytes:
    """``data`` (a PNG) area-averaged to at most ``side`` texels a side, re-encoded as PNG."""
    image = Image.open(io.BytesIO(data))
    image.load()
    if max(image.size) > side:
        factor = max(image.size) // side
        image = image.reduce(factor)  # the mean of each factor x factor block
    out = io.BytesIO()
    image.save(out, format="PNG", optimize=True)
    return out.getvalue()


def glb_with_shrunk_images(raw: bytes, side: int) -> bytes:
    """A GLB with every image in its BIN chunk re-encoded by ``shrunk_png``; the other buffer views
    are copied unchanged, each at a 4-byte aligned offset in order."""
    json_length, = struct.unpack_from("<I", raw, 12)
    doc = json.loads(raw[20:20 + json_length])
    bin_length, = struct.unpack_from("<I", raw, 20 + json_length)
    binary = raw[28 + json_length:28 + json_length + bin_length]
    images = {image["bufferView"] for image in doc.get("images", [])}
    out = bytearray()
    for index, view in enumerate(doc["bufferViews"]):
        start = view.get("byteOffset", 0)
        data = binary[start:start + view["byteLength"]]
        if index in images:
            data = shrunk_png(data, side)
        out += b"\0" * (-len(out) % 4)
        view["byteOffset"], view["byteLength"] = len(out), len(data)
        out += data
    out += b"\0" * (-len(out) % 4)
    doc["buffers"][0]["byteLength"] = len(out)
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(out), 0x004E4942) + bytes(out)
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def write_hdr(path: Path, texels: np.ndarray):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(texels.shape[1], texels.shape[0], 3, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(texels, dtype=np.float32))
    out.close()


def main(source: Path):
    from pbrwarp.environment import Environment
    from pbrwarp.kernels.equirect import downsample

    for folder in ("gltf", "gltf-ext", "hdr", "meshes"):
        shutil.rmtree(HERE / folder, ignore_errors=True)
    made = {}
    for relative in COPIED:
        made[relative] = (source / relative).read_bytes()
    for model in MODELS:
        made[f"gltf/{model}/LICENSE.md"] = (source / "gltf" / model / "LICENSE.md").read_bytes()
    for board in BOARDS:
        folder = source / "gltf-ext" / board
        for path in sorted(folder.glob("glTF*/*")) + [folder / "README.md", folder / "LICENSE.md"]:
            made[str(path.relative_to(source))] = path.read_bytes()
    for relative, side in GLB_TEXTURES.items():
        made[relative] = glb_with_shrunk_images((source / relative).read_bytes(), side)
    for relative, side in PNG_TEXTURES.items():
        made[relative] = shrunk_png((source / relative).read_bytes(), side)
    for relative, data in made.items():
        (HERE / relative).parent.mkdir(parents=True, exist_ok=True)
        (HERE / relative).write_bytes(data)
    (HERE / "hdr").mkdir()
    for relative, width in HDRS.items():
        texels = Environment.load(source / relative).texels
        while texels.shape[1] > width:
            texels = downsample(texels)
        write_hdr(HERE / relative.replace("_1k.hdr", f"_{width}.hdr"), texels)
    total = sum(p.stat().st_size for p in HERE.rglob("*") if p.is_file())
    print(f"{HERE}: {total / 1e6:.2f} MB")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(Path(sys.argv[1]).resolve())
