"""Scenes: triangle meshes with materials, lights and (optionally) the cameras a file defines."""

from __future__ import annotations

import numpy as np

from . import validate
from .camera import Camera
from .errors import AssetFormatError, InputError, InputTypeError
from .gltf import load_gltf
from .lights import DirectionalLight, PointLight, SpotLight
from .materials import Material
# Primitive and its conversions live in their own module (the glTF loader builds on them too);
# they stay importable from here.
from .primitive import Primitive, material_from_trimesh, primitive_from_trimesh, transform_primitive, unit_rows

__all__ = ["LOADABLE", "Primitive", "Scene", "material_from_trimesh", "primitive_from_trimesh",
           "transform_primitive", "unit_rows"]

LOADABLE = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")


class Scene:
    """Meshes, materials and lights to render.

    >>> scene = Scene.load("model.glb")                # or Scene() and add_mesh/add_light
    """

    def __init__(self):
        self.primitives: list[Primitive] = []
        self.lights: list = []
        self.cameras: list[Camera] = []
        self._environment = None

    @property
    def environment(self):
        """The :class:`pbrwarp.Environment` lighting the scene from every direction (and shown
        where no surface is hit, unless ``render(background=...)`` says otherwise), or None."""
        return self._environment

    @environment.setter
    def environment(self, value):
        from .environment import Environment

        if value is not None and not isinstance(value, Environment):
            raise InputTypeError(f"Scene.environment must be a pbrwarp.Environment or None, got {type(value).__name__}")
        self._environment = value

    # ------------------------------------------------------------------ building
    def add_mesh(self, mesh, material: Material | None = None, transform=None) -> Primitive:
        """Add a ``trimesh.Trimesh`` (or a :class:`Primitive`). ``material`` overrides the one
        trimesh read from the file; ``transform`` is an optional 4x4 world matrix."""
        if isinstance(mesh, Primitive):
            prim = mesh if material is None else Primitive(
                mesh.positions, mesh.faces, material, mesh.normals, mesh.uvs, mesh.tangents, mesh.colors, mesh.name)
        else:
            prim = primitive_from_trimesh(mesh, material)
        if transform is not None:
            prim = transform_primitive(prim, transform)
        self.primitives.append(prim)
        return prim

    def add_light(self, light):
        if not isinstance(light, (PointLight, DirectionalLight, SpotLight)):
            raise InputTypeError(
                f"add_light takes a PointLight, DirectionalLight or SpotLight, got {type(light).__name__}")
        self.lights.append(light)
        return light

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, path) -> "Scene":
        """Read a .glb/.gltf/.obj/.ply/.stl/.off file (node transforms applied; glTF materials,
        tangents, samplers, lights and cameras kept)."""
        path, ext = validate.readable_file(path, "scene file", LOADABLE, "meshes and glTF scenes")
        if ext in (".glb", ".gltf"):
            content = load_gltf(path)
            scene = cls()
            scene.primitives.extend(content.primitives)
            scene.lights.extend(content.lights)
            scene.cameras.extend(content.cameras)
            return scene
        import trimesh

        try:
            loaded = trimesh.load(path, force="scene")
        except Exception as err:  # trimesh raises many types for corrupt files
            raise AssetFormatError(f"cannot read {path}: {type(err).__name__}: {err}") from None
        try:
            scene = cls.from_trimesh(loaded)
        except (InputError, InputTypeError) as err:  # NaN normals, overflowing vertices, ...
            raise AssetFormatError(f"cannot load {path}: {err}") from None
        if not scene.primitives:
            raise AssetFormatError(f"{path} contains no triangles")
        return scene

    @classmethod
    def from_trimesh(cls, obj) -> "Scene":
        """A scene from a ``trimesh.Trimesh`` or ``trimesh.Scene`` (scene-graph transforms applied)."""
        import trimesh

        scene = cls()
        if isinstance(obj, trimesh.Trimesh):
            scene.add_mesh(obj)
        elif isinstance(obj, trimesh.Scene):
            for node in obj.graph.nodes_geometry:
                matrix, geometry_name = obj.graph[node]
                geom = obj.geometry[geometry_name]
                if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
                    prim = primitive_from_trimesh(geom, None, name=str(node))
                    scene.primitives.append(transform_primitive(prim, matrix))
        else:
            raise InputTypeError(f"from_trimesh takes a trimesh.Trimesh or trimesh.Scene, got {type(obj).__name__}")
        return scene

    # ------------------------------------------------------------------ queries
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min corner, max corner) of every mesh in the scene."""
        if not self.primitives:
            raise InputError("the scene has no meshes")
        los, his = zip(*(p.bounds() for p in self.primitives))
        return np.min(los, axis=0), np.max(his, axis=0)

    @property
    def triangle_count(self) -> int:
        return sum(len(p.faces) for p in self.primitives)
