"""Pinhole cameras."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError

# Camera.frame's image up when the view direction is parallel to the up vector given: the first
# of these not within ~25 degrees of the view direction (for a +Y-up scene seen from straight
# above, -Z: the far side of the scene at the top of the image).
FALLBACK_UPS = ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0))


def field_of_view(value) -> float:
    """A vertical field of view in degrees, strictly between 0 and 180."""
    fov = validate.finite_scalar(value, "Camera fov_y")
    if not 0.0 < fov < 180.0:
        raise InputError(f"Camera fov_y must lie strictly between 0 and 180 degrees, got {fov}")
    return fov


def _view_direction(camera, value) -> tuple:
    if not any(validate.finite_vector(value, 3, "Camera forward")):
        raise InputError("Camera eye and target coincide: the view direction is undefined")
    return validate.unit_vector(value, "Camera forward")


def _image_up(forward, up) -> np.ndarray:
    """The unit vector in the plane of ``forward`` (unit) and ``up`` perpendicular to forward."""
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9 * max(np.linalg.norm(up), 1e-300):
        raise InputError(f"Camera up {tuple(up)} is parallel to the view direction; choose another up vector")
    right /= np.linalg.norm(right)
    return np.cross(right, forward)


@dataclass
class Camera(validate.Checked):
    """A pinhole camera at ``eye`` (world units, within float32's range) looking along
    ``forward`` (any non-zero vector); ``up`` is the image's up direction, and ``fov_y`` the
    vertical field of view in degrees, strictly between 0 and 180 (default 45). The image's
    aspect ratio comes from the render size. ``forward`` is stored normalized and ``up`` made
    perpendicular to it (unit length, in the plane of the two), also when either is set later.
    Every field is checked when set, by the constructor or later: InputError for a value out of
    range or an ``up`` parallel to ``forward``, InputTypeError for one that is not numbers."""

    eye: tuple
    forward: tuple
    up: tuple
    fov_y: float = 45.0

    _checks = {
        "eye": lambda camera, value: validate.float32_vector(value, 3, "Camera eye"),
        "forward": _view_direction,
        "up": lambda camera, value: validate.finite_vector(value, 3, "Camera up"),
        "fov_y": lambda camera, value: field_of_view(value),
    }

    def _check_together(self):
        object.__setattr__(self, "up", tuple(float(c) for c in _image_up(np.asarray(self.forward), self.up)))

    @property
    def right(self) -> tuple:
        """The image's right direction, forward x up (unit length)."""
        return tuple(float(c) for c in np.cross(self.forward, self.up))

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), fov_y: float = 45.0) -> "Camera":
        """A camera at ``eye`` looking at ``target`` (world positions, which must differ), ``up``
        (default +Y) turned into the image's up, ``fov_y`` the vertical field of view in degrees
        (default 45). InputError for coinciding points or an ``up`` along the view."""
        eye_v = np.asarray(validate.finite_vector(eye, 3, "Camera eye"))
        target_v = np.asarray(validate.finite_vector(target, 3, "Camera target"))
        return cls(eye=tuple(eye_v), forward=tuple(target_v - eye_v), up=up, fov_y=fov_y)

    @classmethod
    def from_matrix(cls, camera_to_world, fov_y: float = 45.0) -> "Camera":
        """A camera from a 4x4 camera-to-world matrix in the glTF/OpenGL convention (looking down -Z,
        +Y up; the eye is its translation), ``fov_y`` the vertical field of view in degrees
        (default 45). InputError for a matrix that is not a finite 4x4 one."""
        m = np.asarray(camera_to_world, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise InputError(f"camera matrix must be a finite 4x4 matrix, got shape {m.shape}")
        return cls(eye=tuple(m[:3, 3]), forward=tuple(-m[:3, 2]), up=tuple(m[:3, 1]), fov_y=fov_y)

    @classmethod
    def frame(cls, scene, direction=(0.6, 0.45, 1.0), up=(0.0, 1.0, 0.0), fov_y: float = 45.0,
              margin: float = 1.1, aspect: float = 1.0) -> "Camera":
        """A camera looking at the whole scene from ``direction`` (a vector pointing from the scene
        towards the eye; default (0.6, 0.45, 1)), as close as every vertex allows: the scene's
        projection is centred in the image and spans 1/``margin`` of it (default 1.1, > 0) along
        the tighter of the two axes, and at most that along the other. ``aspect`` is the width /
        height of the image it frames (render's width / height): the default, 1, frames a square
        image and so also fits any wider one. ``fov_y`` is the vertical field of view in degrees
        (default 45). The image's up is ``up`` (default +Y) made perpendicular to the view
        direction; where the two are parallel, -Z (+Y if the view is along Z). InputError for a
        scene without meshes, a bad argument, or a scene so large that the eye would leave
        float32's range."""
        if not scene.primitives:
            raise InputError("the scene has no meshes: Camera.frame has nothing to frame")
        points = np.concatenate([scene.cache.fact("hull points", p, _hull_points) for p in scene.primitives])
        lo, hi = points.min(axis=0), points.max(axis=0)
        forward = -np.asarray(validate.unit_vector(direction, "Camera.frame direction"))
        image_up = _frame_up(forward, np.asarray(validate.unit_vector(up, "Camera.frame up")))
        right = np.cross(forward, image_up)
        tan_half = math.tan(math.radians(field_of_view(fov_y)) / 2.0)
        slope_y = tan_half / _positive(margin, "Camera.frame margin")
        slope_x = _positive(aspect, "Camera.frame aspect") * slope_y
        # in coordinates about the bounds' centre, for precision far from the origin
        centre = 0.5 * (lo + hi)
        points = points - centre
        x, y, depth = points @ right, points @ image_up, points @ forward
        # the eye's coordinate along forward: the largest at which both the horizontal and the
        # vertical view hold every point, and in front of them all should they project onto one
        # spot (a line seen end-on; a scene collapsed to a point, sized by its distance from 0)
        extent = float(np.max(hi - lo))
        size = extent if extent > 0.0 else max(float(np.max(np.abs(centre))), 1.0)
        along = min(_closest_apex(x, depth, slope_x), _closest_apex(y, depth, slope_y),
                    float(depth.min()) - 1e-6 * size)
        depth = depth - along
        eye = centre + along * forward + _centred(x, depth) * right + _centred(y, depth) * image_up
        if np.max(np.abs(eye)) > validate.FLOAT32_MAX:
            raise InputError(f"the scene spans {extent:.3g} units: a camera framing it would stand at "
                             f"{tuple(float(c) for c in eye)}, beyond the float32 range (|x| < 3.4e38) the "
                             "kernels compute in; scale the scene down")
        return cls(eye=tuple(eye), forward=tuple(forward), up=tuple(image_up), fov_y=fov_y)


def _hull_points(prim) -> np.ndarray:
    """The vertices of ``prim``'s convex hull, which frame it as all its vertices do (a view holds
    a set of points if and only if it holds their hull); all of them where Qhull finds no
    full-dimensional hull (a flat or degenerate mesh)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return prim.positions[ConvexHull(prim.positions).vertices]
    except (QhullError, ValueError):
        return prim.positions


def _positive(value, what: str) -> float:
    x = validate.finite_scalar(value, what)
    if x <= 0.0:
        raise InputError(f"{what} must be > 0, got {x}")
    return x


def _frame_up(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Camera.frame's image up: ``up`` made perpendicular to ``forward``, or a FALLBACK_UPS one
    where the two are parallel."""
    try:
        return _image_up(forward, up)
    except InputError:
        fallback = next(v for v in FALLBACK_UPS if abs(np.dot(forward, v)) < 0.9)
        return _image_up(forward, fallback)


def _closest_apex(a: np.ndarray, depth: np.ndarray, slope: float) -> float:
    """The largest z at which a view of half-width ``slope`` per unit of depth (an image axis's
    tan(half angle)), its apex at depth z, holds every point (a, depth): each of its two sides
    passes the points at (slope depth -+ a) - slope z >= 0, so z is the mean of the two sides'
    tightest bounds over 2 slope, and the apex's a their half-difference (which _centred finds)."""
    return float(np.min(slope * depth - a) + np.min(slope * depth + a)) / (2.0 * slope)


def _centred(a: np.ndarray, depth: np.ndarray) -> float:
    """The offset c along one image axis that centres the projections (a - c) / depth of points
    (depth > 0): the c of the smallest s with |a - c| <= s depth for every point. The gap
    min(a + s depth) - max(a - s depth) is concave and increasing in s, negative at 0; Newton's
    steps from s = 0 reach its root from below in a few iterations (it is piecewise linear)."""
    s = 0.0
    tolerance = 1e-12 * float(np.max(np.abs(a)) + np.max(depth))
    for _ in range(100):
        low, high = a - s * depth, a + s * depth
        i, j = int(np.argmax(low)), int(np.argmin(high))
        gap = high[j] - low[i]
        if gap >= -tolerance:
            break
        s -= gap / (depth[i] + depth[j])
    return 0.5 * float(low[i] + high[j])
