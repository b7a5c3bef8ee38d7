"""KHR_texture_basisu: KTX2 textures (Basis Universal ETC1S or UASTC), decoded by opengl-basisu.

opengl-basisu (the ``ktx2`` extra, ``pip install "pbrwarp[ktx2]"``) binds Binomial's
basis_universal transcoder, which turns a KTX2 file's supercompressed ETC1S or UASTC payload into
RGBA8 texels on the CPU. A texture whose KHR_texture_basisu ``source`` names a KTX2 image samples
that image; its core ``source`` (or EXT_texture_webp's) is then the fallback for viewers without a
decoder. docs/loading.md ("KTX2 textures") says why this package.

The KTX2 header (the KTX 2.0 specification, section 3) is read here before the decoder sees the
bytes: a 2D, single-face, non-array Basis Universal image (``vkFormat`` 0) whose width and height
are within ``LoadLimits.max_texture_side`` and whose level count fits its size. Only level 0 is
decoded. Without opengl-basisu a texture with a fallback uses it, with a warning giving the install
command; one without is an error naming KTX2 and the command.
"""

from __future__ import annotations

import struct

import numpy as np

from .errors import InputError

EXTENSION = "KHR_texture_basisu"
INSTALL = 'pip install "pbrwarp[ktx2]"'
MAGIC = b"\xabKTX 20\xbb\r\n\x1a\n"  # the KTX 2.0 file identifier
_HEADER = struct.Struct("<12s9I")  # identifier, vkFormat, typeSize, width, height, depth, layers, faces, levels, scheme
_HEADER_AND_INDEX = 80  # the header above, then the offsets and lengths of the file's sections
_VK_FORMAT_UNDEFINED = 0  # the vkFormat of a Basis Universal payload


def decoder():
    """The opengl_basisu module, or None when the ``ktx2`` extra is not installed."""
    try:
        import opengl_basisu
    except ImportError:
        return None
    return opengl_basisu


def texture_source(doc, tex: dict, index: int, label: str, fallback):
    """The image texture ``index`` samples: its KHR_texture_basisu KTX2 image when opengl-basisu
    is installed, else ``fallback`` (its core or EXT_texture_webp ``source``, None if it has
    neither), noted (``doc.notes``) when a KTX2 image is passed over. A texture with only a KTX2
    image and no decoder is an error naming the format and the install command."""
    extensions = tex.get("extensions", {})
    spec = extensions.get(EXTENSION) if isinstance(extensions, dict) else None
    if not isinstance(spec, dict) or "source" not in spec:
        return fallback
    if decoder() is not None:
        return spec["source"]
    if fallback is None:
        raise doc.error(f"{label}: texture {index} has only a KTX2 image ({EXTENSION}, Basis Universal) and no PNG "
                        f"or JPEG fallback; decoding KTX2 needs opengl-basisu: {INSTALL}")
    doc.notes.add(f"undecoded {EXTENSION}", f"{EXTENSION} on {{subjects}} not decoded: opengl-basisu is not "
                  f"installed ({INSTALL}); their fallback PNG or JPEG images are used", "texture", index, str(index))
    return fallback


def is_ktx2(data: bytes) -> bool:
    return data[:len(MAGIC)] == MAGIC


def ktx2_size(data: bytes, what: str, max_side: int) -> tuple[int, int]:
    """(width, height) of the KTX2 image ``data`` from its header alone, refused with an
    ``InputError`` when it is not a 2D Basis Universal image pbrwarp decodes or a side exceeds
    ``max_side`` (LoadLimits.max_texture_side)."""
    if len(data) < _HEADER_AND_INDEX:
        raise InputError(f"{what} is a truncated KTX2 file ({len(data)} bytes, shorter than its header)")
    _, vk_format, _, width, height, depth, layers, faces, levels, _ = _HEADER.unpack_from(data)
    if vk_format != _VK_FORMAT_UNDEFINED:
        raise InputError(f"{what} is a KTX2 file of vkFormat {vk_format}; glTF's {EXTENSION} images hold Basis "
                         "Universal data (vkFormat 0)")
    if depth > 0 or layers > 1 or faces != 1:
        raise InputError(f"{what} is a KTX2 file of depth {depth}, {layers} layers and {faces} faces; a glTF "
                         "texture is one 2D image")
    if not 1 <= width <= max_side or not 1 <= height <= max_side:
        raise InputError(f"{what} is {width} x {height} texels, outside 1..{max_side} texels a side "
                         "(LoadLimits.max_texture_side); it is refused before decoding")
    if levels > max(width, height).bit_length():  # a full mip chain of a w x h image has this many levels
        raise InputError(f"{what} declares {levels} mip levels, more than a {width} x {height} image has")
    return width, height


def decode_ktx2(data: bytes, what: str, size: tuple[int, int]) -> np.ndarray:
    """Level 0 of the KTX2 image ``data`` (checked by :func:`ktx2_size`, which gave ``size``)
    as a read-only (H, W, 4) uint8 array, row 0 at the top, as glTF's KTX2 images are stored."""
    basisu = decoder()
    if basisu is None:
        raise InputError(f"{what} is a KTX2 image (Basis Universal); decoding it needs opengl-basisu: {INSTALL}")
    try:
        texture = basisu.Texture(data)
        if (texture.width, texture.height) != size:
            raise InputError(f"{what}: the decoder reads a {texture.width} x {texture.height} image from a header "
                             f"declaring {size[0]} x {size[1]}")
        texels = np.asarray(texture.transcode("rgba8").data, dtype=np.uint8)
    except InputError:
        raise
    except Exception as err:  # opengl-basisu raises BasisuError, UnsupportedError, ValueError on bad data
        raise InputError(f"{what} is a KTX2 image that cannot be decoded ({type(err).__name__}: {err})") from None
    rgba = texels.reshape(size[1], size[0], 4)
    rgba.flags.writeable = False
    return rgba
