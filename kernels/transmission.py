"""Smooth dielectric interfaces for ray-traced transmission (KHR_materials_transmission,
KHR_materials_volume, KHR_materials_ior): Snell refraction with total internal reflection, the
transmitted share of a surface, and Beer-Lambert absorption inside a volume.

Conventions are pbrt-v4's (Pharr, Jakob and Humphreys, "Physically Based Rendering", 4th ed.,
section 9.3): ``wi`` points away from the surface, towards where the light goes back to; ``n`` is
the normal on wi's side; ``eta`` is the relative index of refraction, that of the side the ray
enters over that of the side it leaves (ior entering glass from air, 1 / ior leaving it).
"""

import warp as wp

from .brdf import F_Schlick, dielectric_specular_f0, max_channel
from .direction_sampling import G1_SmithGGX, orthonormal_basis, sample_ggx_vndf
from .microfacet import alpha_from_roughness
from .robust import safe_normalize

# Offset of the random streams of rough transmission's samples (kernels/ambient.py's
# ENVIRONMENT_STREAM is 2^24): one stream per camera sample.
TRANSMISSION_STREAM = wp.constant(1 << 25)

wp.set_module_options({"enable_backward": False})


@wp.func
def refract(wi: wp.vec3, n: wp.vec3, eta: float):
    """(whether light refracts, the transmitted direction): Snell's law, eta sin_t = sin_i, in the
    vector form of pbrt-v4's Refract; False (and a zero vector) on total internal reflection,
    where sin_t would exceed 1. ``wi`` and ``n`` are unit vectors on the same side."""
    cos_i = wp.clamp(wp.dot(n, wi), 0.0, 1.0)
    sin2_i = wp.max(0.0, 1.0 - cos_i * cos_i)
    sin2_t = sin2_i / (eta * eta)
    if sin2_t >= 1.0:
        return False, wp.vec3(0.0)
    cos_t = wp.sqrt(1.0 - sin2_t)
    return True, safe_normalize(-wi / eta + (cos_i / eta - cos_t) * n, -n)


@wp.func
def reflect(wi: wp.vec3, n: wp.vec3) -> wp.vec3:
    """The mirror direction of ``wi`` about ``n``: 2 (n . wi) n - wi."""
    return 2.0 * wp.dot(n, wi) * n - wi


@wp.func
def refract_through(d: wp.vec3, n: wp.vec3, ng: wp.vec3, eta: float):
    """(whether the ray refracts, its new direction, the normal that bent it) for a ray of
    direction ``d`` meeting an interface of shading normal ``n`` and geometric normal ``ng``, both
    turned towards where the ray comes from: refracted by n, or reflected by it on total internal
    reflection. Where the shading normal would send the ray to the wrong side of the geometric
    surface (back where it came from after refraction, through the surface after reflection:
    normal maps and interpolated normals at grazing angles), the geometric normal decides."""
    refracts, direction = refract(-d, n, eta)
    if refracts:
        if wp.dot(direction, ng) < 0.0:
            return True, direction, n
        refracts, direction = refract(-d, ng, eta)
        if refracts:
            return True, direction, ng
        return False, reflect(-d, ng), ng
    direction = reflect(-d, n)
    if wp.dot(direction, ng) > 0.0:
        return False, direction, n
    refracts, direction = refract(-d, ng, eta)
    if refracts:
        return True, direction, ng
    return False, reflect(-d, ng), ng


@wp.func
def sample_rough_interface(d: wp.vec3, n: wp.vec3, ng: wp.vec3, eta: float, roughness: float, u: wp.vec2):
    """(whether the ray refracts, its new direction, its weight): one draw of the GGX transmission
    lobe of a rough interface (Walter, Marschner, Li and Torrance 2007) for a ray of direction
    ``d`` meeting it, normals ``n`` (shading) and ``ng`` turned towards where it comes from. A
    microfacet normal m is drawn from the normals visible from -d (Heitz 2018), and the ray
    refracts through m, or reflects off it on total internal reflection. Drawn so, the lobe's
    D, G1(v) and Jacobian cancel against the pdf, leaving the masking G1 of the new direction as
    the weight (the separable Smith G; the Fresnel weight is the caller's). The weight is 0
    where the new direction falls on the wrong side of the geometric surface."""
    frame = orthonormal_basis(n)
    v_local = wp.transpose(frame) * (-d)
    if v_local[2] <= 0.0:  # seen from below its shading normal: bent as by a smooth interface
        refracts, direction, bent_by = refract_through(d, n, ng, eta)
        return refracts, direction, 1.0
    alpha = alpha_from_roughness(roughness)
    m = frame * sample_ggx_vndf(v_local, alpha, u)
    refracts, direction = refract(-d, m, eta)
    if not refracts:
        direction = reflect(-d, m)
    side = wp.dot(direction, ng)
    if (refracts and side >= 0.0) or ((not refracts) and side <= 0.0):
        return refracts, direction, 0.0
    return refracts, direction, G1_SmithGGX(wp.abs(wp.dot(direction, n)), alpha)


@wp.func
def sample_thin_lobe(d: wp.vec3, n: wp.vec3, ng: wp.vec3, roughness: float, u: wp.vec2):
    """(new direction, weight): one draw of a rough thin wall's transmission lobe, which
    KHR_materials_transmission defines as the specular lobe "sampled along the line of sight
    through the surface": a reflection off a microfacet normal drawn from those visible from -d
    (Heitz 2018), mirrored through the surface's plane. Weight G1 of the reflected direction (as
    for sample_rough_interface), 0 where it would leave on the wrong side. ``roughness`` is the
    lobe's, transmission_roughness of the material's; 0 gives d itself."""
    frame = orthonormal_basis(n)
    v_local = wp.transpose(frame) * (-d)
    if v_local[2] <= 0.0 or roughness <= 0.0:
        return d, 1.0
    alpha = alpha_from_roughness(roughness)
    l = reflect(-d, frame * sample_ggx_vndf(v_local, alpha, u))
    l_dot_n = wp.dot(l, n)
    if l_dot_n <= 0.0:
        return d, 0.0
    through = l - 2.0 * l_dot_n * n
    if wp.dot(through, ng) >= 0.0:
        return d, 0.0
    return through, G1_SmithGGX(l_dot_n, alpha)


@wp.func
def transmitted_share(base_color: wp.vec3, metallic: float, transmission: float, specular: float,
                      f0_dielectric: wp.vec3, n_dot_v: float) -> wp.vec3:
    """The share of light a smooth surface transmits, per channel: glTF's dielectric BRDF with
    KHR_materials_transmission, mix(dielectric, metal, metallic), its base layer
    mix(diffuse, btdf * base_color, transmission) under the specular layer's Fresnel weight
    1 - max(F) (KHR_materials_specular's albedo scaling), F Schlick's at n . v as the layer's:
    (1 - metallic) transmission (1 - max(F)) base_color."""
    f = F_Schlick(dielectric_specular_f0(f0_dielectric, specular), wp.vec3(specular), n_dot_v)
    return base_color * ((1.0 - metallic) * transmission * (1.0 - max_channel(f)))


@wp.func
def transmission_roughness(roughness: float, ior: float) -> float:
    """The roughness of a thin wall's transmission lobe: the material's scaled by
    clamp(2 ior - 2, 0, 1), so that an IOR of 1 bends nothing and 1.5 or more the full amount
    (the Khronos glTF Sample Viewer's applyIorToRoughness)."""
    return roughness * wp.clamp(2.0 * ior - 2.0, 0.0, 1.0)


@wp.func
def transmission_blur(roughness: float, ior: float) -> float:
    """The squared GGX width alpha^2 by which a rough transmissive surface blurs what is seen
    through it, for the cheap rung: alpha = transmission_roughness^2. The squared widths of
    successive surfaces add, as the variances of independent small deflections do."""
    r = transmission_roughness(roughness, ior)
    alpha = r * r
    return alpha * alpha


@wp.func
def blurred_roughness(blur: float) -> float:
    """The perceptual roughness whose GGX width alpha has alpha^2 = blur."""
    return wp.sqrt(wp.sqrt(blur))


@wp.func
def beer_lambert(sigma: wp.vec3, distance: float) -> wp.vec3:
    """Transmittance exp(-sigma distance) per channel of a homogeneous absorbing medium
    (Beer-Lambert law; KHR_materials_volume's sigma = -ln(attenuationColor) / attenuationDistance):
    1 where sigma is 0, whatever the distance."""
    out = wp.vec3(1.0)
    for c in range(3):
        if sigma[c] > 0.0:
            out[c] = wp.exp(-sigma[c] * distance)
    return out
