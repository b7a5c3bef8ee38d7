"""The package's modules import on their own and depend on each other one way: no import cycle,
counting the imports inside functions too (which hide a cycle from Python but not from a reader).
And every kernel module compiles without the backward pass pbrwarp never uses.
"""

import ast
import importlib
from pathlib import Path

import pytest
import warp as wp

PACKAGES = ("pbrwarp", "pbrwarp.kernels", "pbrwarp.meshes")
# __main__ runs the command line when imported; its imports are still in the graph
NOT_IMPORTED = {"pbrwarp.__main__"}


def module_files() -> dict[str, Path]:
    """Every module of PACKAGES (the packages themselves included) by name, found where Python
    finds the packages (a checkout's top-level kernels/ and meshes/, or an installed copy)."""
    files = {}
    for package in PACKAGES:
        folder = Path(importlib.import_module(package).__path__[0])
        files[package] = folder / "__init__.py"
        for path in sorted(folder.glob("*.py")):
            if path.stem != "__init__":
                files[f"{package}.{path.stem}"] = path
    return files


def imported_modules(name: str, path: Path, known: dict) -> set[str]:
    """The modules of ``known`` that module ``name`` (at ``path``) imports anywhere in its code:
    ``from package import module`` names the module, ``from module import value`` the module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")
                parent = parent[:len(parent) - (node.level - 1)]
                base = ".".join(parent + ([base] if base else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                found.add(submodule if submodule in known else base)
    return {module for module in found if module in known and module != name}


def import_graph() -> dict[str, set[str]]:
    known = module_files()
    return {name: imported_modules(name, path, known) for name, path in known.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The graph's strongly connected components of more than one module (Tarjan 1972), each
    sorted: every module in one reaches every other through imports."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph[node]):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


@pytest.mark.parametrize("name", sorted(set(module_files()) - NOT_IMPORTED))
def test_every_module_imports(name):
    importlib.import_module(name)


def test_every_kernel_module_compiles_without_backward():
    """Each module of pbrwarp.kernels defining kernels sets enable_backward=False (a backward pass
    would double compile time for gradients pbrwarp never takes)."""
    modules = [importlib.import_module(name) for name in module_files() if name.startswith("pbrwarp.kernels.")]
    kernels = [value for module in modules for value in vars(module).values()
               if isinstance(value, wp.Kernel) and value.module.name == module.__name__]
    assert len({kernel.module.name for kernel in kernels}) >= 10
    for kernel in kernels:
        assert kernel.module.options["enable_backward"] is False, kernel.module.name


def test_the_graph_sees_the_imports_it_must():
    """The parser follows relative, absolute, aliased and function-level imports (the checks
    below would pass vacuously on an empty graph)."""
    graph = import_graph()
    assert "pbrwarp.kernels.microfacet" in graph["pbrwarp.kernels.energy"]  # from .microfacet import ...
    assert "pbrwarp.kernels.raster" in graph["pbrwarp.raster"]  # from pbrwarp.kernels import raster as rk
    assert "pbrwarp.gltf" in graph["pbrwarp.scene"]
    assert "pbrwarp.kernels.ibl" in graph["pbrwarp.environment"]  # from .kernels.ibl import ..., in a method
    assert "pbrwarp" in graph["pbrwarp.meshes"]  # import pbrwarp as pw


def test_no_import_cycles():
    found = cycles(import_graph())
    assert not found, f"import cycles: {found}"
