"""Loader fuzzing: random, truncated and corrupted scene files raise a pbrwarp error or load.

Every case is generated here (seeded, so the same files every run) from the real assets in
the test assets and from small meshes written on the spot, then loaded by one child
process that prints one line per case. A child is used so that a crash in native code (a
segfault in Warp, numpy or Pillow) or a hang is reported as a failure of the case that caused it
instead of killing pytest. The parent asserts that the child exited normally and that each case
either loaded (and then rendered a 16x16 frame that ``pw.check`` finds finite and non-negative)
or raised a ``pw.PbrwarpError`` subclass: never a raw ``KeyError``, ``IndexError``,
``struct.error``, ``MemoryError`` and so on.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from assets import ASSETS, mesh_file

DUCK = ASSETS / "gltf" / "Duck" / "glTF-Binary" / "Duck.glb"
BOX = ASSETS / "gltf" / "BoxTextured" / "glTF-Binary" / "BoxTextured.glb"

SELF = "@SELF@"  # replaced by the case's own file name
CASE_TIMEOUT_S = 60  # one case taking this long counts as a hang
TOTAL_TIMEOUT_S = 300

# ---------------------------------------------------------------------------- GLB helpers
_JSON, _BIN = 0x4E4F534A, 0x004E4942


def split_glb(raw: bytes) -> tuple[dict, bytearray]:
    """(JSON, BIN chunk) of a well-formed GLB."""
    json_len, = struct.unpack_from("<I", raw, 12)
    doc = json.loads(raw[20:20 + json_len])
    bin_len, = struct.unpack_from("<I", raw, 20 + json_len)
    return doc, bytearray(raw[28 + json_len:28 + json_len + bin_len])


def glb_bytes(doc, binary, *, magic=b"glTF", version=2, length_delta=0, json_bytes=None) -> bytes:
    """A GLB from a JSON document (or raw JSON chunk bytes) and a BIN chunk (None: no BIN chunk)."""
    text = json.dumps(doc).encode() if json_bytes is None else bytes(json_bytes)
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), _JSON) + text
    if binary is not None:
        binary = bytes(binary) + b"\0" * (-len(binary) % 4)
        body += struct.pack("<II", len(binary), _BIN) + binary
    return magic + struct.pack("<II", version, 12 + len(body) + length_delta) + body


class Glb:
    """A parsed GLB to edit: ``doc`` (JSON), ``bin`` (bytearray) and handy indices."""

    def __init__(self, raw: bytes):
        self.doc, self.bin = split_glb(raw)
        prim = self.doc["meshes"][0]["primitives"][0]
        self.prim = prim
        self.indices = prim["indices"]
        self.position = prim["attributes"]["POSITION"]
        self.normal = prim["attributes"]["NORMAL"]
        self.texcoord = prim["attributes"]["TEXCOORD_0"]

    def acc(self, index) -> dict:
        return self.doc["accessors"][index]

    def view_of(self, accessor) -> dict:
        return self.doc["bufferViews"][self.acc(accessor)["bufferView"]]

    def add_view(self, data: bytes) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        self.doc["buffers"][0]["byteLength"] = len(self.bin)
        return len(self.doc["bufferViews"]) - 1

    def image_bytes(self) -> bytes:
        """The encoded bytes of image 0."""
        view = self.doc["bufferViews"][self.doc["images"][0]["bufferView"]]
        return bytes(self.bin[view.get("byteOffset", 0):][:view["byteLength"]])

    def set_image(self, data: bytes):
        self.doc["images"][0] = {"bufferView": self.add_view(data), "mimeType": "image/png"}

    def vertex_count(self) -> int:
        return self.acc(self.position)["count"]

    def data_offset(self, accessor) -> int:
        """Byte offset in BIN of an accessor's first element."""
        return self.view_of(accessor).get("byteOffset", 0) + self.acc(accessor).get("byteOffset", 0)

    def index_offset(self) -> int:
        return self.data_offset(self.indices)

    def glb(self, **kw) -> bytes:
        return glb_bytes(self.doc, self.bin, **kw)


def png_bytes(array, mode=None) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(array), mode).save(buf, format="PNG")
    return buf.getvalue()


def huge_png_header() -> bytes:
    """A PNG whose IHDR claims 200000 x 200000 pixels, followed by no image data."""
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", 200000, 200000, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def _pop(path):
    """An edit removing doc[path[0]][path[1]]...[path[-1]]."""
    def edit(g):
        target = g.doc
        for key in path[:-1]:
            target = target[key]
        del target[path[-1]]
    return edit


# Structured edits of a parsed GLB: name -> function(g) editing g in place. Every one must be
# rejected with a pbrwarp error or load and render finite.
def _structured_edits():
    E = {}
    # -- accessor counts
    for who in ("indices", "position", "texcoord"):
        for label, count in (("1e9", 10**9), ("2p31", 2**31), ("2p32", 2**32), ("2p63", 2**63), ("2p64", 2**64),
                             ("neg", -1), ("zero", 0), ("float", 1.5), ("str", "12"), ("null", None)):
            E[f"count-{who}-{label}"] = lambda g, who=who, count=count: g.acc(getattr(g, who)).update(count=count)
    # accessors with no bufferView are all zeros: a huge count must not allocate gigabytes
    for label, count in (("1e9", 10**9), ("2p31", 2**31), ("2p40", 2**40)):
        def edit(g, count=count):
            acc = g.acc(g.position)
            acc.pop("bufferView")
            acc.pop("byteOffset", None)
            acc["count"] = count
        E[f"count-position-noview-{label}"] = edit
        def edit(g, count=count):  # a sparse accessor with a huge count
            acc = g.acc(g.texcoord)
            acc["sparse"] = {"count": count, "indices": {"bufferView": 0, "componentType": 5123},
                             "values": {"bufferView": 1}}
        E[f"sparse-count-{label}"] = edit
    E["sparse-index-out-of-range"] = lambda g: g.acc(g.texcoord).update(sparse={
        "count": 1, "indices": {"bufferView": g.add_view(struct.pack("<I", 2**32 - 1)), "componentType": 5125},
        "values": {"bufferView": g.add_view(b"\0" * 8)}})
    E["sparse-missing-indices"] = lambda g: g.acc(g.texcoord).update(sparse={"count": 1, "values": {"bufferView": 1}})
    E["sparse-not-object"] = lambda g: g.acc(g.texcoord).update(sparse=[1, 2])
    # -- byte offsets and lengths
    for who in ("indices", "position"):
        E[f"byteOffset-{who}-past-view"] = lambda g, who=who: g.acc(getattr(g, who)).update(
            byteOffset=g.view_of(getattr(g, who))["byteLength"])
        E[f"byteOffset-{who}-2p40"] = lambda g, who=who: g.acc(getattr(g, who)).update(byteOffset=2**40)
        E[f"byteOffset-{who}-neg"] = lambda g, who=who: g.acc(getattr(g, who)).update(byteOffset=-4)
        E[f"byteOffset-{who}-misaligned"] = lambda g, who=who: g.acc(getattr(g, who)).update(byteOffset=1)
        E[f"byteOffset-{who}-float"] = lambda g, who=who: g.acc(getattr(g, who)).update(byteOffset=0.5)
        E[f"view-{who}-offset-past-buffer"] = lambda g, who=who: g.view_of(getattr(g, who)).update(
            byteOffset=len(g.bin) + 4)
        E[f"view-{who}-offset-neg"] = lambda g, who=who: g.view_of(getattr(g, who)).update(byteOffset=-8)
        E[f"view-{who}-length-huge"] = lambda g, who=who: g.view_of(getattr(g, who)).update(byteLength=2**62)
        E[f"view-{who}-length-neg"] = lambda g, who=who: g.view_of(getattr(g, who)).update(byteLength=-1)
        E[f"view-{who}-length-zero"] = lambda g, who=who: g.view_of(getattr(g, who)).update(byteLength=0)
        E[f"view-{who}-buffer-99"] = lambda g, who=who: g.view_of(getattr(g, who)).update(buffer=99)
        E[f"view-{who}-buffer-str"] = lambda g, who=who: g.view_of(getattr(g, who)).update(buffer="0")
        for stride in (0, 1, 3, 4, 13, 252, 256, 2**31, -12, "12", 1.5):
            E[f"byteStride-{who}-{stride}"] = lambda g, who=who, stride=stride: g.view_of(getattr(g, who)).update(
                byteStride=stride)
    E["buffer-length-huge"] = lambda g: g.doc["buffers"][0].update(byteLength=2**40)
    E["buffer-length-zero"] = lambda g: g.doc["buffers"][0].update(byteLength=0)
    E["buffer-length-neg"] = lambda g: g.doc["buffers"][0].update(byteLength=-5)
    E["buffer-uri-http"] = lambda g: g.doc["buffers"][0].update(uri="http://example.invalid/x.bin")
    E["buffer-uri-missing-file"] = lambda g: g.doc["buffers"][0].update(uri="nope.bin")
    E["buffer-uri-bad-base64"] = lambda g: g.doc["buffers"][0].update(uri="data:application/octet-stream;base64,!!!")
    E["buffer-uri-folder"] = lambda g: g.doc["buffers"][0].update(uri=".")
    E["buffers-empty"] = lambda g: g.doc.update(buffers=[])
    # -- indices pointing out of range (written into BIN)
    def index_value(value, fmt="<H"):
        def edit(g):
            struct.pack_into(fmt, g.bin, g.index_offset() + 2 * struct.calcsize(fmt), value)
        return edit
    E["index-eq-vertex-count"] = lambda g: index_value(g.vertex_count())(g)
    E["index-u16-max"] = index_value(2**16 - 1)
    def u32_indices(value):
        def edit(g):
            acc = g.acc(g.indices)
            n = acc["count"]
            idx = np.arange(n, dtype="<u4") % g.vertex_count()
            idx[n // 2] = value
            acc.update(bufferView=g.add_view(idx.tobytes()), byteOffset=0, componentType=5125)
        return edit
    E["index-u32-eq-vertex-count"] = lambda g: u32_indices(g.vertex_count())(g)
    E["index-u32-max"] = u32_indices(2**32 - 1)
    E["index-u32-2p31"] = u32_indices(2**31)
    E["index-read-as-u32"] = lambda g: g.acc(g.indices).update(componentType=5125, count=g.acc(g.indices)["count"] // 2)
    E["index-read-as-u8"] = lambda g: g.acc(g.indices).update(componentType=5121)
    E["index-count-not-multiple-of-3"] = lambda g: g.acc(g.indices).update(count=g.acc(g.indices)["count"] - 1)
    # -- component types and accessor types
    for who in ("indices", "position", "texcoord"):
        for ctype in (-1, 0, 5124, 5130, 5126, 5120, 5121, "5126", None, 1.5):
            E[f"componentType-{who}-{ctype}"] = lambda g, who=who, ctype=ctype: g.acc(getattr(g, who)).update(
                componentType=ctype)
        for kind in ("MAT4", "VEC5", None, 3, "scalar"):
            E[f"type-{who}-{kind}"] = lambda g, who=who, kind=kind: g.acc(getattr(g, who)).update(type=kind)
        E[f"normalized-{who}"] = lambda g, who=who: g.acc(getattr(g, who)).update(normalized=True)
    E["position-u8-normalized"] = lambda g: g.acc(g.position).update(componentType=5121, normalized=True)
    # -- missing required fields
    for path in (("asset",), ("asset", "version"), ("accessors",), ("bufferViews",), ("buffers",), ("meshes",),
                 ("nodes",), ("scenes",), ("materials",), ("textures",), ("images",), ("samplers",),
                 ("accessors", 0, "componentType"), ("accessors", 0, "count"), ("accessors", 0, "type"),
                 ("accessors", 2, "componentType"), ("accessors", 2, "count"), ("accessors", 2, "type"),
                 ("bufferViews", 0, "buffer"), ("bufferViews", 0, "byteLength"), ("bufferViews", 1, "byteLength"),
                 ("buffers", 0, "byteLength"), ("meshes", 0, "primitives"),
                 ("meshes", 0, "primitives", 0, "attributes"),
                 ("scenes", 0, "nodes"), ("textures", 0, "source"), ("images", 0, "bufferView"),
                 ("images", 0, "mimeType"), ("materials", 0, "pbrMetallicRoughness"),
                 ("materials", 0, "pbrMetallicRoughness", "baseColorTexture", "index")):
        E["missing-" + "-".join(map(str, path))] = _pop(path)
    # -- wrong JSON types where objects or arrays belong
    for key in ("accessors", "bufferViews", "buffers", "meshes", "nodes", "scenes", "materials", "textures",
                "images", "samplers", "asset", "extensions", "cameras"):
        for label, value in (("str", "x"), ("num", 3), ("obj", {"0": {}}), ("null", None), ("list-of-num", [1, 2])):
            E[f"jsontype-{key}-{label}"] = lambda g, key=key, value=value: g.doc.update({key: value})
    E["jsontype-attributes-list"] = lambda g: g.prim.update(attributes=[0, 1, 2])
    E["jsontype-primitives-dict"] = lambda g: g.doc["meshes"][0].update(primitives={"a": 1})
    E["jsontype-primitive-str"] = lambda g: g.doc["meshes"][0].update(primitives=["x"])
    E["jsontype-matrix-str"] = lambda g: g.doc["nodes"][0].update(matrix="identity")
    E["jsontype-children-str"] = lambda g: g.doc["nodes"][0].update(children="1")
    E["jsontype-sampler-wrap-str"] = lambda g: g.doc["samplers"][0].update(wrapS="REPEAT")
    E["jsontype-texinfo-list"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"].update(baseColorTexture=[0])
    E["jsontype-extensions-list"] = lambda g: g.doc["materials"][0].update(extensions=[1])
    E["jsontype-required-str"] = lambda g: g.doc.update(extensionsRequired="KHR_lights_punctual")
    E["jsontype-required-dict"] = lambda g: g.doc.update(extensionsRequired={"a": 1})
    # -- primitive modes
    for mode in (0, 1, 2, 3, 5, 6, 7, -1, "4", None):
        E[f"mode-{mode}"] = lambda g, mode=mode: g.prim.update(mode=mode)
    # -- index references out of range
    E["material-99"] = lambda g: g.prim.update(material=99)
    E["material-neg"] = lambda g: g.prim.update(material=-1)
    E["material-str"] = lambda g: g.prim.update(material="0")
    E["material-bool"] = lambda g: g.prim.update(material=True)
    E["texture-99"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(index=99)
    E["texture-neg"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(index=-1)
    E["texcoord-7"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(texCoord=7)
    E["image-99"] = lambda g: g.doc["textures"][0].update(source=99)
    E["image-str"] = lambda g: g.doc["textures"][0].update(source="0")
    E["sampler-99"] = lambda g: g.doc["textures"][0].update(sampler=99)
    E["sampler-wrap-bad"] = lambda g: g.doc["samplers"][0].update(wrapT=1234)
    E["image-view-99"] = lambda g: g.doc["images"][0].update(bufferView=99)
    E["normal-texture-99"] = lambda g: g.doc["materials"][0].update(normalTexture={"index": 99})
    E["emissive-texture-image"] = lambda g: g.doc["materials"][0].update(emissiveTexture={"index": 0})
    E["accessor-99"] = lambda g: g.prim["attributes"].update(NORMAL=99)
    E["accessor-neg"] = lambda g: g.prim["attributes"].update(TEXCOORD_0=-1)
    E["indices-99"] = lambda g: g.prim.update(indices=99)
    E["node-mesh-99"] = lambda g: g.doc["nodes"][-1].update(mesh=99)
    E["node-mesh-neg"] = lambda g: g.doc["nodes"][-1].update(mesh=-1)
    E["node-child-99"] = lambda g: g.doc["nodes"][0].update(children=[99])
    E["node-cycle"] = lambda g: g.doc["nodes"][-1].update(children=[0])
    E["node-self-child"] = lambda g: g.doc["nodes"][0].update(children=[0])
    E["scene-99"] = lambda g: g.doc.update(scene=99)
    E["scene-neg"] = lambda g: g.doc.update(scene=-1)
    E["scenes-empty"] = lambda g: g.doc.update(scenes=[])
    E["scene-root-99"] = lambda g: g.doc["scenes"][0].update(nodes=[99])
    E["camera-99"] = lambda g: g.doc["nodes"][0].update(camera=99)
    # -- materials with bad factors
    for key, value in (("baseColorFactor", [1, 1]), ("baseColorFactor", [-1, 0, 0, 1]), ("baseColorFactor", "red"),
                       ("metallicFactor", 2), ("roughnessFactor", -1), ("roughnessFactor", "x")):
        E[f"factor-{key}-{value}"] = lambda g, key=key, value=value: (
            g.doc["materials"][0]["pbrMetallicRoughness"].update({key: value}))
    E["factor-emissive-neg"] = lambda g: g.doc["materials"][0].update(emissiveFactor=[-1, 0, 0])
    E["factor-emissive-str"] = lambda g: g.doc["materials"][0].update(emissiveFactor="x")
    E["factor-emissive-strength-huge"] = lambda g: g.doc["materials"][0].update(
        emissiveFactor=[1, 1, 1], extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 1e308}})
    E["factor-alpha-mode"] = lambda g: g.doc["materials"][0].update(alphaMode="GLASS")
    E["factor-alpha-cutoff"] = lambda g: g.doc["materials"][0].update(alphaMode="MASK", alphaCutoff=5)
    E["factor-normal-scale-str"] = lambda g: g.doc["materials"][0].update(normalTexture={"index": 0, "scale": "x"})
    E["factor-double-sided-str"] = lambda g: g.doc["materials"][0].update(doubleSided="no")
    E["texture-transform-bad"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(
        extensions={"KHR_texture_transform": {"scale": [0, "x"], "rotation": "r"}})
    E["texture-transform-huge"] = lambda g: g.doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(
        extensions={"KHR_texture_transform": {"scale": [1e300, 1e300], "offset": [1e300, -1e300]}})
    # -- node transforms
    E["node-matrix-zero"] = lambda g: g.doc["nodes"][0].update(matrix=[0] * 16)
    E["node-matrix-short"] = lambda g: g.doc["nodes"][0].update(matrix=[1, 0, 0])
    E["node-matrix-huge"] = lambda g: g.doc["nodes"][0].update(
        matrix=(np.eye(4) * [1e300, 1e300, 1e300, 1]).ravel().tolist())
    E["node-scale-1e39"] = lambda g: g.doc["nodes"][-1].update(scale=[1e39, 1e39, 1e39])
    E["node-scale-1e-300"] = lambda g: g.doc["nodes"][-1].update(scale=[1e-300, 1e-300, 1e-300])
    E["node-translation-1e300"] = lambda g: g.doc["nodes"][-1].update(translation=[1e300, 0, 0])
    E["node-rotation-huge"] = lambda g: g.doc["nodes"][-1].update(rotation=[1e300, 0, 0, 1e300])
    E["node-rotation-tiny"] = lambda g: g.doc["nodes"][-1].update(rotation=[1e-200, 0, 0, 1e-200])
    E["node-rotation-zero"] = lambda g: g.doc["nodes"][-1].update(rotation=[0, 0, 0, 0])
    def deep_chain(g):
        start = len(g.doc["nodes"])
        g.doc["nodes"].extend({"children": [start + i + 1]} for i in range(3000))
        g.doc["nodes"].append({"mesh": 0})
        g.doc["scenes"][0]["nodes"] = [start]
    E["node-chain-3000"] = deep_chain
    # -- lights and cameras
    def light(spec):
        def edit(g):
            g.doc.setdefault("extensionsUsed", []).append("KHR_lights_punctual")
            g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [spec]}}
            g.doc["nodes"].append({"extensions": {"KHR_lights_punctual": {"light": 0}}})
            g.doc["scenes"][0]["nodes"].append(len(g.doc["nodes"]) - 1)
        return edit
    for label, spec in (("point-neg", {"type": "point", "intensity": -5}),
                        ("point-str", {"type": "point", "intensity": "bright"}),
                        ("point-huge", {"type": "point", "intensity": 1e308}),
                        ("colour-short", {"type": "directional", "color": [1, 1]}),
                        ("colour-neg", {"type": "directional", "color": [1, -1, 1]}),
                        ("spot-cones", {"type": "spot", "spot": {"innerConeAngle": 2.0, "outerConeAngle": 1.0}}),
                        ("spot-not-object", {"type": "spot", "spot": 3}),
                        ("unknown", {"type": "area"}), ("no-type", {}), ("not-object", "x")):
        E[f"light-{label}"] = light(spec)
    def light_ref(ref):
        def edit(g):
            g.doc["nodes"].append({"extensions": {"KHR_lights_punctual": ref}})
            g.doc["scenes"][0]["nodes"].append(len(g.doc["nodes"]) - 1)
        return edit
    E["light-ref-99"] = light_ref({"light": 99})
    E["light-ref-not-object"] = light_ref(5)
    def camera(spec):
        def edit(g):
            g.doc["cameras"] = [spec]
            g.doc["nodes"].append({"camera": 0, "translation": [0, 0, 10]})
            g.doc["scenes"][0]["nodes"].append(len(g.doc["nodes"]) - 1)
        return edit
    for label, spec in (("yfov-zero", {"type": "perspective", "perspective": {"yfov": 0}}),
                        ("yfov-neg", {"type": "perspective", "perspective": {"yfov": -1}}),
                        ("yfov-huge", {"type": "perspective", "perspective": {"yfov": 1e9}}),
                        ("yfov-missing", {"type": "perspective", "perspective": {}}),
                        ("yfov-str", {"type": "perspective", "perspective": {"yfov": "wide"}}),
                        ("no-perspective", {"type": "perspective"}),
                        ("ortho", {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1}}),
                        ("not-object", 7)):
        E[f"camera-{label}"] = camera(spec)
    E["extensions-required-unknown"] = lambda g: g.doc.update(extensionsRequired=["EXT_unknown"])
    # -- images that are not images (or are odd ones)
    rng = np.random.default_rng(7)
    E["image-json-text"] = lambda g: g.set_image(json.dumps(g.doc).encode())
    E["image-random-bytes"] = lambda g: g.set_image(rng.integers(0, 256, 3000, dtype=np.uint8).tobytes())
    E["image-empty"] = lambda g: g.set_image(b"")
    E["image-png-signature-only"] = lambda g: g.set_image(b"\x89PNG\r\n\x1a\n")
    E["image-truncated-png"] = lambda g: g.set_image(g.image_bytes()[: len(g.image_bytes()) // 2])
    E["image-png-flipped-bytes"] = lambda g: g.set_image(bytes(b ^ 0x55 if i % 97 == 50 else b
                                                               for i, b in enumerate(g.image_bytes())))
    E["image-huge-dimensions"] = lambda g: g.set_image(huge_png_header())
    E["image-1x1"] = lambda g: g.set_image(png_bytes(np.array([[[200, 10, 10]]], np.uint8)))
    E["image-16bit-grey"] = lambda g: g.set_image(png_bytes(np.full((5, 3), 40000, np.uint16)))
    E["image-la"] = lambda g: g.set_image(png_bytes(np.full((4, 4, 2), 128, np.uint8), "LA"))
    E["image-bilevel"] = lambda g: g.set_image(png_bytes(np.eye(8, dtype=bool)))
    E["image-gif"] = lambda g: g.set_image(_gif_bytes())
    E["image-uri-bad-base64"] = lambda g: g.doc["images"].__setitem__(0, {"uri": "data:image/png;base64,###"})
    E["image-uri-data-not-png"] = lambda g: g.doc["images"].__setitem__(0, {"uri": "data:image/png,hello%20world"})
    E["image-uri-http"] = lambda g: g.doc["images"].__setitem__(0, {"uri": "https://example.invalid/a.png"})
    E["image-uri-missing"] = lambda g: g.doc["images"].__setitem__(0, {"uri": "missing.png"})
    E["image-uri-self"] = lambda g: g.doc["images"].__setitem__(0, {"uri": SELF})
    E["image-no-source"] = lambda g: g.doc["images"].__setitem__(0, {})
    return E


def _gif_bytes() -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("P", (3, 3), 1).save(buf, format="GIF")
    return buf.getvalue()


def glb_cases(name: str, raw: bytes, rng) -> dict[str, bytes]:
    cases = {}
    json_len, = struct.unpack_from("<I", raw, 12)
    json_end = 20 + json_len
    # -- truncation at many offsets, header left as is
    offsets = {0, 1, 3, 4, 8, 11, 12, 16, 19, 20, 21, json_end - 1, json_end, json_end + 4, json_end + 8,
               len(raw) - 4, len(raw) - 1}
    offsets |= set(rng.integers(21, len(raw), 14).tolist())
    for cut in sorted(offsets):
        cases[f"trunc-{cut}"] = raw[:cut]
    # ... and truncated with every length field patched to agree (so the reader gets further)
    g = Glb(raw)
    for frac in (0.0, 0.1, 0.33, 0.5, 0.9, 0.999):
        cut = int(len(g.bin) * frac)
        short = glb_bytes(g.doc, g.bin[:cut])
        cases[f"trunc-bin-patched-{frac}"] = short
        doc = json.loads(json.dumps(g.doc))
        doc["buffers"][0]["byteLength"] = cut
        cases[f"trunc-bin-patched-buffer-{frac}"] = glb_bytes(doc, g.bin[:cut])
    # -- header and chunk framing
    cases["magic-wrong"] = b"glTf" + raw[4:]
    cases["magic-zero"] = b"\0\0\0\0" + raw[4:]
    for version in (0, 1, 3, 2**32 - 1):
        cases[f"version-{version}"] = raw[:4] + struct.pack("<I", version) + raw[8:]
    for label, length in (("plus100", len(raw) + 100), ("minus100", len(raw) - 100), ("zero", 0), ("12", 12),
                          ("20", 20), ("max", 2**32 - 1), ("json-only", json_end)):
        cases[f"header-length-{label}"] = raw[:8] + struct.pack("<I", length) + raw[12:]
    cases["chunk-json-length-max"] = raw[:12] + struct.pack("<I", 2**32 - 1) + raw[16:]
    cases["chunk-json-length-zero"] = raw[:12] + struct.pack("<I", 0) + raw[16:]
    cases["chunk-json-length-odd"] = raw[:12] + struct.pack("<I", json_len - 3) + raw[16:]
    cases["chunk-json-type-bin"] = raw[:16] + struct.pack("<I", _BIN) + raw[20:]
    cases["chunk-bin-type-json"] = raw[:json_end + 4] + struct.pack("<I", _JSON) + raw[json_end + 8:]
    cases["chunk-bin-length-max"] = raw[:json_end] + struct.pack("<I", 2**32 - 1) + raw[json_end + 4:]
    cases["chunk-bin-missing"] = glb_bytes(g.doc, None)
    cases["chunk-extra-unknown"] = raw + struct.pack("<II", 8, 0x12345678) + b"\0" * 8
    fixed = bytearray(cases["chunk-extra-unknown"])
    struct.pack_into("<I", fixed, 8, len(fixed))
    cases["chunk-extra-unknown-patched"] = bytes(fixed)
    cases["chunk-trailing-garbage"] = raw + b"\xff" * 5
    # -- JSON chunk garbage
    for i in range(3):
        cases[f"json-random-{i}"] = raw[:20] + rng.integers(0, 256, json_len, dtype=np.uint8).tobytes() + raw[json_end:]
    for label, text in (("list", b"[]"), ("null", b"null"), ("number", b"12"), ("string", b'"glTF"'),
                        ("empty-object", b"{}"), ("empty", b""), ("latin1", '{"asset": "\xe9"}'.encode("latin-1")),
                        ("deep-list", b"[" * 100000 + b"]" * 100000),
                        ("deep-object", b'{"a":' * 50000 + b"1" + b"}" * 50000),
                        ("nan", json.dumps({**g.doc, "scene": float("nan")}).encode()),
                        ("bom", b"\xef\xbb\xbf" + json.dumps(g.doc).encode()),
                        ("utf16", json.dumps(g.doc).encode("utf-16")),
                        ("nul", b"\0" * 64)):
        cases[f"json-{label}"] = glb_bytes(None, g.bin, json_bytes=text)
    # -- random byte flips in the JSON (mostly invalid JSON) and digit swaps (valid JSON, wrong numbers)
    text = json.dumps(g.doc).encode()
    digits = [i for i, c in enumerate(text) if chr(c).isdigit()]
    for i in range(14):
        flipped = bytearray(text)
        for pos in rng.integers(0, len(text), rng.integers(1, 5)):
            flipped[pos] = int(rng.integers(0, 256))
        cases[f"json-flip-{i}"] = glb_bytes(None, g.bin, json_bytes=flipped)
    for i in range(24):
        swapped = bytearray(text)
        for pos in rng.choice(digits, rng.integers(1, 4)):
            swapped[pos] = ord(str(int(rng.integers(0, 10))))
        cases[f"json-digits-{i}"] = glb_bytes(None, g.bin, json_bytes=swapped)
    # -- random byte flips in the BIN chunk (indices, vertices, image)
    for i in range(16):
        flipped = bytearray(g.bin)
        for pos in rng.integers(0, len(flipped), rng.integers(1, 32)):
            flipped[pos] = int(rng.integers(0, 256))
        cases[f"bin-flip-{i}"] = glb_bytes(g.doc, flipped)
    for region, accessor in (("indices", g.indices), ("positions", g.position), ("normals", g.normal),
                             ("texcoords", g.texcoord)):
        start = g.data_offset(accessor)
        for i in range(3):
            flipped = bytearray(g.bin)
            for pos in rng.integers(start, start + 96, 6):
                flipped[pos] = 0xFF if i == 0 else int(rng.integers(0, 256))
            cases[f"bin-flip-{region}-{i}"] = glb_bytes(g.doc, flipped)
    # positions set to float32 extremes: NaN, Inf, max float, denormals
    pos_start = g.data_offset(g.position)
    for label, value in (("nan", np.nan), ("inf", np.inf), ("fmax", np.finfo(np.float32).max), ("denormal", 1e-45)):
        edited = bytearray(g.bin)
        struct.pack_into("<fff", edited, pos_start, value, value, -value if label != "nan" else value)
        cases[f"bin-position-{label}"] = glb_bytes(g.doc, edited)
    edited = bytearray(g.bin)
    n = g.vertex_count()
    stride = g.view_of(g.position).get("byteStride", 12)
    for v in range(n):
        struct.pack_into("<fff", edited, pos_start + v * stride, *(np.float32(3e38) * np.sign(rng.standard_normal(3))))
    cases["bin-position-all-fmax"] = glb_bytes(g.doc, edited)
    # -- structured edits of the JSON (and BIN)
    for label, edit in _structured_edits().items():
        g = Glb(raw)
        edit(g)
        cases[label] = g.glb()
    return {f"{name}-{label}.glb": data for label, data in cases.items()}


# ---------------------------------------------------------------------------- OBJ / PLY / STL / OFF
def mesh_cases(rng) -> dict[str, bytes]:
    import trimesh

    cases = {}
    exts = (".obj", ".ply", ".stl", ".off")
    for ext in exts:
        cases[f"empty{ext}"] = b""
        cases[f"whitespace{ext}"] = b" \n\n\t\n"
        for i, size in enumerate((1, 7, 84, 300, 5000)):
            cases[f"random-{i}{ext}"] = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        cases[f"random-text{ext}"] = bytes(rng.choice(list(b"0123456789 .-e\nfv#"), 3000).tolist())
    # small real meshes in every format (binary and ASCII), whole and truncated
    small = trimesh.creation.icosphere(subdivisions=1)
    written = {
        "ico.obj": small.export(file_type="obj").encode(),
        "ico-ascii.ply": small.export(file_type="ply", encoding="ascii"),
        "ico-binary.ply": small.export(file_type="ply", encoding="binary"),
        "ico-ascii.stl": small.export(file_type="stl_ascii").encode(),
        "ico-binary.stl": small.export(file_type="stl"),
        "ico.off": small.export(file_type="off").encode(),
    }
    for name, data in written.items():
        stem, ext = os.path.splitext(name)
        cases[name] = data
        for frac in (0.05, 0.3, 0.5, 0.77, 0.999):
            cases[f"{stem}-trunc-{frac}{ext}"] = data[: int(len(data) * frac)]
        for i in range(4):
            flipped = bytearray(data)
            for pos in rng.integers(0, len(flipped), rng.integers(1, 12)):
                flipped[pos] = int(rng.integers(0, 256))
            cases[f"{stem}-flip-{i}{ext}"] = bytes(flipped)
    # real meshes: Suzanne (CC0 glTF) written as OBJ with UVs and normals, and two files as shipped
    suzanne = trimesh.load(ASSETS / "gltf/Suzanne/glTF/Suzanne.gltf", force="mesh")
    real = {"suzanne.obj": suzanne.export(file_type="obj").encode()}
    real.update((os.path.basename(name), mesh_file(name).read_bytes())
                for name in ("bunny-decimated.off", "spot/spot_triangulated.obj"))
    for name, data in real.items():
        stem, ext = os.path.splitext(name)
        for frac in (0.0005, 0.01, 0.1, 0.5, 0.9):
            cases[f"{stem}-trunc-{frac}{ext}"] = data[: int(len(data) * frac)]
        cut = int(rng.integers(1, len(data)))
        cases[f"{stem}-trunc-rand{ext}"] = data[:cut]
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    obj = {
        "face-1e9": tri + "f 1 2 1000000000\n",
        "face-neg-1e9": tri + "f 1 2 -1000000000\n",
        "face-zero": tri + "f 0 1 2\n",
        "face-4": tri + "f 1 2 4\n",
        "face-relative": tri + "f -3 -2 -1\n",
        "face-2p63": tri + "f 1 2 9223372036854775808\n",
        "face-text": tri + "f a b c\n",
        "face-one-index": tri + "f 1\n",
        "face-huge-polygon": tri + "f " + " ".join(["1", "2", "3"] * 2000) + "\n",
        "face-bad-uv": tri + "vt 0 0\nf 1/1 2/5 3/1000000000\n",
        "face-bad-normal": tri + "vn 0 0 1\nf 1//1 2//9 3//1\n",
        "vertex-nan": "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-inf": "v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-neg-inf": "v 0 -inf 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-1e39": "v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-1e300": "v 1e300 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-all-1e38": "v 3e38 3e38 3e38\nv -3e38 0 0\nv 0 -3e38 0\nf 1 2 3\n",
        "vertex-unused-nan": tri + "v nan nan nan\nf 1 2 3\n",
        "vertex-short": "v 1\nv 1 0\nv 0 1 0\nf 1 2 3\n",
        "vertex-text": "v a b c\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "normal-nan": tri + "vn nan 0 1\nf 1//1 2//1 3//1\n",
        "normal-zero": tri + "vn 0 0 0\nf 1//1 2//1 3//1\n",
        "uv-nan": tri + "vt nan inf\nf 1/1 2/1 3/1\n",
        "uv-huge": tri + "vt 1e30 -1e30\nf 1/1 2/1 3/1\n",
        "no-faces": tri,
        "comments-only": "# nothing here\n# at all\n",
        "degenerate-face": "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n",
        "mtllib-missing": "mtllib nope.mtl\nusemtl x\n" + tri + "f 1 2 3\n",
        "mtllib-self": f"mtllib {SELF}\nusemtl x\n" + tri + "f 1 2 3\n",  # the file as its own .mtl
    }
    for label, text in obj.items():
        cases[f"{label}.obj"] = text.encode()
    ply_header = "ply\nformat ascii 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n" \
                 "element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    verts = "0 0 0\n1 0 0\n0 1 0\n"
    ply = {
        "face-1e9": ply_header.format(nv=3, nf=1) + verts + "3 0 1 1000000000\n",
        "face-neg": ply_header.format(nv=3, nf=1) + verts + "3 0 1 -5\n",
        "vertex-count-1e12": ply_header.format(nv=10**12, nf=1) + verts + "3 0 1 2\n",
        "face-count-1e12": ply_header.format(nv=3, nf=10**12) + verts + "3 0 1 2\n",
        "vertex-count-neg": ply_header.format(nv=-3, nf=1) + verts + "3 0 1 2\n",
        "vertex-nan": ply_header.format(nv=3, nf=1) + "nan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        "no-faces": ply_header.format(nv=3, nf=0) + verts,
        "list-length-huge": ply_header.format(nv=3, nf=1) + verts + "255 0 1 2\n",
        "header-only": "ply\nformat ascii 1.0\nend_header\n",
        "format-unknown": "ply\nformat sideways 9.0\nend_header\n",
    }
    for label, text in ply.items():
        cases[f"{label}.ply"] = text.encode()
    binary_header = ("ply\nformat binary_little_endian 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
    body = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    cases["binary-face-2p31.ply"] = binary_header.format(nv=3).encode() + body + b"\x03" + np.array(
        [0, 1, 2**31 - 1], "<i4").tobytes()
    cases["binary-face-neg.ply"] = binary_header.format(nv=3).encode() + body + b"\x03" + np.array(
        [0, 1, -2**31], "<i4").tobytes()
    cases["binary-vertex-count-2p40.ply"] = binary_header.format(nv=2**40).encode() + body
    stl_tri = np.zeros(1, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    stl_tri["v"] = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    for label, count in (("count-max", 2**32 - 1), ("count-zero", 0), ("count-2", 2)):
        cases[f"binary-{label}.stl"] = b"\0" * 80 + struct.pack("<I", count) + stl_tri.tobytes()
    nan_tri = stl_tri.copy()
    nan_tri["v"][0, 0] = [np.nan, np.inf, 0]
    cases["binary-nan.stl"] = b"\0" * 80 + struct.pack("<I", 1) + nan_tri.tobytes()
    cases["ascii-nan.stl"] = (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                              b"endloop\nendfacet\nendsolid x\n")
    cases["solid-then-binary.stl"] = b"solid " + b"\0" * 74 + struct.pack("<I", 1) + stl_tri.tobytes()
    off = {
        "face-1e9": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1000000000\n",
        "face-neg": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n",
        "counts-huge": "OFF\n1000000000000 1000000000000 0\n0 0 0\n",
        "counts-neg": "OFF\n-3 -1 0\n0 0 0\n",
        "vertex-nan": "OFF\n3 1 0\nnan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        "no-faces": "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n",
        "header-only": "OFF\n",
        "face-short": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0\n",
        "polygon-huge": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n100000 0 1 2\n",
    }
    for label, text in off.items():
        cases[f"{label}.off"] = text.encode()
    return cases


def make_cases(folder: Path, rng) -> list[str]:
    cases = {}
    cases.update(glb_cases("duck", DUCK.read_bytes(), rng))
    cases.update(glb_cases("box", BOX.read_bytes(), rng))
    cases.update(mesh_cases(rng))
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in cases.items():
        if name.split(".")[0].endswith("-self"):  # cases that refer to their own file
            data = data.replace(SELF.encode(), name.encode())
        (folder / name).write_bytes(data)
    return sorted(cases)


# ---------------------------------------------------------------------------- the child process
WORKER = textwrap.dedent(r"""
    import faulthandler, os, resource, sys, warnings
    folder, names, case_timeout = sys.argv[1], sys.argv[2].split("\n"), float(sys.argv[3])
    # Huge allocations must fail (MemoryError) rather than take the machine down.
    ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    limit = max(4 << 30, min(16 << 30, ram))
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    faulthandler.enable()
    warnings.simplefilter("ignore")
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    wp.init()
    import pbrwarp as pw

    def one_line(text):
        return " ".join(str(text).split())[:300]

    for name in names:
        print("BEGIN\t" + name, flush=True)
        faulthandler.dump_traceback_later(case_timeout, exit=True)
        try:
            scene = pw.Scene.load(os.path.join(folder, name))
        except pw.PbrwarpError as err:
            outcome, detail = "error:" + type(err).__name__, one_line(err)
        except BaseException as err:
            outcome, detail = "RAW:" + type(err).__module__ + "." + type(err).__qualname__, one_line(err)
        else:
            try:
                scene.add_light(pw.DirectionalLight(direction=(-0.3, -0.5, -1.0), intensity=3.0))
                frame = pw.render(scene, width=16, height=16, progress=False)
                report = pw.check(frame)
                outcome = "loaded" if report.ok else "BADFRAME"
                detail = f"{scene.triangle_count} triangles; {report}"
            except pw.PbrwarpError as err:
                outcome, detail = "render-error:" + type(err).__name__, one_line(err)
            except BaseException as err:
                outcome = "RAW-RENDER:" + type(err).__module__ + "." + type(err).__qualname__
                detail = one_line(err)
        faulthandler.cancel_dump_traceback_later()
        print(f"RESULT\t{name}\t{outcome}\t{detail}", flush=True)
    print("DONE", flush=True)
""")


def run_worker(folder: Path, names: list[str]) -> tuple[subprocess.CompletedProcess, dict]:
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    proc = subprocess.run([sys.executable, "-c", WORKER, str(folder), "\n".join(names), str(CASE_TIMEOUT_S)],
                          capture_output=True, text=True, timeout=TOTAL_TIMEOUT_S, env=env)
    results, began = {}, []
    for line in proc.stdout.splitlines():
        parts = line.split("\t")
        if parts[0] == "BEGIN":
            began.append(parts[1])
        elif parts[0] == "RESULT":
            results[parts[1]] = (parts[2], parts[3] if len(parts) > 3 else "")
    return proc, results, began


@pytest.fixture(scope="module")
def fuzz_results(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    names = make_cases(folder, np.random.default_rng(20240611))
    proc, results, began = run_worker(folder, names)
    return names, proc, results, began


def test_child_process_survives_every_case(fuzz_results):
    names, proc, results, began = fuzz_results
    unfinished = [n for n in began if n not in results]
    assert proc.returncode == 0 and proc.stdout.rstrip().endswith("DONE"), (
        f"the loader child died (exit {proc.returncode}) during {unfinished or 'start-up'}:\n{proc.stderr[-3000:]}")
    assert sorted(results) == sorted(names)


def test_every_case_loads_or_raises_a_pbrwarp_error(fuzz_results):
    names, proc, results, began = fuzz_results
    allowed = ("loaded", "error:", "render-error:")
    bad = {n: r for n, r in results.items() if not r[0].startswith(allowed)}
    assert not bad, "\n".join(f"{n}: {o} {d}" for n, (o, d) in sorted(bad.items()))


# Files that load but that render() refuses, by design: light intensities and emission finite in
# float64 but beyond float32, which the render step checks (gpu_scene) rather than the loader; and
# vertices near float32's maximum, which no camera framing them can stand within float32 to see.
RENDER_REJECTS = ("-light-point-huge.glb", "-factor-emissive-strength-huge.glb", "-position-fmax.glb",
                  "-position-all-fmax.glb", "vertex-all-1e38.obj")


def test_every_loaded_case_renders_finite(fuzz_results):
    """A file that loads renders: nothing reaches Warp that makes NaN, Inf or negative pixels
    (``BADFRAME`` and ``RAW-RENDER`` outcomes fail the test above), and render() raises nothing
    except for the float32-range cases in RENDER_REJECTS."""
    names, proc, results, began = fuzz_results
    render_errors = {n: r for n, r in results.items() if r[0].startswith("render-error:")}
    unexpected = {n: r for n, r in render_errors.items() if not n.endswith(RENDER_REJECTS)}
    assert not unexpected, "\n".join(f"{n}: {o} {d}" for n, (o, d) in sorted(unexpected.items()))
    for name, (outcome, detail) in render_errors.items():
        assert outcome == "render-error:InputError" and "float32" in detail, (name, outcome, detail)


def test_the_fuzz_cases_exercise_both_outcomes(fuzz_results):
    """The corpus is not all rejections: intact and harmlessly edited files still load."""
    names, proc, results, began = fuzz_results
    outcomes = [o for o, _ in results.values()]
    assert outcomes.count("loaded") >= 20
    assert sum(o.startswith("error:") for o in outcomes) >= 0.5 * len(outcomes)
    for name in ("ico.obj", "ico-binary.ply", "ico-ascii.stl", "ico.off", "box-image-1x1.glb",
                 "box-chunk-extra-unknown-patched.glb"):
        assert results[name][0] == "loaded", (name, results[name])


# ---------------------------------------------------------------------------- bugs the fuzzer found
# In process, with the message checked: each of these raised a raw exception, allocated gigabytes,
# loaded something wrong or failed only at render time before the loader fix.
def _box_with(tmp_path, edit, name="case.glb") -> Path:
    g = Glb(BOX.read_bytes())
    edit(g)
    path = tmp_path / name
    path.write_bytes(g.glb())
    return path


def _no_view_huge_count(g):
    acc = g.acc(g.position)
    del acc["bufferView"]
    acc["count"] = 2**40  # so big that, unfixed, it is a MemoryError, not 24 GB of pages in this process


@pytest.mark.parametrize("edit, message", [
    (_no_view_huge_count, "no bufferView and count 1099511627776"),
    (lambda g: struct.pack_into("<f", g.bin, g.data_offset(g.position) + 4, float("nan")),
     "POSITION of mesh 0 primitive 0 has NaN or Inf"),
    (lambda g: g.doc["nodes"][-1].update(mesh=99), "node 1 refers to meshes\\[99\\]"),
    (lambda g: g.prim.update(mode="4"), "invalid mode '4'"),
    (lambda g: g.doc.update(nodes={"0": {}}), "'nodes' must be an array"),
    (lambda g: g.doc["materials"][0].update(doubleSided="false"), "doubleSided must be true or false"),
    (lambda g: g.doc["nodes"][-1].update(rotation=[1e300, 0, 0, 1e300]), "glTF rotations are unit quaternions"),
    (lambda g: g.doc["nodes"][-1].update(rotation=[1e-200, 0, 0, 1e-200]), "glTF rotations are unit quaternions"),
    (lambda g: g.doc["nodes"][-1].update(scale=[1e39, 1, 1]), "exceed the float32 range"),
], ids=["zero-filled-2p40", "nan-position", "node-mesh-99", "mode-str", "nodes-dict", "double-sided-str",
        "rotation-1e300", "rotation-1e-200", "scale-1e39"])
def test_fixed_gltf_cases_raise_asset_format_error(tmp_path, edit, message):
    import pbrwarp as pw

    with pytest.raises(pw.AssetFormatError, match=f"case.glb.*{message}"):
        pw.Scene.load(_box_with(tmp_path, edit))


def test_deeply_nested_json_is_an_asset_format_error(tmp_path):
    import pbrwarp as pw

    path = tmp_path / "deep.gltf"
    path.write_bytes(b"[" * 100000 + b"]" * 100000)
    with pytest.raises(pw.AssetFormatError, match="deep.gltf.*nested too deeply"):
        pw.Scene.load(path)


def test_slightly_non_unit_rotation_is_normalized(tmp_path):
    """Rotations a little off unit length still load, turned as their unit quaternion."""
    import pbrwarp as pw

    s = math.sqrt(0.5)
    scenes = [pw.Scene.load(_box_with(tmp_path, lambda g, k=k: g.doc["nodes"][-1].update(rotation=[s * k, 0, 0, s * k]),
                                      name=f"rot{k}.glb")) for k in (1.0, 1.001)]
    np.testing.assert_allclose(scenes[0].primitives[0].positions, scenes[1].primitives[0].positions, atol=1e-12)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # trimesh's, on the overflowing and NaN values
@pytest.mark.parametrize("text, message", [
    ("v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "exceed the float32 range"),
    ("v 1e300 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "exceed the float32 range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 1\nf 1//1 2//1 3//1\n", "normals contains NaN"),
])
def test_fixed_obj_cases_raise_asset_format_error_naming_the_file(tmp_path, text, message):
    import pbrwarp as pw

    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(pw.AssetFormatError, match=f"bad.obj.*{message}"):
        pw.Scene.load(path)
