"""Transmission as a lobe of the path tracer's BSDF (KHR_materials_transmission, KHR_materials_volume):
what a path does at a transmissive surface that bends light, with the dielectric interfaces of
kernels/transmission.py.

A surface *scatters* light through it where it is the boundary of a volume (thickness > 0, not
alpha-blended: a blended surface is a thin wall, as in the direct kernel) or a rough thin wall
(transmission_roughness of its material's roughness factor > 0); smooth thin walls pass light
straight, as null events (kernels/path.py find_surface). At a scattering surface hit from
outside, the path picks the transmission lobe with probability p = min(max channel of the
transmitted share, MAX_PASSED) and is weighted by share / p, or keeps the surface's reflecting
BRDF with weight 1 / (1 - p) (a one-sample choice between the BSDF's parts, Veach 1997, section
9.2.4): the transmission lobe then
- enters a volume by Snell's law (refract_through; roughness 0, a delta event) or through a GGX
  normal visible from the viewer (sample_rough_interface, Walter et al. 2007 with Heitz 2018's
  visible normals), its weight G1 of the new direction;
- or passes a rough thin wall along the lobe the extension defines, the specular lobe "sampled
  along the line of sight through the surface" (sample_thin_lobe's): the path tracer mirrors the
  shading frame through the wall (thin_lobe_frame) and samples, evaluates and lights that lobe
  with its BRDF code, as the reflection of a white metal (F = 1) at the lobe's roughness, so that
  next-event estimation reaches lights behind the wall, MIS-weighted with the lobe's own pdf.
A volume's surface hit from inside is a bare dielectric interface (relative IOR 1 / ior, no base
colour, no diffuse part, as in the direct kernel): sample_dielectric_interface reflects off it
with the exact Fresnel reflectance of the (micro)facet, total internal reflection included, and
refracts out otherwise. Inside a volume, throughput falls by Beer-Lambert over the distance
travelled (kernels/transmission.py beer_lambert).

Shadow rays stop at scattering surfaces. Next-event estimation does not sample the directions
of a volume's lobes (a straight shadow ray through a refracting surface is no path): a direction
drawn from them records NOT_LIGHT_SAMPLED as its pdf, which gives the emission it finds full MIS
weight.
"""

import functools

import warp as wp

from .brdf import fresnel_dielectric
from .direction_sampling import G1_SmithGGX, orthonormal_basis, sample_ggx_vndf
from .microfacet import alpha_from_roughness
from .robust import FLOAT32_MAX
from .scene_data import MaterialData
from .transmission import reflect, refract, refract_through, sample_rough_interface, transmission_roughness

wp.set_module_options({"enable_backward": False})

# A path passes a transmissive surface with at most this probability (the rest reflects), so
# that the reflecting part keeps being sampled.
MAX_PASSED = wp.constant(0.95)
# The pdf recorded for a direction next-event estimation cannot sample: the power heuristic
# (kernels/bsdf_sampling.py) gives what the path finds along it weight 1 to float32 precision.
NOT_LIGHT_SAMPLED = wp.constant(FLOAT32_MAX)
# What scatter decides: the surface's reflecting BRDF goes on as at any surface; the path was
# scattered along a direction drawn; or it passes a rough thin wall along its mirrored lobe.
REFLECTED = wp.constant(0)
SCATTERED = wp.constant(1)
MIRRORED = wp.constant(2)


@wp.func
def sample_dielectric_interface(d: wp.vec3, n: wp.vec3, ng: wp.vec3, eta: float, roughness: float,
                                u_fresnel: float, u: wp.vec2):
    """(new direction, weight): one draw of a bare dielectric interface's BSDF (reflection and
    refraction, Walter, Marschner, Li and Torrance 2007) for a ray of direction ``d`` meeting it,
    normals ``n`` (shading) and ``ng`` turned towards where it comes from, ``eta`` the relative IOR
    of the far side over the near one. A facet normal m is drawn from the GGX normals visible
    from -d (Heitz 2018; m = n at roughness 0) and the ray reflects off it with probability
    F = fresnel_dielectric(-d . m, eta) (1 on total internal reflection), refracts through it
    otherwise. So drawn, the BSDF times |n . l| over the pdf is G1 of the new direction (1 at
    roughness 0): the weight, 0 where the direction falls on the wrong side of the geometric
    surface. A ray seen from below its shading normal is bent as by a smooth interface."""
    frame = orthonormal_basis(n)
    v_local = wp.transpose(frame) * (-d)
    if roughness <= 0.0 or v_local[2] <= 0.0:
        refracts, direction, bent_by = refract_through(d, n, ng, eta)
        if refracts and u_fresnel < fresnel_dielectric(wp.dot(bent_by, -d), eta):
            direction = reflect(-d, bent_by)
            if wp.dot(direction, ng) <= 0.0:
                direction = reflect(-d, ng)
        return direction, 1.0
    alpha = alpha_from_roughness(roughness)
    m = frame * sample_ggx_vndf(v_local, alpha, u)
    reflects = u_fresnel < fresnel_dielectric(wp.dot(-d, m), eta)
    direction = reflect(-d, m)
    if not reflects:
        refracts, direction = refract(-d, m, eta)
    side = wp.dot(direction, ng)
    if (reflects and side <= 0.0) or ((not reflects) and side >= 0.0):
        return direction, 0.0
    return direction, G1_SmithGGX(wp.abs(wp.dot(direction, n)), alpha)


@wp.func
def is_volume(mat: MaterialData) -> bool:
    """Whether a transmissive material bounds a volume: thickness > 0 (KHR_materials_volume) and
    not alpha-blended (paths pass blended surfaces by their coverage, which would lose track of
    which side they are on)."""
    return mat.thickness > 0.0 and mat.alpha_blend == 0


@wp.func
def medium_after(sigma: wp.vec3, mat: MaterialData, back_face: int, ng: wp.vec3, direction: wp.vec3) -> wp.vec3:
    """The attenuation coefficient of the medium a path is in after leaving a surface along
    ``direction`` (``ng`` turned towards where it came from): a volume's once it crosses the
    volume's surface from outside, none once it crosses it from inside, ``sigma`` otherwise
    (reflected, or a thin wall). One volume at a time: volumes nested in others are not
    tracked."""
    if is_volume(mat) and wp.dot(direction, ng) < 0.0:
        if back_face == 0:
            return mat.attenuation
        return wp.vec3(0.0)
    return sigma


@wp.func
def thin_lobe_frame(n: wp.vec3, v: wp.vec3, ng: wp.vec3, roughness: float, ior: float):
    """(n, v, ng, roughness) of a rough thin wall's transmission lobe seen as a reflection: the
    shading normal ``n``, the view ``v`` and the geometric normal ``ng`` mirrored through the
    wall's plane (n reversed, v reflected by the plane of n), and the lobe's roughness
    (transmission_roughness). Reflection off that frame is sample_thin_lobe's direction:
    mirroring keeps the angles, so D, G and the visible-normal pdf are the reflection's."""
    return -n, v - 2.0 * wp.dot(v, n) * n, -ng, transmission_roughness(roughness, ior)


@functools.cache
def transmission_lobes(volume: bool, rough: bool):
    """(scatters, scatter) compiled for a scene's transmissive materials: ``volume`` where some
    are volumes, ``rough`` where some thin walls are rough. ``scatters(mat)``: whether a
    transmissive material's surfaces scatter light through them (a volume's, a rough thin wall's
    by its roughness factor) rather than pass it straight. ``scatter(...)``: the event at one of
    them (see its docstring)."""

    @wp.func
    def scatters(mat: MaterialData) -> bool:
        if wp.static(volume):
            if is_volume(mat):
                return True
        if wp.static(rough):
            return transmission_roughness(mat.roughness, mat.ior) > 0.0
        return False

    @wp.func
    def scatter(d: wp.vec3, n: wp.vec3, ng: wp.vec3, back_face: int, mat: MaterialData, roughness: float,
                share: wp.vec3, u_choice: float, u_fresnel: float, u: wp.vec2):
        """(event, new direction, weight of the event) where a path along ``d`` meets a
        scattering surface (``scatters``), normals ``n`` and ``ng`` turned towards it,
        ``roughness`` the material's there, ``share`` the share of light it transmits
        (transmitted_share). From inside a volume: a bare interface, SCATTERED (reflected or
        refracted). From outside: the transmission lobe with probability p, else (REFLECTED, d,
        1 / (1 - p)): the caller goes on with the reflecting BRDF. The lobe of a volume:
        SCATTERED into it, weight share / p times the lobe's; of a rough thin wall: (MIRRORED,
        d, share / p), the caller goes on with the lobe's mirrored frame (thin_lobe_frame)."""
        thick = False
        if wp.static(volume):
            thick = is_volume(mat)
            if thick and back_face == 1:
                direction, w = sample_dielectric_interface(d, n, ng, 1.0 / mat.ior, roughness, u_fresnel, u)
                return SCATTERED, direction, wp.vec3(w)
        p = wp.min(wp.max(wp.max(share[0], share[1]), share[2]), MAX_PASSED)
        if p <= 0.0:
            return REFLECTED, d, wp.vec3(1.0)
        if u_choice >= p:
            return REFLECTED, d, wp.vec3(1.0 / (1.0 - p))
        if not thick:
            return MIRRORED, d, share / p
        direction = d
        w = float(1.0)
        refracts = bool(False)
        if roughness > 0.0:
            refracts, direction, w = sample_rough_interface(d, n, ng, mat.ior, roughness, u)
        else:
            refracts, direction, bent_by = refract_through(d, n, ng, mat.ior)
        if not refracts:  # reflected: the BRDF's part, not this lobe's
            w = 0.0
        return SCATTERED, direction, share * (w / p)

    return scatters, scatter
