"""The path tracer's light table (kernels/emitters.py LightTable): every area light, every emissive
triangle and the environment (where it lights the scene), each chosen for next-event estimation
with a probability proportional to an estimate of the power it emits. Punctual lights are not in
it: next-event estimation visits every one of them at every vertex, as the direct kernel does (a
shadow ray each). Chosen by power, a directional light is weighted by a guess at the power it
sends through the scene, and where that guess is low against a point light's (a sun and a lamp),
the light that dominates the image is drawn rarely and at a large weight: noise.

Every triangle whose material emits (a non-zero emissive factor, not unlit) is a light. The
estimates, in lumen-like units (luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the linear RGB):

- an emissive triangle: pi Y(emissive) area, twice that for a double-sided material (a Lambertian
  emitter's power per side); the emissive texture is not read, so a textured emitter is chosen by
  its factor;
- a sphere or rectangle light: its luminous power, pi Y(radiance) area (pbrwarp/lights.py);
- the environment: the power it sends into the scene's bounding sphere, pi r^2 times the
  integral of its radiance over the sphere of directions, 4 pi^2 r^2 Y(mean radiance) (as a
  directional light of the same illuminance would send through the cross-section, from every
  side). It is chosen with probability W_env / (W_env + the table's total weight), or 1 where
  the table is empty.

The table's entries depend on the uploaded scene alone (pbrwarp.gpu_scene.upload's GpuScene,
which is rebuilt when a mesh, material or light changes), and are built from it, never from the
scene as it is now: a render holding an older upload (a pw.Accumulator) must get entries that
index that upload's light arrays. They are kept in the scene's cache under that upload and built
once, by one thread, for every render that shares it; the environment's
probability (its intensity can change between renders) is set in a LightTable of each render's
own.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

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


def light_table(scene, gpu, environment_lights: bool = False) -> LightTable:
    """The light table of ``scene`` as uploaded in ``gpu`` (its entries kept in ``scene.cache``),
    with the scene's environment among the lights where ``environment_lights`` (the render's
    kernel lights with it; an environment seen only as background is no light)."""
    built = scene.cache.get("emitters", _Same(gpu), lambda: _build(gpu))
    table = LightTable()
    table.cdf, table.pmf, table.face, table.face_pmf = built.arrays
    table.count, table.area = built.count, built.area
    table.environment = 0.0
    if environment_lights and scene.environment is not None:
        environment = scene.environment
        # the texels' mean luminance is kept: scanning them costs more than a small render
        mean = scene.cache.get("environment mean luminance", _Same(environment.texels),
                               lambda: mean_luminance(environment.texels))
        table.environment = environment_probability(
            environment_weight(mean * float(environment.intensity), built.radius), built.total)
    return table


def environment_probability(weight: float, others: float) -> float:
    """The probability of choosing the environment of selection weight ``weight`` beside entries
    of total weight ``others``: its share, 1 without other lights (whatever its weight)."""
    if not others > 0.0:
        return 1.0
    if not weight > 0.0:
        return 0.0
    return float(weight / (weight + others)) if math.isfinite(weight) else 1.0


def environment_weight(mean_radiance: float, radius: float) -> float:
    """The selection weight of an environment of mean luminance ``mean_radiance`` over solid angle
    (module docstring): 4 pi^2 r^2 times it, for a bounding sphere of radius ``radius``."""
    return 4.0 * math.pi ** 2 * max(radius, 1e-30) ** 2 * mean_radiance


def mean_luminance(texels: np.ndarray) -> float:
    """The mean over solid angle of the luminance of equirectangular ``texels`` (H, 2H, 3)."""
    from .kernels.equirect import texel_solid_angles

    solid_angle = texel_solid_angles(texels.shape[0])
    row_luminance = (texels.astype(np.float64) @ LUMINANCE).sum(axis=1)
    return float(row_luminance @ solid_angle) / (4.0 * math.pi)


def emissive_materials(scene) -> int:
    """How many of the scene's meshes (primitives) have a material that emits light (a non-zero emissive
    factor, not unlit): every triangle of theirs is a light for the path tracer."""
    return sum(1 for p in scene.primitives if max(p.material.emissive) > 0.0 and not p.material.unlit)


class _Built:
    """The table's arrays (cdf, pmf, face, face_pmf), its counts, its entries' total weight and the
    radius of the scene's bounding sphere the weights use."""

    def __init__(self, arrays: tuple, count: int, area: int, total: float, radius: float):
        self.arrays = arrays
        self.count, self.area = count, area
        self.total, self.radius = total, radius


def face_weights(positions: np.ndarray, indices: np.ndarray, face_primitive: np.ndarray, emissive: np.ndarray,
                 double_sided: np.ndarray) -> np.ndarray:
    """Each triangle's selection weight, pi Y(emissive) area (times 2 if double-sided), in float64;
    ``emissive`` and ``double_sided`` are per primitive (emissive 0 for those that emit nothing)."""
    corners = positions.astype(np.float64)[indices.reshape(-1, 3)]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    per_primitive = math.pi * (emissive @ LUMINANCE) * np.where(double_sided, 2.0, 1.0)
    return per_primitive[face_primitive] * area


def bounding_radius(positions: np.ndarray) -> float:
    """The radius of the sphere about the bounding box of ``positions`` (N, 3) (0 for none)."""
    if len(positions) == 0:
        return 0.0
    points = positions.astype(np.float64)
    return 0.5 * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def area_weights(lights) -> np.ndarray:
    """Each area light's selection weight, pi Y(color) intensity area, in float64."""
    return np.array([float(np.asarray(light.color, dtype=np.float64) @ LUMINANCE) * light.power
                     for light in lights], dtype=np.float64)


def _build(gpu) -> _Built:
    geometry = gpu.geometry
    rows = gpu.material_rows
    emissive = np.array([[float(c) for c in row.emissive] if not row.unlit else [0.0, 0.0, 0.0] for row in rows],
                        dtype=np.float64).reshape(-1, 3)
    double_sided = np.array([bool(row.double_sided) for row in rows])
    face_primitive = geometry.face_primitive.numpy()
    positions = geometry.positions.numpy()
    faces = face_weights(positions, geometry.indices.numpy(), face_primitive, emissive, double_sided)
    emitting = np.flatnonzero(faces > 0.0).astype(np.int32)
    radius = bounding_radius(positions)
    weights = np.concatenate([area_weights(gpu.area_lights), faces[emitting]])
    weights = np.where(np.isfinite(weights), weights, np.finfo(np.float32).max)
    total = weights.sum()
    count = len(weights) if total > 0.0 else 0
    pmf = weights / total if count else np.zeros(1)
    cdf = np.cumsum(pmf) if count else np.ones(1)
    if count:
        cdf[-1] = 1.0  # rounding must leave no u in [0, 1) past the last entry
    face_pmf = np.zeros(max(len(face_primitive), 1), dtype=np.float32)
    area = len(gpu.area_lights)
    if count:
        face_pmf[emitting] = pmf[area:]
    arrays = (
        wp.array(cdf.astype(np.float32), dtype=float, device="cpu"),
        wp.array(pmf.astype(np.float32), dtype=float, device="cpu"),
        wp.array(emitting if len(emitting) else np.zeros(1, np.int32), dtype=wp.int32, device="cpu"),
        wp.array(face_pmf, dtype=float, device="cpu"),
    )
    return _Built(arrays, count, area if count else 0, float(total) if count else 0.0, radius)
