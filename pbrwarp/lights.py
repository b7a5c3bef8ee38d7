"""Punctual lights in photometric units (glTF KHR_lights_punctual).

``intensity`` is in candela for point and spot lights and in lux for directional lights; the
radiometric quantity pbrwarp computes with is ``color * intensity`` (a white Lambert surface lit
head-on by E lux has radiance E/pi). Every field is checked whenever it is set, by the
constructor or later (pbrwarp.validate.Checked): a light never holds a NaN position or a negative
intensity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import validate
from .errors import InputError

POINT, DIRECTIONAL, SPOT = 0, 1, 2


def _position(light, value):
    return validate.float32_vector(value, 3, f"{type(light).__name__}.position")


def _direction(light, value):
    return validate.unit_vector(value, f"{type(light).__name__}.direction")


def _color(light, value):
    return validate.colour(value, f"{type(light).__name__}.color")


def _intensity(light, value):
    return validate.non_negative(value, f"{type(light).__name__}.intensity")


def _range(light, value):
    """None (no cut-off) or a distance > 0 within float32's range."""
    if value is None:
        return None
    x = validate.finite_scalar(value, f"{type(light).__name__}.range")
    if not 0.0 < x < 3.0e38:
        raise InputError(f"{type(light).__name__}.range must be a distance > 0 (or None for no cut-off), got {x}")
    return x


def _angle(name):
    return lambda light, value: validate.finite_scalar(value, f"{type(light).__name__}.{name}")


@dataclass
class PointLight(validate.Checked):
    """Light radiating ``intensity`` candela (>= 0, default 1) of linear RGB ``color`` (>= 0,
    default white) equally in every direction from ``position`` (world units, within float32's
    range; default the origin), falling off by the inverse square law. ``range`` (world units
    > 0, default None: unlimited) is KHR_lights_punctual's cut-off: the falloff is then windowed
    by clamp(1 - (distance / range)^4, 0, 1), as the extension recommends, so that the light
    reaches exactly nothing beyond it."""

    position: tuple = (0.0, 0.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    range: float | None = None

    kind = POINT
    _checks = {"position": _position, "color": _color, "intensity": _intensity, "range": _range}


@dataclass
class DirectionalLight(validate.Checked):
    """Light from infinitely far away, travelling along ``direction`` (any non-zero vector, stored
    normalized; default straight down, (0, -1, 0)): ``intensity`` lux (>= 0, default 1) of linear
    RGB ``color`` (>= 0, default white) on a surface facing it."""

    direction: tuple = (0.0, -1.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    kind = DIRECTIONAL
    _checks = {"direction": _direction, "color": _color, "intensity": _intensity}


@dataclass
class SpotLight(validate.Checked):
    """A point light at ``position`` limited to a cone around ``direction`` (as for
    :class:`PointLight` and :class:`DirectionalLight`); ``intensity`` in candela on its axis.

    ``inner_cone`` and ``outer_cone`` are half-angles in radians (defaults 0 and pi/4) with
    0 <= inner_cone <= outer_cone <= pi/2; between them the intensity falls off smoothly as glTF's
    KHR_lights_punctual specifies. (To widen a cone, set ``outer_cone`` before ``inner_cone``.)
    ``range`` windows the falloff as for :class:`PointLight`.
    """

    position: tuple = (0.0, 0.0, 0.0)
    direction: tuple = (0.0, -1.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    inner_cone: float = 0.0
    outer_cone: float = math.pi / 4.0
    range: float | None = None

    kind = SPOT
    _checks = {"position": _position, "direction": _direction, "color": _color, "intensity": _intensity,
               "inner_cone": _angle("inner_cone"), "outer_cone": _angle("outer_cone"), "range": _range}

    def _check_together(self):
        if not 0.0 <= self.inner_cone <= self.outer_cone <= math.pi / 2.0:
            raise InputError(
                "SpotLight cones must satisfy 0 <= inner_cone <= outer_cone <= pi/2 (radians), got "
                f"inner_cone={self.inner_cone}, outer_cone={self.outer_cone}"
            )


Light = PointLight | DirectionalLight | SpotLight
