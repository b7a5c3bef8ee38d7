"""The path tracer's light table (kernels/emitters.py LightTable): every punctual light and every
emissive triangle, each chosen for next-event estimation with a probability proportional to an
estimate of the power it emits.

Every triangle whose material emits (a non-zero emissive factor, not unlit) is a light. The
estimates, in lumen-like units (luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the linear RGB):

- an emissive triangle: pi Y(emissive) area, twice that for a double-sided material (a Lambertian
  emitter's power per side); the emissive texture is not read, so a textured emitter is chosen by
  its factor;
- a point light: 4 pi Y(intensity); a spot light: that times the share of the sphere its outer
  cone covers, (1 - cos outer) / 2;
- a directional light: Y(illuminance) times the cross-section pi r^2 of the scene's bounding
  sphere.

The table depends on the uploaded scene alone (pbrwarp.gpu_scene.upload's GpuScene, which is
rebuilt when a mesh, material or light changes), so it is kept in the scene's cache under that and
built once, by one thread, for every render that shares it.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from .lights import DIRECTIONAL, SPOT
from pbrwarp.kernels.emitters import LightTable

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


class _Same:
    """A cache key equal only to a key for the very same object (compared by identity)."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def __eq__(self, other):
        return isinstance(other, _Same) and other.value is self.value

    __hash__ = None


def light_table(scene, gpu) -> LightTable:
    """The light table of ``scene`` as uploaded in ``gpu`` (kept in ``scene.cache``)."""
    return scene.cache.get("emitters", _Same(gpu), lambda: _build(scene, gpu)).table


def emissive_materials(scene) -> int:
    """How many of the scene's meshes (primitives) have a material that emits light (a non-zero emissive
    factor, not unlit): every triangle of theirs is a light for the path tracer."""
    return sum(1 for p in scene.primitives if max(p.material.emissive) > 0.0 and not p.material.unlit)


class _Built:
    """The table and the arrays it points to (kept alive with it)."""

    def __init__(self, table: LightTable, arrays: tuple):
        self.table = table
        self.arrays = arrays


def face_weights(positions: np.ndarray, indices: np.ndarray, face_primitive: np.ndarray, emissive: np.ndarray,
                 double_sided: np.ndarray) -> np.ndarray:
    """Each triangle's selection weight, pi Y(emissive) area (times 2 if double-sided), in float64;
    ``emissive`` and ``double_sided`` are per primitive (emissive 0 for those that emit nothing)."""
    corners = positions.astype(np.float64)[indices.reshape(-1, 3)]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    per_primitive = math.pi * (emissive @ LUMINANCE) * np.where(double_sided, 2.0, 1.0)
    return per_primitive[face_primitive] * area


def punctual_weights(scene) -> np.ndarray:
    """Each of ``scene.punctual_lights``' selection weight (see the module docstring), in float64."""
    weights = []
    radius = None
    for light in scene.punctual_lights:
        y = float(np.asarray(light.color, dtype=np.float64) @ LUMINANCE) * light.intensity
        if light.kind == DIRECTIONAL:
            if radius is None:
                lo, hi = scene.bounds()
                radius = 0.5 * float(np.linalg.norm(hi - lo))
            weights.append(y * math.pi * max(radius, 1e-30) ** 2)
        elif light.kind == SPOT:
            weights.append(4.0 * math.pi * y * 0.5 * (1.0 - math.cos(light.outer_cone)))
        else:
            weights.append(4.0 * math.pi * y)
    return np.array(weights, dtype=np.float64)


def _build(scene, gpu) -> _Built:
    geometry = gpu.geometry
    rows = gpu.material_rows
    emissive = np.array([[float(c) for c in row.emissive] if not row.unlit else [0.0, 0.0, 0.0] for row in rows],
                        dtype=np.float64).reshape(-1, 3)
    double_sided = np.array([bool(row.double_sided) for row in rows])
    face_primitive = geometry.face_primitive.numpy()
    faces = face_weights(geometry.positions.numpy(), geometry.indices.numpy(), face_primitive, emissive,
                         double_sided)
    emitting = np.flatnonzero(faces > 0.0).astype(np.int32)
    weights = np.concatenate([punctual_weights(scene), faces[emitting]])
    weights = np.where(np.isfinite(weights), weights, np.finfo(np.float32).max)
    total = weights.sum()
    count = len(weights) if total > 0.0 else 0
    pmf = weights / total if count else np.zeros(1)
    cdf = np.cumsum(pmf) if count else np.ones(1)
    if count:
        cdf[-1] = 1.0  # rounding must leave no u in [0, 1) past the last entry
    face_pmf = np.zeros(max(len(face_primitive), 1), dtype=np.float32)
    punctual = len(scene.punctual_lights)
    if count:
        face_pmf[emitting] = pmf[punctual:]
    arrays = (
        wp.array(cdf.astype(np.float32), dtype=float, device="cpu"),
        wp.array(pmf.astype(np.float32), dtype=float, device="cpu"),
        wp.array(emitting if len(emitting) else np.zeros(1, np.int32), dtype=wp.int32, device="cpu"),
        wp.array(face_pmf, dtype=float, device="cpu"),
    )
    table = LightTable()
    table.cdf, table.pmf, table.face, table.face_pmf = arrays
    table.count, table.punctual = count, punctual if count else 0
    return _Built(table, arrays)
