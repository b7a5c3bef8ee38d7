"""Textures: images plus how to sample them (wrap modes, UV transform).

UV convention: pbrwarp uses glTF's, (0, 0) is the top-left corner of the image and v grows
downwards. Meshes from trimesh carry (u, 1 - v) and are converted when they enter a scene.
"""

from __future__ import annotations

import io
import math
import threading
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import validate
from .errors import InputError, InputTypeError

WRAP_MODES = {"repeat": 0, "clamp": 1, "mirror": 2}


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), applied per channel to values in [0, 1]."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


# Pillow modes whose raw channels are not colour (+ alpha) values, and what Pillow converts them to:
# palette indices, padding bytes, premultiplied alpha, other colour spaces.
_PILLOW_CONVERSIONS = {"P": "RGBA", "PA": "RGBA", "RGBX": "RGB", "RGBa": "RGBA", "La": "LA", "1": "L",
                       "CMYK": "RGB", "YCbCr": "RGB", "LAB": "RGB", "HSV": "RGB"}
_COLOUR_KEY_MODES = ("L", "RGB", "I", "I;16", "I;16B", "I;16L")


def _pillow_array(image) -> np.ndarray:
    """A Pillow image as an integer or float array of colour (+ alpha) channels. A PNG tRNS colour
    key (``image.info["transparency"]`` on greyscale and RGB images) becomes an alpha channel, as
    PNG decoders give it; palette transparency comes through Pillow's RGBA conversion."""
    mode = image.mode
    if mode in _PILLOW_CONVERSIONS:
        return np.asarray(image.convert(_PILLOW_CONVERSIONS[mode]))
    if mode in ("I;16", "I;16B", "I;16L"):
        arr = np.asarray(image).astype(np.uint16)
    elif mode == "I":  # 32-bit integers; from PNGs, 16-bit greyscale
        arr = np.clip(np.asarray(image, dtype=np.int64), 0, 65535).astype(np.uint16)
    else:
        arr = np.asarray(image)
    key = image.info.get("transparency") if mode in _COLOUR_KEY_MODES else None
    if key is not None:
        key = np.asarray(key)
        channels = 1 if arr.ndim == 2 else arr.shape[2]
        if key.dtype.kind in "iu" and key.size == channels:
            matches = arr == key if arr.ndim == 2 else np.all(arr == key.reshape(1, 1, -1), axis=2)
            alpha = np.where(matches, 0, np.iinfo(arr.dtype).max).astype(arr.dtype)
            arr = np.dstack([arr, alpha])
    return arr


def image_to_rgba(image, what: str = "texture") -> np.ndarray:
    """Any Pillow image or numpy array as an (H, W, 4) RGBA array: uint8 for 8-bit images (kept
    8-bit, as the renderer stores them), else float32 values in [0, 1].

    Other integer arrays are scaled by their type's maximum (16-bit PNGs); float arrays are taken
    as they are. Greyscale is replicated to RGB; a missing alpha channel becomes opaque. A
    read-only (H, W, 4) uint8 or float32 array is returned as it is, anything else is copied.
    """
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow is a core dependency
        Image = None
    if Image is not None and isinstance(image, Image.Image):
        image = _pillow_array(image)
    if not isinstance(image, np.ndarray):
        raise InputTypeError(f"{what} must be a numpy array or a Pillow image, got {type(image).__name__}")
    arr = image
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] not in (1, 2, 3, 4):
        raise InputError(f"{what} must have shape (H, W) or (H, W, 1..4), got {image.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{what} is empty (shape {image.shape})")
    if arr.shape[2] == 4 and not arr.flags.writeable and arr.dtype in (np.uint8, np.float32):
        if arr.dtype == np.float32 and not np.all(np.isfinite(arr)):
            raise InputError(f"{what} contains NaN or Inf texels")
        return arr  # nobody can change it through this array: no copy needed
    if arr.dtype == np.uint8:
        opaque = 255
    elif np.issubdtype(arr.dtype, np.integer):
        arr = arr.astype(np.float32) / float(np.iinfo(arr.dtype).max)
        opaque = 1.0
    elif np.issubdtype(arr.dtype, np.floating) or arr.dtype == np.bool_:
        arr = arr.astype(np.float32)
        opaque = 1.0
    else:
        raise InputTypeError(f"{what} has unsupported dtype {arr.dtype}")
    if arr.dtype == np.float32 and not np.all(np.isfinite(arr)):
        raise InputError(f"{what} contains NaN or Inf texels")
    h, w, c = arr.shape
    out = np.full((h, w, 4), opaque, dtype=arr.dtype)
    if c in (1, 2):
        out[:, :, :3] = arr[:, :, :1]
        if c == 2:
            out[:, :, 3] = arr[:, :, 1]
    else:
        out[:, :, :c] = arr
    return out


def image_to_float_rgba(image, what: str = "texture") -> np.ndarray:
    """Any Pillow image or numpy array as a float32 (H, W, 4) array of values in [0, 1]
    (:func:`image_to_rgba`, 8-bit values divided by 255)."""
    rgba = image_to_rgba(image, what)
    return rgba.astype(np.float32) / 255.0 if rgba.dtype == np.uint8 else rgba


def _unorm8_decode_table() -> np.ndarray:
    """float32[512]: entry b is the 8-bit value b as a float in [0, 1], entry 256 + b the same
    value decoded from sRGB; exactly the values image_to_float_rgba and srgb_to_linear give."""
    linear = np.arange(256, dtype=np.uint8).astype(np.float32) / 255.0
    table = np.concatenate([linear, srgb_to_linear(linear)]).astype(np.float32)
    table.flags.writeable = False
    return table


# The kernels decode 8-bit texels with this table (kernels/textures.py, Texels.decode).
UNORM8_DECODE = _unorm8_decode_table()

# Image formats a model's textures may use: glTF's PNG and JPEG, and a few common formats Pillow
# reads itself. Others (EPS, which Pillow renders with Ghostscript, PSD, ...) are refused.
IMAGE_FORMATS = ("PNG", "JPEG", "WEBP", "GIF", "BMP", "TGA")
# warnings.catch_warnings changes process-wide state: one image header at a time.
_HEADER_LOCK = threading.Lock()


def open_image(data: bytes, what: str, max_side: int, formats=IMAGE_FORMATS):
    """``data`` opened as a Pillow image with only its header read (nothing decoded), refused
    with an ``InputError`` when it is not an image of ``formats`` (None: any format Pillow
    reads) or a side exceeds ``max_side`` texels (LoadLimits.max_texture_side). Pillow's
    warning about images past ``PIL.Image.MAX_IMAGE_PIXELS`` is silenced, as the side limit
    says it more precisely; Pillow refuses images of more than twice that many pixels itself."""
    from PIL import Image

    try:
        with _HEADER_LOCK, warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data), formats=formats)
    except Image.DecompressionBombError as err:
        raise InputError(f"{what} is refused by Pillow's limit on decoded pixels (PIL.Image.MAX_IMAGE_PIXELS): "
                         f"{err}") from None
    except Exception as err:  # Pillow raises several types for bad image data
        raise InputError(f"{what} cannot be decoded: {type(err).__name__}: {err}") from None
    width, height = image.size
    if max(width, height) > max_side:
        image.close()
        raise InputError(f"{what} is {width} x {height} texels, larger than {max_side} texels a side "
                         "(LoadLimits.max_texture_side); it is refused before decoding")
    return image


def decode_rgba(image, what: str) -> np.ndarray:
    """An opened Pillow image decoded to a read-only (H, W, 4) array (:func:`image_to_rgba`)."""
    try:
        image.load()
        rgba = image_to_rgba(image, what)
    except (InputError, InputTypeError):
        raise
    except Exception as err:  # Pillow raises several types for bad image data
        raise InputError(f"{what} cannot be decoded: {type(err).__name__}: {err}") from None
    finally:
        image.close()
    rgba.flags.writeable = False
    return rgba


def _wrap_mode(name: str):
    def check(texture, mode):
        if mode not in WRAP_MODES:
            raise InputError(f"Texture {name} must be one of {sorted(WRAP_MODES)}, got {mode!r}")
        return mode
    return check


def _uv_set(value) -> int:
    if isinstance(value, bool) or value not in (0, 1):
        raise InputError(f"Texture texcoord must be 0 or 1 (the uv set it is read with), got {value!r}")
    return int(value)


def _image(texture, image):
    """``image`` as given; its texels, converted (and so checked), become ``texture._rgba``."""
    object.__setattr__(texture, "_rgba", image_to_rgba(image))
    return image


@dataclass(eq=False)
class Texture(validate.Checked):
    """An image and the way a material samples it.

    - ``image``: a NumPy array (H, W), (H, W, 1..4) (grey, grey + alpha, RGB, RGBA) of 8- or
      16-bit integers or floats (floats taken as they are, finite), or a Pillow image (palette,
      16-bit and other modes converted). 8-bit images stay 8-bit in memory (4 bytes a texel) and
      are decoded to linear values as the renderer samples them; others are kept as float32.
    - ``srgb``: whether the colour channels are sRGB-encoded; None (the default) lets the material
      slot decide (colour slots sRGB, data slots linear, as glTF says).
    - ``wrap_s``/``wrap_t``: "repeat" (default), "clamp" or "mirror".
    - ``offset`` (default (0, 0)), ``rotation`` (radians, default 0) and ``scale`` (default
      (1, 1)): KHR_texture_transform's, in UV units, finite.
    - ``texcoord``: the uv set the texture is read with, 0 (the mesh's ``uvs``, glTF TEXCOORD_0;
      the default) or 1 (its ``uvs1``, TEXCOORD_1; a mesh without ``uvs1`` reads ``uvs``).

    Every field is checked whenever it is set, by the constructor or later: InputError for a
    value out of range (an empty image, NaN texels, an unknown wrap mode), InputTypeError for an
    image that is not an array or Pillow image.
    """

    image: object
    srgb: bool | None = None
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    offset: tuple[float, float] = (0.0, 0.0)
    rotation: float = 0.0
    scale: tuple[float, float] = (1.0, 1.0)
    texcoord: int = 0
    _rgba: np.ndarray | None = field(default=None, repr=False)

    _checks = {
        "wrap_s": _wrap_mode("wrap_s"),
        "wrap_t": _wrap_mode("wrap_t"),
        "offset": lambda texture, value: validate.finite_vector(value, 2, "Texture offset"),
        "rotation": lambda texture, value: validate.finite_scalar(value, "Texture rotation"),
        "scale": lambda texture, value: validate.finite_vector(value, 2, "Texture scale"),
        "texcoord": lambda texture, value: _uv_set(value),
        "image": _image,
    }

    @classmethod
    def wrap(cls, value, what: str) -> "Texture | None":
        """``value`` as a Texture: None stays None, images and arrays get default sampling."""
        if value is None or isinstance(value, Texture):
            return value
        try:
            return cls(value)
        except InputError as err:
            raise InputError(f"{what}: {err}") from None
        except InputTypeError as err:
            raise InputTypeError(f"{what}: {err}") from None

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) in texels."""
        return self._rgba.shape[:2]

    @property
    def rgba8(self) -> np.ndarray | None:
        """The (H, W, 4) uint8 texels of an 8-bit image as stored (sRGB-encoded or not), else None."""
        return self._rgba if self._rgba.dtype == np.uint8 else None

    def texels(self, srgb: bool) -> np.ndarray:
        """Linear float32 RGBA texels; colour channels decoded from sRGB when ``srgb``."""
        if self._rgba.dtype == np.uint8:
            table_row = np.array([256, 256, 256, 0]) if srgb else 0  # alpha is never sRGB-encoded
            return UNORM8_DECODE[self._rgba + table_row]
        if not srgb:
            return self._rgba
        out = self._rgba.copy()
        out[:, :, :3] = srgb_to_linear(out[:, :, :3])
        return out

    def uv_matrix(self) -> np.ndarray:
        """The 2x3 affine map uv -> uv' of KHR_texture_transform (translation * rotation * scale)."""
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        sx, sy = self.scale
        tx, ty = self.offset
        return np.array([[c * sx, s * sy, tx], [-s * sx, c * sy, ty]], dtype=np.float32)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """The inverse of :func:`srgb_to_linear` (IEC 61966-2-1's OETF), per channel, for values in [0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1.0 / 2.4) - 0.055)


def _box_taps(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Source indices (m, 3) and weights (m, 3) of the box filter that shrinks a side of ``size``
    texels to m = max(1, size // 2): output texel i averages the piecewise-constant source over
    [i size / m, (i + 1) size / m], so an even side averages pairs and an odd side's boxes are
    2 + 1/m texels wide, weighting the texels they cover in part by the covered fraction. Each
    level's mean therefore equals its parent's exactly (up to rounding)."""
    m = max(1, size // 2)
    width = size / m
    start = np.arange(m, dtype=np.float64)[:, None] * width
    first = np.floor(start).astype(np.int64)
    taps = first + np.arange(3)[None, :]
    overlap = np.minimum(taps + 1, start + width) - np.maximum(taps, start)
    weights = np.clip(overlap, 0.0, None) / width
    return np.minimum(taps, size - 1), weights


def _halved(img: np.ndarray, axis: int) -> np.ndarray:
    """``img`` with the side along ``axis`` (0 or 1) shrunk by the box filter of :func:`_box_taps`;
    an even side averages neighbouring pairs directly (no gathered copy of the image)."""
    size = img.shape[axis]
    if size % 2 == 0:
        pairs = img.reshape(img.shape[:axis] + (size // 2, 2) + img.shape[axis + 1:])
        return pairs.mean(axis=axis + 1, dtype=img.dtype)
    taps, weights = _box_taps(size)
    if axis == 0:
        return np.einsum("mk,mkwc->mwc", weights.astype(img.dtype), img[taps])
    return np.einsum("nk,hnkc->hnc", weights.astype(img.dtype), img[:, taps])


def box_downsample(linear: np.ndarray) -> np.ndarray:
    """The next mip level of linear (H, W, C) texels, each side halved (rounded down, at least 1)
    by the area-weighted box filter of :func:`_box_taps`; float32 texels stay float32 (the
    precision they are stored in), anything else is computed in float64."""
    img = np.asarray(linear)
    if img.dtype != np.float32:
        img = img.astype(np.float64)
    return _halved(_halved(img, 0), 1)


def mip_chain(linear: np.ndarray) -> list[np.ndarray]:
    """Linear (H, W, 4) texels and their mip levels down to 1 x 1 texel, level 0 first
    (1 + floor(log2(max(H, W))) levels), float32 for float32 texels, else float64. The levels
    past 0 add at most a third of level 0's texels (exactly a third for square power-of-two
    sides)."""
    img = np.asarray(linear)
    levels = [img if img.dtype == np.float32 else img.astype(np.float64)]
    while max(levels[-1].shape[:2]) > 1:
        levels.append(box_downsample(levels[-1]))
    return levels


def mip_texel_count(height: int, width: int) -> tuple[int, int]:
    """(levels, texels) of the full mip chain of a height x width image: what :func:`mip_chain`
    makes, counted without making it."""
    levels = max(height, width).bit_length()  # 1 + floor(log2(longer side))
    return levels, sum(max(1, height >> lv) * max(1, width >> lv) for lv in range(levels))


def encode_unorm8(linear: np.ndarray, srgb: bool) -> np.ndarray:
    """Linear RGBA values in [0, 1] as 8-bit texels (rounded to nearest): colour channels
    sRGB-encoded when ``srgb`` so that UNORM8_DECODE gives them back, alpha never."""
    out = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0).copy()
    if srgb:
        out[..., :3] = linear_to_srgb(out[..., :3])
    return np.rint(out * 255.0).astype(np.uint8)


def mip_levels(texture: "Texture", srgb: bool) -> list[np.ndarray]:
    """``texture``'s mip levels past level 0, in its stored form: 8-bit textures stay 8-bit
    (averaged in linear space, then re-encoded as they were, so the kernels' decode stays
    correct), others float32 linear."""
    chain = mip_chain(texture.texels(srgb))[1:]
    if texture.rgba8 is not None:
        return [encode_unorm8(level, srgb) for level in chain]
    return [level.astype(np.float32) for level in chain]
