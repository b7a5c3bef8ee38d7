"""Where the tests' assets are: this folder, or the larger set that PBRWARP_TEST_ASSETS names.

This folder holds small copies of public models (SOURCES.md: origin, licence, changes), laid out
as the shared asset set is (``gltf/<Model>/glTF*/``, ``hdr/``, ``meshes/``); the decimated bunny
is installed with pbrwarp (``pbrwarp.meshes.SAMPLES``). With ``PBRWARP_TEST_ASSETS=DIR`` (e.g.
``../shared/assets``) the tests over every model and mesh (GLTF, MESHES) run over DIR's too: the
whole glTF sample set and the full-size scanned meshes, besides the small copies here, so that a
run with the variable also proves what a bare clone runs; single named files (ASSETS, hdr) then
come from DIR: the full-size models and the 1k HDRs.
"""

from __future__ import annotations

import os
from pathlib import Path

from pbrwarp.meshes import SAMPLES

VARIABLE = "PBRWARP_TEST_ASSETS"
IN_REPO = Path(__file__).resolve().parent


def _extended() -> Path | None:
    value = os.environ.get(VARIABLE)
    if not value:
        return None
    folder = Path(value).expanduser().resolve()
    if not (folder / "gltf").is_dir():
        import pytest

        raise pytest.UsageError(f"{VARIABLE}={value}: no gltf/ folder there; point it at the shared assets "
                                f"(e.g. {VARIABLE}=../shared/assets) or unset it to use tests/assets")
    return folder


EXTENDED = _extended()
ASSETS = EXTENDED or IN_REPO
# The in-repo meshes: this folder's and the samples pbrwarp installs (the decimated bunny).
_IN_REPO_MESH_FOLDERS = [IN_REPO / "meshes", SAMPLES]
_MESH_FOLDERS = [EXTENDED / "meshes"] if EXTENDED else _IN_REPO_MESH_FOLDERS
MESH_SUFFIXES = (".obj", ".off", ".ply", ".stl")


def _models(root: Path) -> list[Path]:
    return sorted(root.glob("gltf/*/glTF*/*.gl[tb]*"))


def _meshes(folders) -> list[Path]:
    return sorted(p for folder in folders for p in folder.rglob("*") if p.suffix in MESH_SUFFIXES)


GLTF = _models(IN_REPO) + (_models(EXTENDED) if EXTENDED else [])
MESHES = _meshes(_IN_REPO_MESH_FOLDERS) + (_meshes([EXTENDED / "meshes"]) if EXTENDED else [])


def _board_names(root: Path) -> set[str]:
    return {p.parent.parent.name for p in root.glob("gltf-ext/*/glTF*/*.gl[tb]*")}


# The Khronos test boards the run has: this folder's small ones, and every one of PBRWARP_TEST_ASSETS.
BOARDS = sorted(_board_names(IN_REPO) | (_board_names(EXTENDED) if EXTENDED else set()))


def board(name: str) -> Path:
    """The model file of the Khronos test board ``name`` (``gltf-ext/<name>/glTF*/``): from
    PBRWARP_TEST_ASSETS when it holds the board, else this folder's copy (the small boards are
    kept here whole)."""
    for root in ([EXTENDED] if EXTENDED else []) + [IN_REPO]:
        found = sorted((root / "gltf-ext" / name).glob("glTF*/*.gl[tb]*"))
        if found:
            return found[0]
    raise FileNotFoundError(f"no test board {name!r} in {IN_REPO / 'gltf-ext'}")


def asset_id(path: Path) -> str:
    """A test id for an asset file: its name, prefixed "shared:" when it comes from PBRWARP_TEST_ASSETS."""
    return f"shared:{path.name}" if EXTENDED and EXTENDED in path.parents else path.name


def mesh_file(relative: str) -> Path:
    """The file ``relative`` in the test meshes (``"teapot.obj"``, ``"spot/spot_texture.png"``, ...)."""
    for folder in _MESH_FOLDERS:
        if (folder / relative).is_file():
            return folder / relative
    raise FileNotFoundError(f"no test mesh {relative!r} in {', '.join(map(str, _MESH_FOLDERS))}")


def hdr(name: str) -> Path:
    """The HDR environment ``name`` (``"venice_sunset"``): 1024 x 512 from PBRWARP_TEST_ASSETS, else
    this folder's smaller copy."""
    found = sorted(ASSETS.glob(f"hdr/{name}_*.hdr"))
    if not found:
        raise FileNotFoundError(f"no HDR {name!r} in {ASSETS / 'hdr'}")
    return found[0]


def describe() -> str:
    """One line for pytest's header: which assets the run uses."""
    if EXTENDED:
        return f"assets: {EXTENDED} ({VARIABLE})"
    return f"assets: {IN_REPO} (set {VARIABLE}=../shared/assets for the full sample set)"
