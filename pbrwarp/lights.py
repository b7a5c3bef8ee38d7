"""Punctual lights in photometric units (glTF KHR_lights_punctual).

``intensity`` is in candela for point and spot lights and in lux for directional lights; the
radiometric quantity pbrwarp computes with is ``color * intensity`` (a white Lambert surface lit
head-on by E lux has radiance E/pi).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError

POINT, DIRECTIONAL, SPOT = 0, 1, 2


def _unit(v, what):
    x = np.asarray(validate.finite_vector(v, 3, what))
    n = np.linalg.norm(x)
    if n == 0.0:
        raise InputError(f"{what} must not be the zero vector")
    return tuple(float(c) for c in x / n)


@dataclass
class PointLight:
    """Light radiating ``intensity`` candela equally in every direction from ``position``."""

    position: tuple = (0.0, 0.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    kind = POINT

    def __post_init__(self):
        self.position = validate.finite_vector(self.position, 3, f"{type(self).__name__}.position")
        self.color = validate.colour(self.color, f"{type(self).__name__}.color")
        self.intensity = validate.non_negative(self.intensity, f"{type(self).__name__}.intensity")


@dataclass
class DirectionalLight:
    """Light from infinitely far away, travelling along ``direction``; ``intensity`` in lux."""

    direction: tuple = (0.0, -1.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    kind = DIRECTIONAL

    def __post_init__(self):
        self.direction = _unit(self.direction, "DirectionalLight.direction")
        self.color = validate.colour(self.color, "DirectionalLight.color")
        self.intensity = validate.non_negative(self.intensity, "DirectionalLight.intensity")


@dataclass
class SpotLight:
    """A point light limited to a cone around ``direction``; ``intensity`` in candela on its axis.

    ``inner_cone`` and ``outer_cone`` are half-angles in radians with
    0 <= inner_cone <= outer_cone <= pi/2; between them the intensity falls off smoothly as glTF's
    KHR_lights_punctual specifies.
    """

    position: tuple = (0.0, 0.0, 0.0)
    direction: tuple = (0.0, -1.0, 0.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    inner_cone: float = 0.0
    outer_cone: float = math.pi / 4.0

    kind = SPOT

    def __post_init__(self):
        self.position = validate.finite_vector(self.position, 3, "SpotLight.position")
        self.direction = _unit(self.direction, "SpotLight.direction")
        self.color = validate.colour(self.color, "SpotLight.color")
        self.intensity = validate.non_negative(self.intensity, "SpotLight.intensity")
        self.inner_cone = validate.finite_scalar(self.inner_cone, "SpotLight.inner_cone")
        self.outer_cone = validate.finite_scalar(self.outer_cone, "SpotLight.outer_cone")
        if not 0.0 <= self.inner_cone <= self.outer_cone <= math.pi / 2.0:
            raise InputError(
                "SpotLight cones must satisfy 0 <= inner_cone <= outer_cone <= pi/2 (radians), got "
                f"inner_cone={self.inner_cone}, outer_cone={self.outer_cone}"
            )


Light = PointLight | DirectionalLight | SpotLight
