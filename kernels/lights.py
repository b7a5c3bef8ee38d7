"""Punctual lights (KHR_lights_punctual): the direction to the light and the irradiance it
delivers to a surface facing it, in photometric units (lux)."""

import functools

import warp as wp

from .robust import RAY_FAR, clamp_to_float32_max

wp.set_module_options({"enable_backward": False})

LIGHT_POINT = wp.constant(0)
LIGHT_DIRECTIONAL = wp.constant(1)
LIGHT_SPOT = wp.constant(2)
# Squared distance floor of the inverse-square law: a point light on the surface gives a huge
# but finite irradiance instead of Inf.
MIN_DISTANCE_SQ = wp.constant(1.0e-20)


@wp.struct
class LightData:
    kind: int
    position: wp.vec3
    # the direction the light travels (directional and spot lights)
    direction: wp.vec3
    # color * intensity: candela for point/spot, lux for directional
    intensity: wp.vec3
    # glTF spot cone: attenuation = saturate(cos(angle) * cone_scale + cone_offset)^2
    cone_scale: float
    cone_offset: float
    # KHR_lights_punctual's range as 1 / range^4, 0 for none
    inv_range4: float


@wp.struct
class LightSample:
    to_light: wp.vec3
    # irradiance on a surface facing the light (times n.l gives the irradiance)
    irradiance: wp.vec3
    distance: float


@wp.func
def spot_attenuation(light: LightData, to_light: wp.vec3) -> float:
    """glTF's smooth cone falloff between the inner and outer cone angles."""
    cos_angle = wp.dot(light.direction, -to_light)
    a = wp.clamp(cos_angle * light.cone_scale + light.cone_offset, 0.0, 1.0)
    return a * a


@wp.func
def range_window(light: LightData, dist_sq: float) -> float:
    """KHR_lights_punctual's window of the inverse square law, clamp(1 - (d / range)^4, 0, 1):
    1 at the light, 0 from its range on, 1 everywhere without a range."""
    if light.inv_range4 == 0.0:
        return 1.0  # and no 0 * Inf where d^4 overflows float32
    return wp.clamp(1.0 - dist_sq * dist_sq * light.inv_range4, 0.0, 1.0)


@wp.func
def sample_directional(light: LightData) -> LightSample:
    out = LightSample()
    out.to_light = -light.direction
    out.irradiance = light.intensity
    out.distance = RAY_FAR
    return out


@wp.func
def sample_positional(light: LightData, p: wp.vec3) -> LightSample:
    """A point light's direction, distance and inverse-square irradiance (no spot cone)."""
    out = LightSample()
    d = light.position - p
    dist_sq = wp.dot(d, d)
    dist = wp.sqrt(dist_sq)
    if dist > 0.0:
        out.to_light = d / dist
    else:
        out.to_light = -light.direction
    out.distance = dist
    out.irradiance = clamp_to_float32_max(light.intensity * (range_window(light, dist_sq)
                                                             / wp.max(dist_sq, MIN_DISTANCE_SQ)))
    return out


@functools.cache
def light_sampler(point: bool, directional: bool, spot: bool):
    """sample_light(light, p) -> LightSample compiled for the light kinds a scene has: the code of
    an absent kind is not generated."""

    @wp.func
    def sample_light(light: LightData, p: wp.vec3) -> LightSample:
        out = LightSample()
        if wp.static(directional):
            if wp.static(point or spot):
                if light.kind == LIGHT_DIRECTIONAL:
                    return sample_directional(light)
            else:
                return sample_directional(light)
        if wp.static(point or spot):
            out = sample_positional(light, p)
            if wp.static(spot):
                if light.kind == LIGHT_SPOT:
                    out.irradiance = out.irradiance * spot_attenuation(light, out.to_light)
        return out

    return sample_light
