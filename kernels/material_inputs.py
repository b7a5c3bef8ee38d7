"""A material's inputs at a hit: base colour, metallic, roughness and specular, the extension
layers' parameters, emission and the (normal-mapped) shading normal, each its factors times its
textures. Built per feature set and texture lookup, so a kernel holds only the lookups its scenes
need; shared by the direct render kernel (kernels/render.py) and the path tracer (kernels/path.py)."""

import functools

import warp as wp

from .anisotropy import anisotropy_direction
from .normal_mapping import perturb_normal
from .robust import safe_normalize
from .scene_data import NO_TEXTURE, MaterialData, SceneData
from .surface import SurfaceHit, interpolate
from .texture_coords import SurfaceUV

wp.set_module_options({"enable_backward": False})


@functools.cache
def material_lookups(f, texture):
    """The lookups of a kernel built for ``f`` (pbrwarp.features.Features), reading textures
    with ``texture`` (kernels/texture_coords.py texture_lookups), as a namespace of Warp functions:

    - base_color_at(scene, h, mat, uv) -> vec3; surface_inputs(scene, mat, uv) -> (metallic,
      roughness, specular, f0_dielectric); roughness_at(scene, mat, uv); transmission_at(scene,
      mat, uv); anisotropy_at(scene, h, mat, uv, n) -> (direction, strength); thin_film_at(scene,
      mat, uv) -> (strength, IOR, thickness); emission_at(scene, mat, uv) -> vec3 (cd/m^2);
    - oriented_normal(scene, h, uv, normal_map, scale) and shading_normal(scene, h, mat, uv):
      the interpolated normal, perturbed by a normal map, turned to the side the ray came from.
    """

    @wp.func
    def base_color_at(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: SurfaceUV) -> wp.vec3:
        """The material's base colour at the hit: its factor times vertex colour and texture."""
        base = wp.vec3(mat.base_color[0], mat.base_color[1], mat.base_color[2])
        if wp.static(f.vertex_colors):
            vertex_color = interpolate(scene.colors, h)
            base = wp.cw_mul(base, wp.vec3(vertex_color[0], vertex_color[1], vertex_color[2]))
        if wp.static(f.base_color_texture):
            bc = texture(scene, mat.base_color_texture, uv)
            base = wp.cw_mul(base, wp.vec3(bc[0], bc[1], bc[2]))
        return base

    @wp.func
    def anisotropy_at(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: SurfaceUV, n: wp.vec3):
        """(the unit anisotropy direction, the strength) of KHR_materials_anisotropy at the hit,
        with ``n`` the shading normal; strength 0 where there is no tangent frame."""
        strength = mat.anisotropy_strength
        if strength <= 0.0:
            return wp.vec3(0.0), 0.0
        rotation = mat.anisotropy_rotation
        direction = rotation
        if wp.static(f.anisotropy_texture):
            if mat.anisotropy_texture != NO_TEXTURE:
                texel = texture(scene, mat.anisotropy_texture, uv)
                d = wp.vec2(2.0 * texel[0] - 1.0, 2.0 * texel[1] - 1.0)
                length = wp.length(d)
                if length > 0.0:
                    d = d / length
                else:
                    d = wp.vec2(1.0, 0.0)
                direction = wp.vec2(rotation[0] * d[0] - rotation[1] * d[1], rotation[1] * d[0] + rotation[0] * d[1])
                strength = strength * texel[2]
        front = n
        if h.back_face == 1:
            front = -n
        t = anisotropy_direction(front, interpolate(scene.tangents, h), direction)
        if wp.dot(t, t) == 0.0:
            strength = 0.0
        return t, strength

    @wp.func
    def thin_film_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV) -> wp.vec3:
        """(strength, IOR, thickness in nm) of KHR_materials_iridescence's film at the hit."""
        strength = mat.iridescence
        thickness = mat.iridescence_thickness[1]
        if wp.static(f.iridescence_texture):
            if mat.iridescence_texture != NO_TEXTURE:
                strength = strength * texture(scene, mat.iridescence_texture, uv)[0]
            if mat.iridescence_thickness_texture != NO_TEXTURE:
                g = texture(scene, mat.iridescence_thickness_texture, uv)[1]
                thickness = wp.lerp(mat.iridescence_thickness[0], mat.iridescence_thickness[1], g)
        return wp.vec3(strength, mat.iridescence_ior, thickness)

    @wp.func
    def surface_inputs(scene: SceneData, mat: MaterialData, uv: SurfaceUV):
        """(metallic, roughness, specular, f0_dielectric) at the hit: the factors times their
        textures."""
        metallic = mat.metallic
        roughness = mat.roughness
        specular = mat.specular
        f0_dielectric = mat.f0_dielectric
        if wp.static(f.metallic_roughness_texture):
            mr = texture(scene, mat.metallic_roughness_texture, uv)
            roughness = roughness * mr[1]
            metallic = metallic * mr[2]
        if wp.static(f.specular_texture):
            specular = specular * texture(scene, mat.specular_texture, uv)[3]
        if wp.static(f.specular_color_texture):
            sc = texture(scene, mat.specular_color_texture, uv)
            f0_dielectric = wp.cw_mul(f0_dielectric, wp.vec3(sc[0], sc[1], sc[2]))
        return metallic, roughness, specular, f0_dielectric

    @wp.func
    def roughness_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV) -> float:
        metallic, roughness, specular, f0_dielectric = surface_inputs(scene, mat, uv)
        return roughness

    @wp.func
    def transmission_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV) -> float:
        """KHR_materials_transmission's share at the hit: its factor times the texture's R."""
        t = mat.transmission
        if wp.static(f.transmission_texture):
            if t > 0.0:
                t = t * texture(scene, mat.transmission_texture, uv)[0]
        return t

    @wp.func
    def oriented_normal(scene: SceneData, h: SurfaceHit, uv: SurfaceUV, normal_map: int, scale: float) -> wp.vec3:
        """Interpolated normal, perturbed by texture ``normal_map`` (unless NO_TEXTURE) with
        ``scale``, turned to the side the ray came from."""
        front_ng = h.ng
        if h.back_face == 1:
            front_ng = -h.ng
        n = safe_normalize(interpolate(scene.normals, h), front_ng)
        if wp.static(f.normal_mapping or f.clearcoat_textures):
            if normal_map != NO_TEXTURE:
                texel = texture(scene, normal_map, uv)
                n = perturb_normal(n, interpolate(scene.tangents, h), texel, scale)
        if h.back_face == 1:
            n = -n
        return n

    @wp.func
    def shading_normal(scene: SceneData, h: SurfaceHit, mat: MaterialData, uv: SurfaceUV) -> wp.vec3:
        """The material's (normal-mapped) normal, turned to the side the ray came from."""
        normal_map = NO_TEXTURE
        if wp.static(f.normal_mapping):
            normal_map = mat.normal_texture
        return oriented_normal(scene, h, uv, normal_map, mat.normal_scale)

    @wp.func
    def emission_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV) -> wp.vec3:
        """Emitted radiance (cd/m^2): the emissive factor times its texture."""
        radiance = mat.emissive
        if wp.static(f.emissive_texture):
            em = texture(scene, mat.emissive_texture, uv)
            radiance = wp.cw_mul(radiance, wp.vec3(em[0], em[1], em[2]))
        return radiance

    return _Lookups(base_color_at=base_color_at, surface_inputs=surface_inputs, roughness_at=roughness_at,
                    transmission_at=transmission_at, anisotropy_at=anisotropy_at, thin_film_at=thin_film_at,
                    emission_at=emission_at, oriented_normal=oriented_normal, shading_normal=shading_normal)


class _Lookups:
    """The functions material_lookups built, as attributes."""

    def __init__(self, **functions):
        self.__dict__.update(functions)
