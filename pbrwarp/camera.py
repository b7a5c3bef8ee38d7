"""Pinhole cameras."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validate
from .errors import InputError


@dataclass
class Camera:
    """A pinhole camera at ``eye`` looking along ``forward``; ``fov_y`` is the vertical field of
    view in degrees. The image's aspect ratio comes from the render size."""

    eye: tuple
    forward: tuple
    up: tuple
    fov_y: float = 45.0

    def __post_init__(self):
        self.eye = validate.finite_vector(self.eye, 3, "Camera eye")
        fwd = np.asarray(validate.finite_vector(self.forward, 3, "Camera forward"))
        up = np.asarray(validate.finite_vector(self.up, 3, "Camera up"))
        self.fov_y = validate.finite_scalar(self.fov_y, "Camera fov_y")
        if not 0.0 < self.fov_y < 180.0:
            raise InputError(f"Camera fov_y must lie strictly between 0 and 180 degrees, got {self.fov_y}")
        if np.linalg.norm(fwd) == 0.0:
            raise InputError("Camera eye and target coincide: the view direction is undefined")
        fwd = fwd / np.linalg.norm(fwd)
        right = np.cross(fwd, up)
        if np.linalg.norm(right) < 1e-9 * max(np.linalg.norm(up), 1e-300):
            raise InputError(f"Camera up {tuple(up)} is parallel to the view direction; choose another up vector")
        right /= np.linalg.norm(right)
        self.forward = tuple(float(c) for c in fwd)
        self.up = tuple(float(c) for c in np.cross(right, fwd))

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
