"""The scene as Warp sees it: flat arrays of vertices, triangles, materials, textures and lights."""

import warp as wp

from .area_lights import AreaLightData
from .lights import LightData
from .textures import Texels, TextureData

wp.set_module_options({"enable_backward": False})

NO_TEXTURE = wp.constant(-1)
# The index of refraction MaterialData.ior holds for KHR_materials_ior's infinite one (ior = 0):
# refraction at it bends rays along the normal to within 1e-6 radians.
INFINITE_IOR = 1.0e6


@wp.struct
class MaterialData:
    base_color: wp.vec4
    emissive: wp.vec3
    metallic: float
    roughness: float
    specular: float
    # ((ior - 1) / (ior + 1))^2 times the specular colour: the dielectric's f0 before its clamp to
    # 1 and the specular factor (KHR_materials_ior, KHR_materials_specular)
    f0_dielectric: wp.vec3
    normal_scale: float
    # glTF occlusion: ambient light is scaled by 1 + strength (texel - 1)
    occlusion_strength: float
    alpha_cutoff: float
    # complex IOR eta + i kappa of a metal for the exact Fresnel rung; eta = 0 when none is given
    ior_eta: wp.vec3
    ior_kappa: wp.vec3
    # 1 when back faces are shaded (glTF doubleSided), 0 when they are culled
    double_sided: int
    # 1 for glTF alphaMode MASK
    alpha_mask: int
    # 1 for glTF alphaMode BLEND: camera rays composite its alpha as coverage
    alpha_blend: int
    # 1 for an unlit material (KHR_materials_unlit): its radiance is its base colour, lights ignored
    unlit: int
    # KHR_materials_anisotropy: strength in [0, 1] and the direction's rotation (cos, sin) from the tangent
    anisotropy_strength: float
    anisotropy_rotation: wp.vec2
    # KHR_materials_iridescence: strength, the film's IOR, its thickness (min, max) in nm
    iridescence: float
    iridescence_ior: float
    iridescence_thickness: wp.vec2
    # KHR_materials_clearcoat: the coat's intensity, perceptual roughness and normal-map scale
    clearcoat: float
    clearcoat_roughness: float
    clearcoat_normal_scale: float
    # KHR_materials_sheen: the sheen's linear colour and perceptual roughness
    sheen_color: wp.vec3
    sheen_roughness: float
    # KHR_materials_transmission's factor (0: opaque), KHR_materials_volume's thickness factor (0:
    # thin-walled), attenuation coefficient sigma per scene unit (0: none; FLOAT32_MAX for an
    # infinite one), and the dielectric's index of refraction (KHR_materials_ior; its "infinite"
    # 0 stored as INFINITE_IOR)
    transmission: float
    thickness: float
    attenuation: wp.vec3
    ior: float
    # indices into SceneData.textures, NO_TEXTURE when the slot is empty
    base_color_texture: int
    metallic_roughness_texture: int
    normal_texture: int
    emissive_texture: int
    occlusion_texture: int
    specular_texture: int
    specular_color_texture: int
    anisotropy_texture: int
    iridescence_texture: int
    iridescence_thickness_texture: int
    clearcoat_texture: int
    clearcoat_roughness_texture: int
    clearcoat_normal_texture: int
    sheen_color_texture: int
    sheen_roughness_texture: int
    transmission_texture: int


@wp.struct
class SceneData:
    mesh: wp.uint64
    positions: wp.array(dtype=wp.vec3)
    indices: wp.array(dtype=wp.int32)
    # zero-length normals mean "shade this vertex flat"
    normals: wp.array(dtype=wp.vec3)
    uvs: wp.array(dtype=wp.vec2)
    # TEXCOORD_1, for textures whose uv_set is 1; the very array ``uvs`` when no texture reads it
    uvs1: wp.array(dtype=wp.vec2)
    tangents: wp.array(dtype=wp.vec4)
    colors: wp.array(dtype=wp.vec4)
    face_material: wp.array(dtype=wp.int32)
    materials: wp.array(dtype=MaterialData)
    textures: wp.array(dtype=TextureData)
    texels: Texels
    # the punctual lights, and the area lights (sphere, rectangle), each in scene order
    lights: wp.array(dtype=LightData)
    num_lights: int
    area_lights: wp.array(dtype=AreaLightData)
    num_area_lights: int


@wp.func
def triangle_corners(indices: wp.array(dtype=wp.int32), face: int) -> wp.vec3i:
    """The vertex indices of triangle ``face`` in a flat index array."""
    return wp.vec3i(indices[3 * face], indices[3 * face + 1], indices[3 * face + 2])
