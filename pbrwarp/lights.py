"""Lights in photometric units: punctual lights (glTF KHR_lights_punctual) and area lights.

``intensity`` is in candela for point and spot lights, in lux for directional lights and in nits
(cd/m^2, the emitted luminance) for the area lights :class:`SphereLight` and :class:`RectLight`;
the radiometric quantity pbrwarp computes with is ``color * intensity`` (a white Lambert surface
lit head-on by E lux has radiance E/pi). Every field is checked whenever it is set, by the
constructor or later (pbrwarp.validate.Checked): a light never holds a NaN position or a negative
intensity. :class:`AreaLighting` chooses how the direct integrator integrates area lights
(docs/lighting.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import validate
from .errors import InputError

POINT, DIRECTIONAL, SPOT = 0, 1, 2
SPHERE, RECT = 3, 4
PUNCTUAL_KINDS = (POINT, DIRECTIONAL, SPOT)
AREA_KINDS = (SPHERE, RECT)
# Sizes of area lights (world units): their squares and products must be normal float32 numbers,
# which the kernels compute solid angles and areas with.
MIN_SIZE = 1.0e-18
MAX_SIZE = 1.0e18
# Edges of a RectLight count as perpendicular while |cos(angle)| stays below this.
MAX_EDGE_COSINE = 1.0e-4
AREA_LIGHTING_METHODS = ("representative_point", "monte_carlo")


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


def _size(what: str, value) -> float:
    x = validate.finite_scalar(value, what)
    if x == 0.0:
        raise InputError(f"{what} must be > 0, got 0: an area light of a given luminance emits in proportion to its "
                         "size, so a zero-size one emits nothing (for a light from a point, use a PointLight)")
    if not MIN_SIZE <= x <= MAX_SIZE:
        raise InputError(f"{what} must lie in [{MIN_SIZE:g}, {MAX_SIZE:g}] (world units), got {x}")
    return x


def _radius(light, value):
    return _size(f"{type(light).__name__}.radius", value)


def _edge(name):
    def check(light, value):
        what = f"{type(light).__name__}.{name}"
        edge = validate.float32_vector(value, 3, what)
        _size(f"the length of {what}", math.sqrt(sum(c * c for c in edge)))
        return edge

    return check


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


@dataclass
class SphereLight(validate.Checked):
    """A sphere of ``radius`` (world units, > 0, default 0.1) centred at ``position`` (default the
    origin) whose surface emits ``intensity`` nits (cd/m^2, >= 0, default 1) of linear RGB
    ``color`` (>= 0, default white) outwards, equally in every direction (a Lambertian emitter):
    every point that sees it receives radiance ``color * intensity`` from the solid angle it
    subtends, and a surface facing it at distance d from its centre the illuminance
    pi * intensity * radius^2 / d^2 lux. Its luminous power is 4 pi^2 radius^2 intensity lumens;
    to replace a :class:`PointLight` of I candela, take intensity = I / (pi radius^2). Points
    inside the sphere receive none of its light (it emits outwards only). A zero radius is refused:
    at a given luminance the light would emit nothing.

    The light itself is not seen by camera rays; it lights surfaces (and glossy surfaces reflect
    it). ``pw.render(..., area_lighting=pw.AreaLighting(...))`` chooses how exactly."""

    position: tuple = (0.0, 0.0, 0.0)
    radius: float = 0.1
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    kind = SPHERE
    _checks = {"position": _position, "radius": _radius, "color": _color, "intensity": _intensity}

    @property
    def area(self) -> float:
        """The emitting surface in square world units, 4 pi radius^2."""
        return 4.0 * math.pi * self.radius ** 2

    @property
    def power(self) -> float:
        """Luminous power in lumens (per unit of ``color``): pi * intensity * area."""
        return math.pi * self.intensity * self.area


@dataclass
class RectLight(validate.Checked):
    """A rectangle centred at ``position`` (default the origin) with edges ``edge_u`` and ``edge_v``
    (world-unit vectors, perpendicular, each of length > 0; defaults 1 along x and 1 along z), so
    that its corners are position +- edge_u / 2 +- edge_v / 2, emitting ``intensity`` nits (cd/m^2,
    >= 0, default 1) of linear RGB ``color`` (>= 0, default white) from one side only: the side
    edge_u x edge_v points to (the defaults emit downwards, along -y), as a Lambertian emitter.
    Every point in front of it that sees it receives radiance ``color * intensity`` from the solid
    angle it subtends; points behind it or in its plane receive nothing. Its luminous power is
    pi * intensity * |edge_u| * |edge_v| lumens. Zero-length edges are refused: at a given
    luminance the light would emit nothing.

    The light itself is not seen by camera rays; it lights surfaces (and glossy surfaces reflect
    it). ``pw.render(..., area_lighting=pw.AreaLighting(...))`` chooses how exactly."""

    position: tuple = (0.0, 0.0, 0.0)
    edge_u: tuple = (1.0, 0.0, 0.0)
    edge_v: tuple = (0.0, 0.0, 1.0)
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    kind = RECT
    _checks = {"position": _position, "edge_u": _edge("edge_u"), "edge_v": _edge("edge_v"), "color": _color,
               "intensity": _intensity}

    def _check_together(self):
        u, v = self.edge_u, self.edge_v
        lengths = math.sqrt(sum(c * c for c in u)) * math.sqrt(sum(c * c for c in v))
        if abs(sum(a * b for a, b in zip(u, v))) > MAX_EDGE_COSINE * lengths:
            raise InputError(f"RectLight edges must be perpendicular, got edge_u={u}, edge_v={v} (for a tilted "
                             "rectangle, rotate both edges)")

    @property
    def normal(self) -> tuple:
        """The unit vector the light emits along: edge_u x edge_v, normalized."""
        u, v = self.edge_u, self.edge_v
        c = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        length = math.sqrt(sum(x * x for x in c))
        return tuple(x / length for x in c)

    @property
    def area(self) -> float:
        """The emitting surface in square world units, |edge_u| |edge_v|."""
        return math.sqrt(sum(c * c for c in self.edge_u)) * math.sqrt(sum(c * c for c in self.edge_v))

    @property
    def power(self) -> float:
        """Luminous power in lumens (per unit of ``color``): pi * intensity * area."""
        return math.pi * self.intensity * self.area


@dataclass(frozen=True)
class AreaLighting:
    """How the direct integrator lights surfaces with area lights (:class:`SphereLight`,
    :class:`RectLight`), passed as ``pw.render(..., area_lighting=pw.AreaLighting(...))`` (the
    ``quality`` presets pick one otherwise); it matters only when the scene has area lights.

    - ``method`` (default "representative_point"): "representative_point", the cheap rung (Karis
      2013): the diffuse lobe gets the light's exact unoccluded irradiance (a sphere's
      pi L sin^2(alpha) cos(theta), Snyder's form across the horizon; a rectangle's polygon form
      factor clipped to the horizon), the specular lobe the light as a point where the
      reflection ray passes closest to it, widened by Karis's energy normalization; one shadow
      ray to the light's centre (hard shadows) |
      "monte_carlo", the exact rung: ``samples`` points per light and hit, drawn uniformly in the
      solid angle the light subtends, each with a shadow ray (soft shadows), through the very
      BRDF punctual lights use.
    - ``samples``: points per light and hit for "monte_carlo", a whole number >= 1 (default 16).

    An unknown method or ``samples`` < 1 raises InputError.
    """

    method: str = "representative_point"
    samples: int = 16

    def __post_init__(self):
        if self.method not in AREA_LIGHTING_METHODS:
            raise InputError(f"AreaLighting method must be one of {', '.join(AREA_LIGHTING_METHODS)}, "
                             f"got {self.method!r}")
        object.__setattr__(self, "samples", validate.positive_int(self.samples, "AreaLighting.samples"))

    def describe(self) -> str:
        if self.method == "representative_point":
            return ("representative point (Karis 2013): exact unoccluded irradiance for the diffuse lobe, the "
                    "point nearest the reflection ray with energy normalization for the specular lobe")
        return (f"Monte Carlo, {self.samples} points per light and hit, uniform in the solid angle each light "
                "subtends (a sphere's cone; a rectangle's spherical rectangle, Urena et al. 2013)")


def area_lighting_for_quality(quality: str | None, area_lighting: AreaLighting | None) -> AreaLighting:
    """The area-light rung a render uses: ``area_lighting`` when given, else the quality preset's:
    the representative point for every preset but "reference", which integrates by Monte Carlo
    with 64 points per light and hit."""
    if area_lighting is not None:
        if not isinstance(area_lighting, AreaLighting):
            from .errors import InputTypeError

            raise InputTypeError(f"area_lighting must be a pbrwarp.AreaLighting, got {type(area_lighting).__name__}")
        return area_lighting
    return AreaLighting(method="monte_carlo", samples=64) if quality == "reference" else AreaLighting()


PunctualLight = PointLight | DirectionalLight | SpotLight
AreaLight = SphereLight | RectLight
Light = PunctualLight | AreaLight
