"""Hostile files: a model reads nothing outside its folder, and no small file makes a load
allocate or walk without bound (docs/loading.md).

Every crafted file is written here, on the spot. URI cases record, with an audit hook, every
file the process opens during the load and assert that none lies outside the model's folder.
Memory-bomb cases load in a child process under an address-space limit (RLIMIT_AS) and a
timeout, and the child reports its peak resident memory before and after the load; node-graph
cases load in a child with a timeout, so a hang fails the test instead of stalling the suite.
"""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import pbrwarp as pw
from pbrwarp.gltf import load_gltf

from test_gltf import Builder

# ---------------------------------------------------------------------------- files opened
_OPENED: list[str] | None = None  # paths opened while recording, else None


def _audit(event, args):
    if _OPENED is not None and event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENED.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)


def load_recording_opens(path, **kwargs):
    """(the error Scene.load raised or the scene it returned, every path opened meanwhile)."""
    global _OPENED
    _OPENED = []
    try:
        try:
            result = pw.Scene.load(path, **kwargs)
        except pw.PbrwarpError as err:
            result = err
        return result, list(_OPENED)
    finally:
        _OPENED = None


def assert_opened_only_inside(opened, folder: Path, model: Path):
    root = os.path.realpath(folder)
    for path in opened:
        real = os.path.realpath(path)
        inside = os.path.commonpath([real, root]) == root
        python_files = real.endswith((".py", ".pyc", ".so")) or "site-packages" in real  # lazy imports
        assert inside or python_files, f"loading {model.name} opened {path} outside {root}"


# ---------------------------------------------------------------------------- URIs
SECRET = b"outside the model's folder"


@pytest.fixture
def folders(tmp_path):
    """(model folder, a folder beside it holding secret.bin and secret.png)."""
    model, outside = tmp_path / "model", tmp_path / "outside"
    model.mkdir()
    outside.mkdir()
    (outside / "secret.bin").write_bytes(SECRET * 100)
    Image.fromarray(np.full((2, 2, 3), 200, np.uint8)).save(outside / "secret.png")
    return model, outside


def textured_quad_gltf(folder: Path, buffer_uri=None, image_uri=None, name="model.gltf") -> Path:
    """A .gltf of a textured quad whose buffer (default: a data: URI) and image (default: none)
    have the given URIs; the buffer's bytes are also written to ``buffer.bin`` beside it."""
    b = Builder()
    material = None
    if image_uri is not None:
        b.json["images"] = [{"uri": image_uri}]
        b.json["textures"] = [{"source": 0}]
        b.json["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        material = 0
    b.node(mesh=b.quad(material=material))
    path = b.gltf(folder / name)
    (folder / "buffer.bin").write_bytes(bytes(b.bin))
    if buffer_uri is not None:
        b.json["buffers"][0]["uri"] = buffer_uri
        path.write_text(json.dumps(b.json))
    return path


def escaping_uris(outside: Path, ext: str) -> dict:
    """URIs of ``outside/secret.<ext>`` from a model folder beside ``outside``, each another way
    out, with the words the refusal must contain."""
    target = outside / f"secret.{ext}"
    return {
        "dot-dot": (f"../outside/secret.{ext}", "leads outside"),
        "deep-dot-dot": (f"sub/../../../{'../' * 20}{str(target).lstrip('/')}", "leads outside"),
        "absolute": (str(target), "absolute path outside"),
        "percent-dot-dot": (f"%2e%2e/outside/secret.{ext}", "leads outside"),
        "percent-slash": (f"%2E%2E%2Foutside%2Fsecret.{ext}", "leads outside"),
        "percent-absolute": ("%2F" + str(target).lstrip("/").replace("/", "%2F"), "absolute path outside"),
        "file-uri": (f"file://{target}", "scheme 'file:'"),
        "file-relative": (f"file:secret.{ext}", "scheme 'file:'"),
        "host": (f"//server/share/secret.{ext}", "names the host"),
        "backslash": (f"..\\outside\\secret.{ext}", "backslash"),
        "percent-backslash": (f"..%5coutside%5csecret.{ext}", "backslash"),
        "nul": (f"buffer.bin\0../outside/secret.{ext}", "NUL byte"),
        "percent-nul": (f"buffer.bin%00.{ext}", "NUL byte"),
        "symlink-file": (f"link.{ext}", "leads outside"),
        "symlink-folder": (f"linked/secret.{ext}", "leads outside"),
    }


@pytest.mark.parametrize("kind", ["buffer", "image"])
@pytest.mark.parametrize("case", list(escaping_uris(Path("/x"), "bin")))
def test_uri_leaving_the_model_folder_is_refused_before_any_file_is_opened(folders, kind, case):
    model, outside = folders
    ext = "bin" if kind == "buffer" else "png"
    (model / f"link.{ext}").symlink_to(outside / f"secret.{ext}")
    (model / "linked").symlink_to(outside, target_is_directory=True)
    uri, words = escaping_uris(outside, ext)[case]
    path = textured_quad_gltf(model, **{f"{kind}_uri": uri}) if kind == "buffer" else \
        textured_quad_gltf(model, image_uri=uri)
    result, opened = load_recording_opens(path)
    assert isinstance(result, pw.AssetFormatError), result
    assert f"{kind} 0 has URI" in str(result) and words in str(result), str(result)
    assert "model's folder" in str(result)
    assert_opened_only_inside(opened, model, path)
    assert str(outside / f"secret.{ext}") not in " ".join(opened)


@pytest.mark.parametrize("uri", ["buffer.bin", "sub/../buffer.bin", "./buffer.bin", "data%20file.bin", "inside-link.bin",
                                 None])
def test_uris_that_stay_inside_the_folder_load(folders, uri):
    model, _ = folders
    (model / "sub").mkdir()
    path = textured_quad_gltf(model)  # writes buffer.bin
    (model / "data file.bin").write_bytes((model / "buffer.bin").read_bytes())
    (model / "inside-link.bin").symlink_to(model / "buffer.bin")
    if uri is not None:  # None keeps the data: URI
        doc = json.loads(path.read_text())
        doc["buffers"][0]["uri"] = uri
        path.write_text(json.dumps(doc))
    result, opened = load_recording_opens(path)
    assert isinstance(result, pw.Scene) and result.triangle_count == 2
    assert_opened_only_inside(opened, model, path)


def test_allowed_roots_let_a_model_read_another_folder(folders):
    model, outside = folders
    path = textured_quad_gltf(model, image_uri="../outside/secret.png")
    with pytest.raises(pw.AssetFormatError, match="image 0 has URI '../outside/secret.png'.*leads outside"):
        pw.Scene.load(path)
    scene = pw.Scene.load(path, allowed_roots=[outside])
    texture = scene.primitives[0].material.base_color_texture
    assert texture.shape == (2, 2) and texture.rgba8[0, 0, 0] == 200
    # other folders stay closed
    with pytest.raises(pw.AssetFormatError, match="outside every folder of allowed_roots"):
        pw.Scene.load(textured_quad_gltf(model, image_uri="../../etc/passwd", name="other.gltf"),
                      allowed_roots=[outside])
    with pytest.raises(pw.AssetNotFoundError, match="not a folder"):
        pw.Scene.load(path, allowed_roots=[outside / "secret.png"])


def test_a_fifo_in_the_model_folder_is_refused_not_read(folders):
    """Opening a FIFO would block until a writer comes: it is not a regular file."""
    model, _ = folders
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    os.mkfifo(model / "pipe.bin")
    with pytest.raises(pw.AssetFormatError, match="pipe.bin, which is not a regular file"):
        pw.Scene.load(textured_quad_gltf(model, buffer_uri="pipe.bin"))


def test_obj_material_library_and_texture_outside_the_folder_are_refused(folders):
    model, outside = folders
    (outside / "evil.mtl").write_text("newmtl m\nKd 1 1 1\n")
    obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n"
    (model / "a.obj").write_text("mtllib ../outside/evil.mtl\n" + obj)
    result, opened = load_recording_opens(model / "a.obj")
    assert isinstance(result, pw.AssetFormatError) and "'../outside/evil.mtl'" in str(result), result
    assert_opened_only_inside(opened, model, model / "a.obj")
    (model / "m.mtl").write_text(f"newmtl m\nKd 1 1 1\nmap_Kd {outside / 'secret.png'}\n")
    (model / "b.obj").write_text("mtllib m.mtl\n" + obj)
    result, opened = load_recording_opens(model / "b.obj")
    assert isinstance(result, pw.AssetFormatError) and "absolute path outside" in str(result), result
    assert_opened_only_inside(opened, model, model / "b.obj")
    (model / "c.obj").write_text("mtllib missing.mtl\n" + obj)
    with pytest.warns(UserWarning, match="'missing.mtl', which does not exist"):
        assert pw.Scene.load(model / "c.obj").triangle_count == 1


# ---------------------------------------------------------------------------- memory bombs
def zero_png(width: int, height: int) -> bytes:
    """A valid 8-bit RGBA PNG of transparent black, built without holding its pixels: the
    deflate stream of all-zero scanlines is one compressed chunk repeated (each ends in a full
    flush, so it decodes the same anywhere in the stream), then an empty final block and the
    Adler-32 of the zeros (a = 1, b = n mod 65521: RFC 1950)."""
    row = 1 + 4 * width  # a filter byte, then the pixels
    rows_per_chunk = max(1, min(height, (1 << 22) // row))
    while height % rows_per_chunk:
        rows_per_chunk -= 1
    compressor = zlib.compressobj(9)
    chunk = bytes(row * rows_per_chunk)
    first = compressor.compress(chunk) + compressor.flush(zlib.Z_FULL_FLUSH)
    repeat = compressor.compress(chunk) + compressor.flush(zlib.Z_FULL_FLUSH)
    total = row * height
    adler = ((total % 65521) << 16) | 1
    stream = first + repeat * (height // rows_per_chunk - 1) + b"\x03\x00" + struct.pack(">I", adler)

    def png_chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", header) + png_chunk(b"IDAT", stream) + png_chunk(b"IEND", b"")


def test_zero_png_is_a_valid_png():
    img = Image.open(io.BytesIO(zero_png(3000, 1000)))  # four repeats of the compressed chunk
    img.load()
    assert img.size == (3000, 1000) and img.mode == "RGBA" and not np.asarray(img).any()


def glb_with_image(path: Path, png: bytes) -> Path:
    b = Builder()
    b.json["images"] = [{"bufferView": b.view(png), "mimeType": "image/png"}]
    b.json["textures"] = [{"source": 0}]
    b.json["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    b.node(mesh=b.quad(material=0))
    return b.glb(path)


LIMITED_LOAD = textwrap.dedent("""
    import json, resource, sys, time
    limit = int(sys.argv[2]) << 20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    def peak_mb():
        # this process's own peak (VmHWM); ru_maxrss would start at the parent's, kept across exec
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("VmHWM:")) / 1024

    import pbrwarp as pw
    before = peak_mb()
    start = time.perf_counter()
    try:
        pw.Scene.load(sys.argv[1])
        outcome = {"error": None}
    except BaseException as err:
        outcome = {"error": type(err).__name__, "message": str(err),
                   "pbrwarp": isinstance(err, pw.PbrwarpError)}
    outcome["seconds"] = time.perf_counter() - start
    outcome["rss_mb"] = [before, peak_mb()]
    print(json.dumps(outcome))
""")


def load_in_child(path: Path, memory_mb: int = 1536, timeout_s: float = 120) -> dict:
    """Scene.load(path) in a child process under RLIMIT_AS = memory_mb: its outcome, duration and
    peak resident memory (MB) before and after the load."""
    proc = subprocess.run([sys.executable, "-c", LIMITED_LOAD, str(path), str(memory_mb)], capture_output=True,
                          text=True, timeout=timeout_s, cwd=Path(__file__).resolve().parents[1])
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


EACH_LOAD = textwrap.dedent("""
    import json, resource, sys
    limit = 1536 << 20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    import pbrwarp as pw
    outcomes = {}
    for path in sys.argv[1:]:
        try:
            pw.Scene.load(path)
            outcomes[path] = "loaded"
        except pw.AssetFormatError:
            outcomes[path] = "refused"
        except BaseException as err:
            outcomes[path] = f"{type(err).__name__}: {err}"
    print(json.dumps(outcomes))
""")


def damaged_copies(raw: bytes, rng, header: int, copies: int = 20) -> list[bytes]:
    """Damaged copies of a valid stream ``raw``: the empty stream first, then ``copies`` each of
    truncations, copies with 1 to 5 bytes overwritten, and random bytes after its first
    ``header`` bytes."""
    ends = sorted(set(rng.integers(1, len(raw), copies).tolist()) | {header - 1, header})
    out = [b""] + [raw[:end] for end in ends]
    for _ in range(copies):
        flipped = bytearray(raw)
        for at in rng.integers(0, len(raw), rng.integers(1, 6)):
            flipped[at] = int(rng.integers(0, 256))
        out.append(bytes(flipped))
    return out + [raw[:header] + rng.integers(0, 256, len(raw) - header, dtype=np.uint8).tobytes()
                  for _ in range(copies)]


def load_each_in_child(paths: list[Path], timeout_s: float = 300) -> dict[str, str]:
    """Scene.load of each path, in one child process under RLIMIT_AS = 1536 MB that must exit
    normally (a crash in a decoder would kill it): "loaded", "refused" (an AssetFormatError) or
    the other error, by path; asserts that there was no other error."""
    proc = subprocess.run([sys.executable, "-c", EACH_LOAD, *map(str, paths)], capture_output=True, text=True,
                          timeout=timeout_s, cwd=Path(__file__).resolve().parents[1])
    assert proc.returncode == 0, proc.stderr[-3000:]
    outcomes = json.loads(proc.stdout.strip().splitlines()[-1])
    assert set(outcomes.values()) <= {"loaded", "refused"}, outcomes
    return outcomes


def assert_refused_small(outcome: dict, *words: str):
    assert outcome["error"] == "AssetFormatError" and outcome["pbrwarp"], outcome
    for word in words:
        assert word in outcome["message"], outcome["message"]
    before, after = outcome["rss_mb"]
    assert after - before < 100 and after < 600, f"peak resident memory {before:.0f} -> {after:.0f} MB"


def test_png_of_12000_squared_texels_is_refused_from_its_header(tmp_path):
    """The PNG is ~0.6 MB and decodes to 576 MB of RGBA (more with its conversions)."""
    path = glb_with_image(tmp_path / "bomb.glb", zero_png(12000, 12000))
    assert path.stat().st_size < 2 << 20
    assert_refused_small(load_in_child(path), "image 0 is 12000 x 12000 texels", "LoadLimits.max_texture_side")


def test_texture_side_and_texel_budget_limits(tmp_path):
    path = glb_with_image(tmp_path / "wide.glb", zero_png(8193, 1))
    with pytest.raises(pw.AssetFormatError, match="wide.glb: image 0 is 8193 x 1 texels.*max_texture_side"):
        pw.Scene.load(path)
    loaded = pw.Scene.load(path, limits=pw.LoadLimits(max_texture_side=8193))
    assert loaded.primitives[0].material.base_color_texture.shape == (1, 8193)
    small = glb_with_image(tmp_path / "small.glb", zero_png(16, 16))
    with pytest.raises(pw.AssetFormatError, match="image 0 .16 x 16. would bring .* 256, more than the 255 of "
                                                  "LoadLimits.max_texels"):
        pw.Scene.load(small, limits=pw.LoadLimits(max_texels=255))


def test_image_format_outside_the_list_is_refused(tmp_path):
    """Pillow opens many formats (EPS through Ghostscript); a glTF texture may be PNG or JPEG,
    and pbrwarp also reads WebP, GIF, BMP and TGA."""
    buf = io.BytesIO()
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(buf, format="TIFF")
    with pytest.raises(pw.AssetFormatError, match="image 0 cannot be decoded"):
        pw.Scene.load(glb_with_image(tmp_path / "tiff.glb", buf.getvalue()))


def test_zero_filled_accessor_of_2_26_elements_is_refused_before_allocating(tmp_path):
    """An accessor without a bufferView costs no bytes in the file."""
    b = Builder()
    mesh = b.quad()
    b.json["accessors"].append({"componentType": 5126, "type": "VEC4", "count": 2**26})
    b.json["meshes"][mesh]["primitives"][0]["attributes"]["TANGENT"] = len(b.json["accessors"]) - 1
    b.node(mesh=mesh)
    assert_refused_small(load_in_child(b.glb(tmp_path / "zeros.glb")),
                         "accessor 4 (TANGENT of mesh 0 primitive 0) has no bufferView and count 67108864",
                         "LoadLimits.max_vertices")


def test_unused_accessor_counts_are_checked_too(tmp_path):
    """trimesh reads every accessor, used or not."""
    b = Builder()
    b.node(mesh=b.quad())
    b.json["accessors"].append({"componentType": 5126, "type": "MAT4", "count": 2**40})
    with pytest.raises(pw.AssetFormatError, match="accessor 4 has no bufferView and count 1099511627776"):
        pw.Scene.load(b.glb(tmp_path / "unused.glb"))
    b.json["accessors"][-1].update(bufferView=0)
    with pytest.raises(pw.AssetFormatError, match="accessor 4 reads bytes 0..70368744177664 of bufferView 0"):
        pw.Scene.load(b.glb(tmp_path / "unused.glb"))


def mesh_placed(times: int, triangles: int) -> Builder:
    """A mesh of ``triangles`` triangles over 4 vertices, placed by ``times`` root nodes."""
    b = Builder()
    pos = b.accessor(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32), "VEC3")
    indices = b.accessor(np.tile([0, 1, 2], triangles), "SCALAR", 5123)
    b.json["meshes"].append({"primitives": [{"attributes": {"POSITION": pos}, "indices": indices}]})
    b.json["nodes"] = [{"mesh": 0, "translation": [i, 0, 0]} for i in range(times)]
    b.json["scenes"][0]["nodes"] = list(range(times))
    return b


def test_mesh_placed_20000_times_is_refused_before_instancing(tmp_path):
    """20,000 x 2,000 triangles: 40 million after instancing, from a ~0.5 MB file."""
    path = mesh_placed(20000, 2000).glb(tmp_path / "instances.glb")
    assert path.stat().st_size < 1 << 20
    assert_refused_small(load_in_child(path), "more than 33554432 triangles (LoadLimits.max_triangles)")


def test_instance_limit(tmp_path):
    path = mesh_placed(4, 1).glb(tmp_path / "four.glb")
    assert len(pw.Scene.load(path).primitives) == 4
    with pytest.raises(pw.AssetFormatError, match="more than 3 mesh primitives .LoadLimits.max_instances.*node 3"):
        pw.Scene.load(path, limits=pw.LoadLimits(max_instances=3))


# ---------------------------------------------------------------------------- node graphs
def graph_glb(path: Path, nodes: list, roots: list) -> Path:
    b = Builder()
    mesh = b.quad()
    b.json["nodes"] = [{key: value for key, value in node.items() if key != "leaf"} | ({"mesh": mesh} if node.get("leaf") else {})
                       for node in nodes]
    b.json["scenes"][0]["nodes"] = roots
    return b.glb(path)


def test_node_dag_with_exponentially_many_paths_is_refused_at_once(tmp_path):
    """40 levels of two nodes, each the parent of both nodes of the next level: 2^40 paths to
    the last level from a 2.5 KB file. A glTF node has one parent."""
    levels = 40
    nodes = [{"children": [2 * level + 2, 2 * level + 3]} for level in range(levels - 1) for _ in range(2)]
    nodes += [{"leaf": True}, {"leaf": True}]
    path = graph_glb(tmp_path / "dag.glb", nodes, [0, 1])
    assert path.stat().st_size < 4096
    outcome = load_in_child(path, timeout_s=60)
    assert_refused_small(outcome, "is reached twice, from node", "one parent per node")


def chain_glb(tmp_path, depth):
    """A .glb whose nodes form one chain ``depth`` levels deep, each 1 mm above its parent."""
    nodes = [{"children": [i + 1], "translation": [0, 0, 1e-3]} for i in range(depth - 1)] + [{"leaf": True}]
    return graph_glb(tmp_path / "chain.glb", nodes, [0])


def test_chain_of_50000_nodes_is_refused_at_the_depth_limit(tmp_path):
    path = chain_glb(tmp_path, depth=50000)
    outcome = load_in_child(path, timeout_s=60)
    assert_refused_small(outcome, "node 1024 is 1025 levels deep", "LoadLimits.max_node_depth")


def test_deep_chain_within_a_raised_depth_limit_loads_with_its_world_matrix(tmp_path):
    depth = 3000
    path = chain_glb(tmp_path, depth)
    with pytest.raises(pw.AssetFormatError, match="max_node_depth"):
        load_gltf(path)
    prim, = load_gltf(path, limits=pw.LoadLimits(max_node_depth=depth)).primitives
    np.testing.assert_allclose(prim.positions[:, 2], (depth - 1) * 1e-3, rtol=1e-9)


@pytest.mark.parametrize("nodes, roots, message", [
    ([{"children": [1]}, {"children": [0], "leaf": True}], [0], "node 0 is its own ancestor"),
    ([{"children": [0], "leaf": True}], [0], "node 0 is its own ancestor"),
    ([{"children": [2]}, {"children": [2]}, {"leaf": True}], [0, 1], "node 2 is reached twice, from node 0 and from node 1"),
    ([{"children": [1, 1]}, {"leaf": True}], [0], "node 1 is reached twice, from node 0 and from node 0"),
    ([{"children": [1]}, {"leaf": True}], [0, 1], "node 1 is reached twice, from node 0 and from the scene's root list"),
    ([{"leaf": True}], [0, 0], "node 0 is reached twice, from the scene's root list and from the scene's root list"),
])
def test_node_graphs_that_are_not_trees_are_refused(tmp_path, nodes, roots, message):
    with pytest.raises(pw.AssetFormatError, match=message):
        pw.Scene.load(graph_glb(tmp_path / "graph.glb", nodes, roots))


def test_load_limits_are_checked(tmp_path):
    with pytest.raises(pw.InputError, match="max_texture_side must be > 0"):
        pw.LoadLimits(max_texture_side=0)
    with pytest.raises(pw.InputTypeError, match="max_triangles must be a whole number"):
        pw.LoadLimits(max_triangles=1e9)
    with pytest.raises(pw.InputTypeError, match="limits must be a pbrwarp.LoadLimits"):
        pw.Scene.load(mesh_placed(1, 1).glb(tmp_path / "one.glb"), limits={"max_triangles": 5})
