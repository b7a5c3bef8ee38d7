"""What pbrwarp honours of a glTF file, and the notes naming what it does not.

Every glTF extension pbrwarp knows has an entry in ``_EXTENSIONS`` with its status and, when it
is ignored, what is rendered instead; each core feature pbrwarp does not honour has a ``_note_*``
function that notes the elements using it. ``_note_unhonoured`` runs them all over a loaded
document; the reader (pbrwarp/gltf.py) adds the notes it can only make where it reads (texture
coordinate sets, camera types, morph target attributes). docs/loading.md tables the same.
The ``doc`` the functions take is the reader's document (pbrwarp.gltf._Document): its ``json``
and its ``notes`` (a ``_Notes``).
"""

from __future__ import annotations

from collections import deque

_TRIANGLES = 4  # glTF's default primitive mode

# Every glTF extension pbrwarp knows and what it does with it (docs/loading.md tables the same):
# HONOURED, read as the extension specifies; PARTLY, read but for a property that is noted where a
# file uses it (rough KHR_materials_transmission: _note_rough_transmission); NO_EFFECT, nothing a
# still image shows (metadata, interaction); IGNORED, dropped with a warning saying what is
# rendered instead (the entry's text). A file may require (extensionsRequired) any extension but
# an IGNORED one; an extension pbrwarp does not know is IGNORED.
HONOURED, PARTLY, NO_EFFECT, IGNORED = "honoured", "partly honoured", "no visual effect", "ignored"
_EXTENSIONS = {
    "KHR_lights_punctual": (HONOURED, ""),
    "KHR_materials_emissive_strength": (HONOURED, ""),
    "KHR_materials_ior": (HONOURED, ""),
    "KHR_materials_specular": (HONOURED, ""),
    "KHR_texture_transform": (HONOURED, ""),
    "KHR_xmp_json_ld": (NO_EFFECT, "metadata"),
    "KHR_xmp": (NO_EFFECT, "metadata (the draft name of KHR_xmp_json_ld)"),
    "KHR_node_hoverability": (NO_EFFECT, "interaction"),
    "KHR_node_selectability": (NO_EFFECT, "interaction"),
    "KHR_animation_pointer": (IGNORED, "its animations are not played; the stored values are shown"),
    "KHR_draco_mesh_compression": (HONOURED, "decoded by DracoPy, the draco extra (pbrwarp/gltf_draco.py)"),
    "KHR_materials_anisotropy": (HONOURED, ""),
    "KHR_materials_clearcoat": (HONOURED, ""),
    "KHR_materials_diffuse_transmission": (IGNORED, "rendered opaque (no light passes through)"),
    "KHR_materials_dispersion": (IGNORED, "rendered without dispersion"),
    "KHR_materials_iridescence": (HONOURED, ""),
    "KHR_materials_pbrSpecularGlossiness": (IGNORED, "rendered with the material's metallic-roughness values"),
    "KHR_materials_sheen": (HONOURED, ""),
    "KHR_materials_transmission": (PARTLY, "objects seen through rough surfaces are not blurred but by the exact rung"),
    "KHR_materials_unlit": (HONOURED, ""),
    "KHR_materials_variants": (IGNORED, "each primitive shows its default material"),
    "KHR_materials_volume": (HONOURED, ""),
    "KHR_mesh_quantization": (HONOURED, ""),
    "KHR_meshopt_compression": (IGNORED, "the uncompressed fallback buffers are read instead"),
    "EXT_meshopt_compression": (IGNORED, "the uncompressed fallback buffers are read instead"),
    "KHR_node_visibility": (HONOURED, ""),
    "KHR_texture_basisu": (HONOURED, "decoded by opengl-basisu, the ktx2 extra (pbrwarp/gltf_basisu.py)"),
    "EXT_texture_webp": (HONOURED, ""),
    "EXT_texture_avif": (IGNORED, "the textures' fallback PNG or JPEG images are used"),
    "MSFT_texture_dds": (IGNORED, "the textures' fallback PNG or JPEG images are used"),
    "EXT_mesh_gpu_instancing": (HONOURED, ""),
    "EXT_lights_image_based": (IGNORED, "no environment lighting from the file (set scene.environment)"),
    "MSFT_lod": (IGNORED, "the most detailed level is shown"),
}
_UNKNOWN_EXTENSION = (IGNORED, "pbrwarp does not know this extension")
_SUPPORTED_EXTENSIONS = frozenset(name for name, (status, _) in _EXTENSIONS.items() if status != IGNORED)

# Sampler magnification filters (glTF 2.0, "Filtering"): code -> (name, honoured). pbrwarp filters
# every texture bilinearly, so NEAREST magnification (pixel art's sharp texels) is not honoured.
# Minification filters are not noted: without mip-maps glTF's fallback for the LINEAR_MIPMAP
# modes is LINEAR, which pbrwarp does, and for the NEAREST ones NEAREST, which differs from it
# only in which texel of a many-texel footprint is taken (docs/loading.md).
_MAG_FILTERS = {9728: ("NEAREST", False), 9729: ("LINEAR", True)}
_SKIPPED_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips"}  # rendered without them
# Top-level arrays whose elements own the extension objects inside them, by singular noun.
_OWNER_NOUNS = {"accessors": "accessor", "animations": "animation", "buffers": "buffer", "bufferViews": "bufferView",
                "cameras": "camera", "images": "image", "materials": "material", "meshes": "mesh", "nodes": "node",
                "samplers": "sampler", "scenes": "scene", "skins": "skin", "textures": "texture"}


class _Notes:
    """What one load found in a file that pbrwarp does not honour, gathered by kind: one message
    per kind, saying how many things of that kind there are and naming the first few."""

    SHOWN = 3

    def __init__(self, path: str):
        self.path = path
        self._kinds: dict[str, tuple[str, str | None, dict]] = {}  # kind -> (text, noun, {key: shown})

    def add(self, kind: str, text: str, noun: str | None = None, key=None, shown: str | None = None):
        """Note the thing ``key`` (a ``noun``, e.g. "material", shown as ``shown``, e.g.
        "'cloth'") under ``kind``. ``text`` is the kind's message, with ``{subjects}`` where the
        things noted go ("material 'cloth'", "3 materials ('cloth', 2, 'felt')"). Without a
        ``noun`` the note is about the file as a whole."""
        _, _, things = self._kinds.setdefault(kind, (text, noun, {}))
        if noun is not None:
            things.setdefault(key, str(key) if shown is None else shown)

    def messages(self) -> tuple[str, ...]:
        """The messages, in the order their kinds were first noted, each naming the file."""
        return tuple(f"{self.path}: " + text.replace("{subjects}", self._subjects(noun, list(things.values())))
                     for text, noun, things in self._kinds.values())

    def _subjects(self, noun: str | None, shown: list[str]) -> str:
        if noun is None or not shown:
            return ""
        if len(shown) == 1:
            return f"{noun} {shown[0]}"
        plural = noun + ("es" if noun.endswith(("sh", "ch", "s", "x")) else "s")
        listed = ", ".join(shown[: self.SHOWN]) + (", ..." if len(shown) > self.SHOWN else "")
        return f"{len(shown)} {plural} ({listed})"


def _ident(item, index) -> str:
    """How a note shows a glTF element: its name, quoted, or its index where it has none."""
    name = item.get("name") if isinstance(item, dict) else None
    if isinstance(name, str) and name:
        return repr(name if len(name) <= 40 else name[:37] + "...")
    return str(index)


def _elements(doc, kind: str) -> list[tuple[int, dict]]:
    """(index, element) of every object in the top-level array ``kind`` (none if it is not one)."""
    items = doc.json.get(kind, [])
    return [(i, item) for i, item in enumerate(items) if isinstance(item, dict)] if isinstance(items, list) else []


def _note_unhonoured(doc, nodes: list):
    """Note (doc.notes) everything in the file that pbrwarp does not honour; the reader notes the
    rest where it reads it (texture coordinate sets in _Materials._texture, camera types in
    _node_camera, morph target attributes in _morph_targets). ``nodes``: the default scene's (_scene_nodes)."""
    _note_extensions(doc)
    _note_scenes(doc)
    _note_animations(doc)
    _note_points_and_lines(doc, nodes)
    _note_sampler_filters(doc)
    _note_rough_transmission(doc)


def _note_extensions(doc):
    """Each IGNORED extension (_EXTENSIONS) the file uses, with the elements that use it."""
    owners: dict[str, list] = {}  # extension -> [(noun, index, shown)], the file itself as noun None
    for name, owner in _extension_uses(doc.json):
        owners.setdefault(name, []).append(owner)
    listed = doc.json.get("extensionsUsed", [])
    for name in listed if isinstance(listed, list) else []:
        owners.setdefault(str(name), [])
    for name, found in owners.items():
        status, instead = _EXTENSIONS.get(name, _UNKNOWN_EXTENSION)
        if status != IGNORED:
            continue
        elements = [owner for owner in found if owner[0] is not None]
        if not elements:
            doc.notes.add(f"extension {name}", f"{name} ignored: {instead}")
        for noun, index, shown in elements:
            doc.notes.add(f"extension {name}", f"{name} on {{subjects}} ignored: {instead}", noun, index, shown)


def _extension_uses(gltf: dict) -> list[tuple[str, tuple]]:
    """(extension name, owner) for every extension object in the file, ``extras`` aside; the
    owner is the top-level element holding it, (noun, index, shown), or (None, None, None) for
    the file's root. Walked breadth first without recursion (any JSON nesting depth is safe)."""
    root = (None, None, None)
    uses, pending = [], deque()
    for key, value in gltf.items():
        if key in _OWNER_NOUNS and isinstance(value, list):
            pending.extend((item, (_OWNER_NOUNS[key], i, _ident(item, i))) for i, item in enumerate(value))
        elif key != "extras":
            pending.append(({key: value} if key == "extensions" else value, root))
    while pending:
        value, owner = pending.popleft()
        if isinstance(value, dict):
            extensions = value.get("extensions")
            if isinstance(extensions, dict):
                uses.extend((str(name), owner) for name in extensions)
            pending.extend((v, owner) for k, v in value.items() if k != "extras" and isinstance(v, (dict, list)))
        elif isinstance(value, list):
            pending.extend((v, owner) for v in value if isinstance(v, (dict, list)))
    return uses


def _note_scenes(doc):
    scenes = doc.json.get("scenes", [])
    if isinstance(scenes, list) and len(scenes) > 1:
        index = doc.json.get("scene", 0)  # a valid index: _scene_nodes checked it
        why = "the default" if "scene" in doc.json else "the first; the file names no default"
        doc.notes.add("scenes", f"the file has {len(scenes)} scenes; only scene {_ident(scenes[index], index)} "
                      f"({why}) is loaded")


def _note_animations(doc):
    for index, animation in _elements(doc, "animations"):
        doc.notes.add("animations", "{subjects} not played: the static pose the nodes store (their "
                      "transforms and morph weights) is shown", "animation", index, _ident(animation, index))


def _placed_primitives(doc, nodes: list, modes) -> list[tuple[int, int, dict]]:
    """(mesh index, primitive index, mesh) of each primitive drawn in one of ``modes`` that the
    scene's nodes place, each once."""
    found = {}
    for index, _ in nodes:
        node = doc.json["nodes"][index]
        if "mesh" in node:
            mesh = doc.json["meshes"][node["mesh"]]
            for pi, prim in enumerate(mesh.get("primitives", [])):
                if prim.get("mode", _TRIANGLES) in modes:
                    found.setdefault((node["mesh"], pi), (node["mesh"], pi, mesh))
    return list(found.values())


def _note_points_and_lines(doc, nodes: list):
    for mi, pi, mesh in _placed_primitives(doc, nodes, _SKIPPED_MODES):
        name = _SKIPPED_MODES[mesh["primitives"][pi].get("mode")]
        doc.notes.add(f"mode {name}", f"{{subjects}} drawn as {name} skipped: pbrwarp renders triangles only",
                      "primitive", (mi, pi), f"{pi} of mesh {_ident(mesh, mi)}")


def _note_sampler_filters(doc):
    for index, sampler in _elements(doc, "samplers"):
        code = sampler.get("magFilter", 9729)
        name, honoured = _MAG_FILTERS.get(code, (repr(code), False)) if isinstance(code, int) else (repr(code), False)
        if not honoured:
            doc.notes.add(f"magFilter {name}", f"magFilter {name} of {{subjects}} not honoured: their textures are "
                          "filtered bilinearly (texels blend rather than show as sharp squares)",
                          "sampler", index, _ident(sampler, index))



def _note_rough_transmission(doc):
    """Transmissive materials whose roughness is not 0: the default rung blurs only the
    environment seen through them (docs/materials.md "Transmission")."""
    for index, material in _elements(doc, "materials"):
        extensions = material.get("extensions")
        transmission = extensions.get("KHR_materials_transmission") if isinstance(extensions, dict) else None
        if not isinstance(transmission, dict) or transmission.get("transmissionFactor", 0.0) == 0.0:
            continue
        pbr = material.get("pbrMetallicRoughness")
        pbr = pbr if isinstance(pbr, dict) else {}
        if pbr.get("roughnessFactor", 1.0) != 0.0:
            doc.notes.add("rough transmission", "objects seen through {subjects} with roughness above 0 not blurred "
                          "(KHR_materials_transmission): only the environment seen through them is, but with Monte "
                          "Carlo environment lighting (quality='reference')", "material", index, _ident(material, index))
