"""pbrwarp: physically based rendering of triangle meshes on the CPU with NVIDIA Warp.

>>> import pbrwarp as pw
>>> scene = pw.Scene.load("model.glb")
>>> pw.render(scene, pw.Camera.frame(scene), width=512, height=512).save("out.png")
"""

from .brdf import BRDF
from .camera import Camera
from .diagnostics import FrameCheck, check
from .environment import Environment
from .errors import AssetFormatError, AssetNotFoundError, InputError, InputTypeError, PbrwarpError
from .frame import Frame
from .ibl import IBL
from .lights import DirectionalLight, PointLight, SpotLight
from .materials import Material
from .features import Features
from .render import explain, render
from .scene import Primitive, Scene
from .shadow_maps import ShadowMap
from .textures import Texture

__all__ = [
    "AssetFormatError", "AssetNotFoundError", "BRDF", "Camera", "DirectionalLight", "Environment", "Features", "Frame", "FrameCheck", "IBL", "InputError",
    "InputTypeError", "Material", "PbrwarpError", "PointLight", "Primitive", "Scene", "ShadowMap", "SpotLight",
    "Texture", "check", "explain", "render",
]
__version__ = "0.1.0"
