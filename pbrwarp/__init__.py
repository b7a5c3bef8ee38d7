"""pbrwarp: physically based rendering of triangle meshes on the CPU with NVIDIA Warp.

>>> import pbrwarp as pw
>>> scene = pw.Scene.load("model.glb")
>>> pw.render(scene, pw.Camera.frame(scene), width=512, height=512).save("out.png")
"""

from .startup import start_warp

start_warp()  # first, before any module below touches Warp: quiet unless PBRWARP_VERBOSE is set


def _load_checkout_subpackages():
    """pbrwarp.kernels and pbrwarp.meshes are a checkout's top-level kernels/ and meshes/, which
    pyproject.toml maps into the installed package. Run from the checkout's root (``python -m
    pbrwarp``, the README's first command), this folder shadows the installed package and has
    neither: load them from beside it, under the installed names."""
    import importlib.util
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parent
    for name in ("kernels", "meshes"):
        full_name = f"{__name__}.{name}"
        init = here.parent / name / "__init__.py"
        if full_name in sys.modules or (here / name).exists() or not init.is_file():
            continue
        spec = importlib.util.spec_from_file_location(full_name, init, submodule_search_locations=[str(init.parent)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[full_name] = module
        spec.loader.exec_module(module)
        globals()[name] = module  # as the import system binds a submodule it loads


_load_checkout_subpackages()

from .brdf import BRDF  # noqa: E402 - after the subpackages it imports
from .camera import Camera
from .denoise import denoise
from .diagnostics import FrameCheck, check
from .environment import Environment
from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError, PbrwarpError, ResourceError
from .frame import Frame
from .ibl import IBL
from .lights import AreaLighting, DirectionalLight, PointLight, RectLight, SphereLight, SpotLight
from .load_limits import LoadLimits
from .materials import Material
from .features import Features
from .render import Accumulator, explain, render
from .batch import render_batch
from .scene import Primitive, Scene
from .shadow_maps import ShadowMap
from .textures import Texture

__all__ = [
    "Accumulator", "AreaLighting", "AssetFormatError", "AssetNotFoundError", "BRDF", "Camera", "DirectionalLight", "Environment", "Features", "Frame", "FrameCheck", "IBL", "InputError",
    "InputTypeError", "LoadLimits", "Material", "PbrwarpError", "PointLight", "Primitive", "RectLight", "ResourceError", "Scene", "ShadowMap",
    "SphereLight", "SpotLight",
    "Texture", "check", "denoise", "explain", "render", "render_batch",
]
__version__ = "0.1.0"
