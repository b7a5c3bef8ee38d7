"""KHR_materials_clearcoat: a thin, clear dielectric layer (IOR 1.5, f0 = 0.04) over the whole
material, with its own roughness and normal.

The extension's layering (its "fresnel_coat", as Filament's clear coat model):

    coated = mix(material, coat_brdf, clearcoat F_coat(Nc.v)),   coat_brdf = D(a_c) V(a_c),

with a_c = clearcoatRoughness^2, Nc the coat's normal and F_coat the Fresnel of f0 = 0.04 at
Nc.v (not at v.h: the attenuation of the layer below then depends on the view alone, so the
mix conserves energy whenever both of its parts do). Emission lies below the coat and is
darkened by the same weight. The coat's D and V are the render's BRDF rungs (the specular term
of glTF's Appendix B by default) and F_coat its Fresnel rung (Schlick's by default, the exact
dielectric Fresnel of IOR 1.5 with ``fresnel="exact"``).

Environment light on the coat takes the split sum (Karis 2013) whatever the IBL rung: the
prefiltered radiance around the reflection about Nc times the lobe's directional albedo A + B
from the DFG table (f0 = f90 = 1: the coat's Fresnel is in its weight). The layers below keep
the IBL rung chosen."""

import functools

import warp as wp

from .brdf import FRESNEL_TERMS
from .dfg import dfg_lookup
from .ibl import EnvironmentData, prefiltered_radiance
from .microfacet import alpha_from_roughness, distribution_for, visibility_for
from .robust import MIN_COSINE, safe_normalize
from .scene_data import MaterialData, SceneData
from .texture_coords import SurfaceUV, no_texture

wp.set_module_options({"enable_backward": False})

# Reflectance at normal incidence of the coat, IOR 1.5: ((1.5 - 1) / (1.5 + 1))^2.
COAT_F0 = wp.constant(0.04)


@wp.struct
class Coat:
    """The clear coat at a surface point seen from v: its unit normal Nc (turned to the viewer's
    side), its perceptual roughness, and its weight clearcoat F_coat(Nc.v), the share of the view's
    light the coat reflects (the layers below keep 1 - weight)."""

    normal: wp.vec3
    roughness: float
    weight: float


@functools.cache
def clearcoat_for(distribution: str = "ggx", geometry: str = "schlick_ggx", fresnel: str = "schlick",
                  texture=None):
    """(coat_at, coat_layer, clearcoat_brdf, clearcoat_environment) for a render's BRDF rungs;
    ``texture``, the render kernel's lookup texture(scene, index, uv) (kernels/texture_coords.py
    texture_lookups), compiles in clearcoatTexture (R) and clearcoatRoughnessTexture (G); None
    leaves them out.

    - coat_at(scene, mat, uv, normal, v) -> Coat: the material's coat at a hit, ``normal`` the
      coat's normal there (the interpolated normal, or the coat's normal map's).
    - coat_layer(clearcoat, roughness, normal, v) -> Coat: the coat of these inputs.
    - clearcoat_brdf(coat, v, l) -> the coat's weighted BRDF, weight D V, 0 where Nc.l <= 0.
    - clearcoat_environment(env, dfg, coat, v) -> the radiance the coat reflects of the
      environment, weight included."""
    textured = texture is not None
    lookup = texture if textured else no_texture
    fresnel_term = FRESNEL_TERMS[fresnel]
    ndf = distribution_for(distribution)
    visibility = visibility_for(geometry)

    @wp.func
    def F_coat(n_dot_v: float) -> float:
        """The coat's Fresnel at Nc.v, f0 = 0.04 and f90 = 1 (Schlick 1994 by default)."""
        return fresnel_term(wp.vec3(COAT_F0), wp.vec3(1.0), n_dot_v)[0]

    @wp.func
    def coat_layer(clearcoat: float, roughness: float, normal: wp.vec3, v: wp.vec3) -> Coat:
        coat = Coat()
        coat.normal = normal
        coat.roughness = roughness
        coat.weight = clearcoat * F_coat(wp.max(wp.dot(normal, v), MIN_COSINE))
        return coat

    @wp.func
    def coat_at(scene: SceneData, mat: MaterialData, uv: SurfaceUV, normal: wp.vec3, v: wp.vec3) -> Coat:
        clearcoat = mat.clearcoat
        roughness = mat.clearcoat_roughness
        if wp.static(textured):
            clearcoat = clearcoat * lookup(scene, mat.clearcoat_texture, uv)[0]
            roughness = roughness * lookup(scene, mat.clearcoat_roughness_texture, uv)[1]
        return coat_layer(clearcoat, roughness, normal, v)

    @wp.func
    def clearcoat_brdf(coat: Coat, v: wp.vec3, l: wp.vec3) -> float:
        n = coat.normal
        n_dot_l = wp.dot(n, l)
        if n_dot_l <= 0.0 or coat.weight <= 0.0:
            return 0.0
        n_dot_v = wp.max(wp.dot(n, v), MIN_COSINE)
        h = safe_normalize(v + l, n)
        n_cross_h = wp.cross(n, h)
        d = ndf(alpha_from_roughness(coat.roughness), wp.min(wp.dot(n, h), 1.0), wp.dot(n_cross_h, n_cross_h))
        return coat.weight * d * visibility(n_dot_v, n_dot_l, coat.roughness)

    @wp.func
    def clearcoat_environment(env: EnvironmentData, dfg: wp.array2d(dtype=wp.vec2), coat: Coat,
                              v: wp.vec3) -> wp.vec3:
        if coat.weight <= 0.0:
            return wp.vec3(0.0)
        n_dot_v = wp.max(wp.dot(coat.normal, v), MIN_COSINE)
        ab = dfg_lookup(dfg, n_dot_v, coat.roughness)
        reflected = prefiltered_radiance(env, 2.0 * n_dot_v * coat.normal - v, coat.roughness)
        return reflected * (coat.weight * (ab[0] + ab[1]))

    return coat_at, coat_layer, clearcoat_brdf, clearcoat_environment
