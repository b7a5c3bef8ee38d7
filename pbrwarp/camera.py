"""Pinhole cameras."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError


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
    """A pinhole camera at ``eye`` looking along ``forward``; ``fov_y`` is the vertical field of
    view in degrees, strictly between 0 and 180. The image's aspect ratio comes from the render
    size. ``forward`` is stored normalized and ``up`` made perpendicular to it (unit length, in
    the plane of the two), also when either is set later; every field is checked when set."""

    eye: tuple
    forward: tuple
    up: tuple
    fov_y: float = 45.0

    _checks = {
        "eye": lambda camera, value: validate.finite_vector(value, 3, "Camera eye"),
        "forward": _view_direction,
        "up": lambda camera, value: validate.finite_vector(value, 3, "Camera up"),
        "fov_y": lambda camera, value: field_of_view(value),
    }

    def _check_together(self):
        object.__setattr__(self, "up", tuple(float(c) for c in _image_up(np.asarray(self.forward), self.up)))

    @property
    def right(self) -> tuple:
        return tuple(float(c) for c in np.cross(self.forward, self.up))

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), fov_y: float = 45.0) -> "Camera":
        eye_v = np.asarray(validate.finite_vector(eye, 3, "Camera eye"))
        target_v = np.asarray(validate.finite_vector(target, 3, "Camera target"))
        return cls(eye=tuple(eye_v), forward=tuple(target_v - eye_v), up=up, fov_y=fov_y)

    @classmethod
    def from_matrix(cls, camera_to_world, fov_y: float = 45.0) -> "Camera":
        """A camera from a 4x4 camera-to-world matrix in the glTF/OpenGL convention (looking down -Z, +Y up)."""
        m = np.asarray(camera_to_world, dtype=np.float64)
        if m.shape != (4, 4) or not np.all(np.isfinite(m)):
            raise InputError(f"camera matrix must be a finite 4x4 matrix, got shape {m.shape}")
        return cls(eye=tuple(m[:3, 3]), forward=tuple(-m[:3, 2]), up=tuple(m[:3, 1]), fov_y=fov_y)

    @classmethod
    def frame(cls, scene, direction=(0.6, 0.45, 1.0), up=(0.0, 1.0, 0.0), fov_y: float = 45.0,
              margin: float = 1.1) -> "Camera":
        """A camera looking at the scene's bounding sphere from ``direction`` (pointing from the
        scene towards the eye), close enough that the whole sphere fits the vertical field of view."""
        lo, hi = scene.bounds()
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-30)
        d = np.asarray(validate.finite_vector(direction, 3, "Camera.frame direction"))
        d = d / np.linalg.norm(d)
        distance = margin * radius / math.sin(math.radians(fov_y) / 2.0)
        return cls.look_at(centre + d * distance, centre, up=up, fov_y=fov_y)
