"""Conformance gallery: every glTF sample model of the shared assets, rendered beside its reference.

    python bench/gallery.py [--height 192] [--spp 4] [--env hdr/studio_small_03_1k.hdr] [--only NAME ...]

For each model folder of ``../shared/assets/gltf/`` and ``gltf-ext/`` (one Khronos sample model
or test board each): loads the model (``pw.Scene.load``; the first of its glTF-Binary, glTF,
glTF-Quantized and glTF-Draco variants), frames it (``Camera.frame``) from +Z and a little
above, as the Khronos sample viewer's screenshots mostly show a model (from 45 degrees above for
a model flat in Y), lights it with the environment alone and renders it at
the reference screenshot's aspect. Writes, for each model, one image, pbrwarp's render on the
left and the folder's reference screenshot (the sample viewer's, from the folder's
``screenshot/``) on the right, to ``docs/gallery/<model>.jpg``, and ``docs/gallery.md``: the
images, every warning pbrwarp gave at load and render (what it does not honour) or the error
that refused the model, the model's licence and the times. Not a benchmark: times are one run's.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, machine  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp.meshes import ASSETS  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"
VARIANTS = ("glTF-Binary", "glTF", "glTF-Quantized", "glTF-Draco")
SCREENSHOTS = ("screenshot.jpg", "screenshot.png", "screenshot.gif")
GAP = 4  # pixels between the render and the reference


def model_folders(only):
    for group in ("gltf", "gltf-ext"):
        for folder in sorted((ASSETS / group).iterdir()):
            if folder.is_dir() and (folder / "LICENSE.md").is_file() and (not only or folder.name in only):
                yield group, folder


def model_file(folder: Path) -> Path | None:
    for variant in VARIANTS:
        files = sorted((folder / variant).glob("*.gl[tb]*")) if (folder / variant).is_dir() else []
        if files:
            return files[0]
    return None


def reference(folder: Path) -> Image.Image | None:
    for name in SCREENSHOTS:
        path = folder / "screenshot" / name
        if path.is_file():
            with Image.open(path) as image:
                return image.convert("RGB")
    return None


def licence(folder: Path) -> str:
    """The SPDX identifier of the licence of the model's own files (the first its LICENSE.md names)."""
    ids = re.findall(r'SPDX license identifier: "([^"]+)"', (folder / "LICENSE.md").read_text(encoding="utf-8"))
    return ids[0] if ids else "see LICENSE.md"


def short(message: str, folder: Path) -> str:
    """A warning or error without the machine's paths to the model."""
    return str(message).replace(str(folder) + os.sep, "").replace(str(ASSETS) + os.sep, "").replace("|", "/")


def view_direction(scene) -> tuple:
    """From +Z and a little above (14 degrees), as the sample viewer's screenshots mostly show a
    model; from 45 degrees above for a scene flat in Y (a plane seen edge-on shows nothing)."""
    lo, hi = scene.bounds()
    extent = hi - lo
    flat = extent[1] < 0.2 * max(extent[0], extent[2])
    return (0.0, 1.0, 1.0) if flat else (0.0, 0.25, 1.0)


def render_model(path: Path, environment, aspect: float, height: int, spp: int):
    """(image as RGB uint8 or None, messages, load s, render s)."""
    messages = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        start = time.perf_counter()
        try:
            scene = pw.Scene.load(path)
        except pw.PbrwarpError as error:
            return None, [f"refused: {error}"], time.perf_counter() - start, 0.0
        loaded = time.perf_counter() - start
        scene.environment = environment
        width = max(16, round(height * aspect))
        start = time.perf_counter()
        try:
            frame = pw.render(scene, pw.Camera.frame(scene, direction=view_direction(scene), aspect=width / height),
                              width=width, height=height, spp=spp, progress=False)
        except pw.PbrwarpError as error:
            return None, [f"render refused: {error}"], loaded, time.perf_counter() - start
        rendered = time.perf_counter() - start
    seen = set()
    for w in caught:
        text = str(w.message)
        if text not in seen:
            seen.add(text)
            messages.append(text)
    return frame.to_srgb8(), messages, loaded, rendered


def side_by_side(render: np.ndarray | None, ref: Image.Image | None, height: int) -> Image.Image:
    left = Image.fromarray(render) if render is not None else Image.new("RGB", (height, height), (64, 0, 0))
    parts = [left]
    if ref is not None:
        parts.append(ref.resize((max(1, round(ref.width * height / ref.height)), height), Image.LANCZOS))
    out = Image.new("RGB", (sum(p.width for p in parts) + GAP * (len(parts) - 1), height), (255, 255, 255))
    x = 0
    for part in parts:
        out.paste(part, (x, 0))
        x += part.width + GAP
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="gallery.py", description=__doc__.splitlines()[0])
    ap.add_argument("--height", type=int, default=192, help="image height in pixels")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--env", default="hdr/studio_small_03_1k.hdr", help="environment, relative to the shared assets")
    ap.add_argument("--only", nargs="*", default=[],
                    help="model folder names (default: all); writes their images only, not the page")
    args = ap.parse_args(argv)
    environment = pw.Environment.load(ASSETS / args.env)
    out_dir = DOCS / "gallery"
    out_dir.mkdir(exist_ok=True)
    rows = []
    for group, folder in model_folders(set(args.only)):
        path = model_file(folder)
        ref = reference(folder)
        aspect = ref.width / ref.height if ref is not None else 4 / 3
        if path is None:
            image, messages, loaded, rendered = None, ["no glTF file in this folder"], 0.0, 0.0
        else:
            image, messages, loaded, rendered = render_model(path, environment, aspect, args.height, args.spp)
        side_by_side(image, ref, args.height).save(out_dir / f"{folder.name}.jpg", quality=82, optimize=True)
        rows.append((group, folder, path, ref is not None, [short(m, folder) for m in messages], loaded, rendered))
        print(f"{folder.name}: {len(messages)} message(s), {loaded:.2f} s load, {rendered:.2f} s render", file=sys.stderr)
    if args.only:  # a partial run must not replace the page of every model
        print("--only: images written; docs/gallery.md left as it was (run without --only to remake it)",
              file=sys.stderr)
        return
    (DOCS / "gallery.md").write_text(markdown(rows, command_line(ap, args), args))


def markdown(rows, command, args) -> str:
    info = machine()
    refused = sum(1 for r in rows if any(m.startswith(("refused", "render refused", "no glTF")) for m in r[4]))
    warned = sum(1 for r in rows if r[4]) - refused
    lines = [
        "# Gallery: the glTF sample models, pbrwarp beside the Khronos sample viewer",
        "",
        f"Each image: pbrwarp's render on the left, the model's reference screenshot (rendered by the Khronos "
        f"glTF sample viewer, from the model's folder) on the right. pbrwarp lights the model with the "
        f"environment `{Path(args.env).name}` alone, frames it with `Camera.frame` from +Z, 14 degrees above "
        f"(45 for a model flat in Y), {args.spp} samples "
        f"per pixel, ACES tone mapping; the sample viewer used its own environment and tone map, so compare "
        f"what each test board tests (its README), not the exact colours. Under each image: every warning "
        f"pbrwarp gave (what it does not honour), or the error that refused the model.",
        "",
        f"{len(rows)} models: {len(rows) - warned - refused} without a warning, {warned} with warnings, "
        f"{refused} refused.",
        "",
        f"Made by `{command}` (reads `../shared/assets`); {info['cpu']}, {info['cores']} cores; warp "
        f"{info['warp']}; commit {info['commit']}; {info['date']}. Models and screenshots: the Khronos glTF "
        f"sample assets (https://github.com/KhronosGroup/glTF-Sample-Assets, `Models/<model>/`), each under "
        f"the licence named in its row (the SPDX identifier its `LICENSE.md` gives for the model's files).",
        "",
        "| model | pbrwarp · reference | what pbrwarp said | licence | load s / render s |",
        "|---|---|---|---|---|",
    ]
    for group, folder, path, has_ref, messages, loaded, rendered in rows:
        said = "<br>".join(messages) if messages else "nothing"
        image = f"![{folder.name}](gallery/{folder.name}.jpg)"
        if not has_ref:
            image += "<br>(no reference screenshot in this folder)"
        variant = path.parent.name if path is not None else "-"
        lines.append(f"| {folder.name} ({group}, {variant}) | {image} | {said} | {licence(folder)} | "
                     f"{loaded:.2f} / {rendered:.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
