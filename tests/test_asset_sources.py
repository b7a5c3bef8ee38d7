"""The assets kept in the repository stay small, and each is accounted for (source, licence, changes)
in the SOURCES.md beside it."""

import pytest

from pbrwarp.meshes import SAMPLES

from assets import IN_REPO

FOLDERS = [IN_REPO, SAMPLES]
BUDGET_BYTES = 10_000_000  # all of them together: a clone stays quick to make


def data_files(folder):
    return [p for p in folder.rglob("*") if p.is_file() and p.suffix not in (".py", ".pyc")
            and p.name != "SOURCES.md" and "__pycache__" not in p.parts]


def test_assets_in_the_repository_stay_small():
    total = sum(p.stat().st_size for folder in FOLDERS for p in data_files(folder))
    assert 0 < total <= BUDGET_BYTES, total


@pytest.mark.parametrize("folder", FOLDERS, ids=["tests/assets", "meshes"])
def test_every_asset_is_named_in_its_sources(folder):
    """A glTF model by its folder (which also holds its LICENSE.md), anything else by its name."""
    sources = (folder / "SOURCES.md").read_text(encoding="utf-8")
    for path in data_files(folder):
        parts = path.relative_to(folder).parts
        if parts[0] in ("gltf", "gltf-ext"):
            assert parts[1] == "LICENSES" or (folder / parts[0] / parts[1] / "LICENSE.md").is_file(), path
            assert parts[1] in sources, path
        else:
            assert path.name in sources, path
