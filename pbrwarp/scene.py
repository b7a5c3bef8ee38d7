"""Scenes: triangle meshes with materials, lights and (optionally) the cameras a file defines."""

from __future__ import annotations

import os
import warnings

import numpy as np

from . import validate
from .camera import Camera
from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError
from .gltf import load_gltf
from .lights import AREA_KINDS, PUNCTUAL_KINDS, DirectionalLight, PointLight, RectLight, SphereLight, SpotLight
from .load_limits import LoadLimits
from .materials import Material
from .scene_cache import SceneCache
# Primitive and its conversions live in their own module (the glTF loader builds on them too);
# they stay importable from here.
from .primitive import Primitive, material_from_trimesh, primitive_from_trimesh, transform_primitive, unit_rows
from .textures import open_image

__all__ = ["LOADABLE", "Primitive", "Scene", "material_from_trimesh", "primitive_from_trimesh",
           "transform_primitive", "unit_rows"]

LOADABLE = (".glb", ".gltf", ".obj", ".ply", ".stl", ".off")
# Textures a mesh file's material may name, whose header _ConfinedFiles checks before trimesh decodes them.
_IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".webp", ".gif", ".bmp", ".tga", ".tif", ".tiff")


class Scene:
    """Meshes, materials and lights to render.

    ``primitives`` (list of :class:`Primitive`), ``lights`` (point, directional, spot,
    sphere and rectangle lights), ``cameras`` (those a file defines; ``render`` uses the first by default) and
    ``environment`` may be read and changed freely between renders; ``cache`` keeps what renders
    derived from them. ``load_warnings`` (a tuple of strings) holds the warnings :meth:`load`
    issued about what in the file pbrwarp does not honour; :func:`pbrwarp.explain` lists them. One
    scene may be rendered from several threads at once.

    >>> scene = Scene.load("model.glb")                # or Scene() and add_mesh/add_light
    """

    def __init__(self):
        self.primitives: list[Primitive] = []
        self.lights: list = []
        self.cameras: list[Camera] = []
        self.load_warnings: tuple[str, ...] = ()
        self._environment = None
        self._cache = SceneCache()

    @property
    def cache(self) -> SceneCache:
        """What renders derived from this scene and keep for the next (uploaded geometry, light
        buffers, shadow maps...; pbrwarp/scene_cache.py lists it), each part rebuilt when what it
        depends on changes; ``scene.cache.clear()`` drops it all."""
        return self._cache

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
        """Add a ``trimesh.Trimesh`` (or a :class:`Primitive`) and return the :class:`Primitive`
        added. ``material`` overrides the one trimesh read from the file (or the primitive's);
        ``transform`` is an optional 4x4 world matrix (a mirroring one reverses the winding).
        InputTypeError for another kind of mesh, InputError for a mesh without faces, with NaN or
        Inf, or a singular transform."""
        if isinstance(mesh, Primitive):
            prim = mesh if material is None else Primitive(
                mesh.positions, mesh.faces, material, mesh.normals, mesh.uvs, mesh.tangents, mesh.colors, mesh.name,
                mesh.uvs1)
        else:
            prim = primitive_from_trimesh(mesh, material)
        if transform is not None:
            prim = transform_primitive(prim, transform)
        self.primitives.append(prim)
        return prim

    def add_light(self, light):
        """Add a :class:`PointLight`, :class:`DirectionalLight`, :class:`SpotLight`,
        :class:`SphereLight` or :class:`RectLight` and return it (InputTypeError for anything
        else)."""
        if not isinstance(light, (PointLight, DirectionalLight, SpotLight, SphereLight, RectLight)):
            raise InputTypeError(f"add_light takes a PointLight, DirectionalLight, SpotLight, SphereLight or "
                                 f"RectLight, got {type(light).__name__}")
        self.lights.append(light)
        return light

    @property
    def punctual_lights(self) -> list:
        """The point, directional and spot lights of ``lights``, in order (those shadow maps and
        light buffers are built for)."""
        return [light for light in self.lights if light.kind in PUNCTUAL_KINDS]

    @property
    def area_lights(self) -> list:
        """The sphere and rectangle lights of ``lights``, in order."""
        return [light for light in self.lights if light.kind in AREA_KINDS]

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, path, *, allowed_roots=None, limits: LoadLimits | None = None) -> "Scene":
        """Read a .glb/.gltf/.obj/.ply/.stl/.off file (node transforms applied; glTF materials,
        tangents, samplers, lights and cameras kept).

        - ``allowed_roots``: folders besides the model's own whose files the model may name
          (default None: only the model's folder). A glTF buffer or image URI, an OBJ's material
          library or a texture path is resolved (``..`` and symbolic links followed) and refused,
          before anything is opened, unless it lies inside one of these folders; glTF ``data:``
          URIs are always read.
        - ``limits``: a :class:`pbrwarp.LoadLimits` bounding texture sizes and, for glTF, the
          node graph, instance, vertex and triangle counts; every size is checked against it
          before anything is decoded or allocated (default None: ``LoadLimits()``).

        Raises ``AssetNotFoundError`` for a missing file and ``AssetFormatError`` naming the file
        and the problem for a corrupt one, one that names a file outside the allowed folders or
        one past a limit. Warns (a ``UserWarning`` naming the file) once for each kind of thing in
        the file that pbrwarp does not honour -- a glTF extension it ignores, alphaMode BLEND, an
        animation, a skin, a texture file an OBJ names that does not exist -- saying what is
        rendered instead; the scene keeps the messages in ``load_warnings``. docs/loading.md lists
        what is read, what is warned about, what is refused and why.
        """
        path, ext = validate.readable_file(path, "scene file", LOADABLE, "meshes and glTF scenes")
        roots = validate.allowed_roots(allowed_roots)
        limits = LoadLimits.of(limits)
        if ext in (".glb", ".gltf"):
            content = load_gltf(path, allowed_roots=roots, limits=limits)
            scene = cls()
            scene.primitives.extend(content.primitives)
            scene.lights.extend(content.lights)
            scene.cameras.extend(content.cameras)
            scene.load_warnings = content.load_warnings
            return scene
        import trimesh

        files = _ConfinedFiles(path, roots, limits)
        try:
            loaded = trimesh.load(path, force="scene", resolver=files)
        except Exception as err:  # trimesh raises many types for corrupt files
            raise AssetFormatError(f"cannot read {path}: {type(err).__name__}: {err}") from None
        if files.refused:  # trimesh logs a file it cannot get and goes on without it
            raise files.refused[0]
        notes = tuple(f"{path} names the file {name!r}, which does not exist; loaded without it"
                      for name in files.missing)
        for message in notes:
            warnings.warn(message, stacklevel=2)
        try:
            scene = cls.from_trimesh(loaded)
        except (InputError, InputTypeError) as err:  # NaN normals, overflowing vertices, ...
            raise AssetFormatError(f"cannot load {path}: {err}") from None
        scene.load_warnings = notes
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
        """(min corner, max corner), float64 arrays of 3, of every mesh in the scene; InputError
        for a scene without meshes."""
        if not self.primitives:
            raise InputError("the scene has no meshes")
        los, his = zip(*(p.bounds() for p in self.primitives))
        return np.min(los, axis=0), np.max(his, axis=0)

    @property
    def triangle_count(self) -> int:
        """Triangles of every primitive together."""
        return sum(len(p.faces) for p in self.primitives)


class _ConfinedFiles:
    """The trimesh resolver of a mesh file's material libraries and textures: only files inside
    its folder or the allowed roots (validate.confined_path; names are plain paths, not
    percent-encoded), images of any format Pillow reads only within ``limits.max_texture_side``. trimesh swallows a
    resolver's errors, so refusals and missing files are also kept for Scene.load to report."""

    def __init__(self, model: str, roots: tuple[str, ...], limits: LoadLimits):
        self.model, self.roots, self.limits = model, roots, limits
        self.base_dir = os.path.dirname(os.path.abspath(model))
        self.file_name = os.path.basename(model)
        self.refused: list[AssetFormatError] = []
        self.missing: list[str] = []

    def get(self, name: str) -> bytes:
        what = f"the file {name!r} it names"
        try:
            real = validate.confined_path(name.strip(), self.base_dir, self.roots, what, self.model,
                                          percent_encoded=False)
            data = validate.read_confined(real, what, self.model)
            if os.path.splitext(real)[1].lower() in _IMAGE_EXTENSIONS:
                try:
                    open_image(data, what, self.limits.max_texture_side, formats=None).close()
                except InputError as err:
                    raise AssetFormatError(f"cannot load {self.model}: {err}") from None
            return data
        except AssetNotFoundError:
            self.missing.append(name)
            raise
        except AssetFormatError as err:
            self.refused.append(err)
            raise

    __getitem__ = get
