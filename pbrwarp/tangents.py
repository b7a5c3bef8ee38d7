"""Per-vertex tangents generated from UVs, following MikkTSpace (the algorithm glTF names).

glTF's tangent frame: ``tangent.xyz`` points along increasing u, and the bitangent is
``cross(normal, tangent.xyz) * tangent.w``. glTF normal maps are OpenGL-style (green = +Y =
"up" in the image), and glTF UVs have v pointing *down* the image, so the bitangent points along
*decreasing* glTF v, i.e. along increasing ``1 - v``. MikkTSpace is therefore run on
``(u, 1 - v)``, which is also what glTF exporters such as Blender do.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

_TINY = np.finfo(np.float64).tiny  # squared lengths at or below this count as zero


def frame_uv_set(material, uvs, uvs1) -> int | None:
    """The uv set (0 or 1) from which a mesh with ``material`` and uv sets ``uvs`` (TEXCOORD_0,
    or None) and ``uvs1`` (TEXCOORD_1, or None) generates its tangent frame: the set the normal
    map (else the clear coat's, else the anisotropy map) is read with. None when nothing reads a
    frame (no normal maps, no anisotropy) or that set is missing."""
    if (material.normal_texture is None and material.clearcoat_normal_texture is None
            and material.anisotropy_strength == 0.0):
        return None
    mapped = material.normal_texture or material.clearcoat_normal_texture or material.anisotropy_texture
    if mapped is not None and mapped.texcoord == 1 and uvs1 is not None:
        return 1
    return 0 if uvs is not None else None


def generate_tangents(positions, normals, uvs, faces) -> np.ndarray:
    """glTF tangents (V, 4) float64 for a triangle mesh: unit ``xyz`` perpendicular to the vertex
    normal and handedness ``w`` = +1 or -1.

    What is the same as MikkTSpace:

    - per-face tangent and bitangent directions from UV derivatives (its equations 18/19),
      normalised per face, so large triangles do not outweigh small ones;
    - at each corner they are projected onto the vertex normal's plane and weighted by the corner
      angle measured in that plane;
    - faces whose UV orientation is mirrored relative to the others at a vertex are kept apart;
    - vertices with bit-identical position, normal and UV are welded first (MikkTSpace identifies
      vertices by value, not by index);
    - the tangent is Gram-Schmidt orthogonalised against the normal; ``w`` is
      ``sign(dot(cross(n, t), b))`` with ``b`` the accumulated bitangent.

    What differs:

    - no vertex splitting. MikkTSpace gives a vertex one tangent per orientation group (and per
      smoothing group); with one output row per vertex, the group with the larger summed corner
      angle wins and the other group's faces are ignored at that vertex. Meshes exported with
      tangents are already split at UV mirror seams, so this only matters for meshes that share
      a vertex between mirrored and unmirrored faces;
    - orientation is decided relative to the vertex normal, where MikkTSpace uses only the sign
      of the UV area; the two agree unless the normals disagree with the winding, and this choice
      keeps ``cross(n, t) * w`` pointing along the true bitangent in that case too;
    - degenerate triangles are not repaired from their neighbours (MikkTSpace's DegenPrologue /
      DegenEpilogue): faces with zero UV area contribute nothing, corners of zero-area faces get
      zero weight, and a vertex left with no usable direction gets an arbitrary unit tangent
      perpendicular to its normal, with w = +1;
    - float64 throughout, so results match MikkTSpace's float32 ones only to about 1e-6.

    Zero-length normals mean "flat shaded": such a vertex uses the angle-weighted normal of the
    faces around it (the face normal when they are coplanar). The result is finite even for
    degenerate input; non-finite input or faces indexing missing vertices raise ``InputError``.
    """
    pos, nrm, uv, tri = _checked(positions, normals, uvs, faces)
    if len(pos) == 0:
        return np.zeros((0, 4))
    weld, rep = _weld(pos, nrm, uv)
    wtri = weld[tri]
    n_welded = len(rep)

    face_n = np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]])
    face_t, face_b, uv_sign = _face_frames(pos, uv, tri)

    corner_angle = _corner_angles(pos, tri, None)
    vert_n = _vertex_normals(nrm[rep], wtri, face_n, corner_angle, n_welded)

    corner_v = wtri.reshape(-1)
    corner_n = vert_n[corner_v]
    corner_f = np.repeat(np.arange(len(tri)), 3)
    weight = _corner_angles(pos, tri, corner_n.reshape(-1, 3, 3)).reshape(-1)
    t = _unit(_project(face_t[corner_f], corner_n))
    b = _unit(_project(face_b[corner_f], corner_n))
    # Orientation of this face's frame relative to the vertex normal (see the docstring).
    facing = np.where(np.einsum("ij,ij->i", corner_n, face_n[corner_f]) < 0.0, -1.0, 1.0)
    orient = uv_sign[corner_f] * facing
    # Faces of zero UV area have no direction to contribute, nor zero-area faces a plane.
    flat = (orient == 0.0) | ~np.any(_unit(face_n), axis=1)[corner_f]
    weight = np.where(flat, 0.0, weight)

    group = (orient < 0.0).astype(np.int64)  # 0: right-handed, 1: mirrored
    slot = corner_v * 2 + group
    angle_sum = np.bincount(slot, weight, minlength=2 * n_welded).reshape(n_welded, 2)
    t_sum = _scatter_sum(slot, t * weight[:, None], 2 * n_welded).reshape(n_welded, 2, 3)
    b_sum = _scatter_sum(slot, b * weight[:, None], 2 * n_welded).reshape(n_welded, 2, 3)
    winner = np.argmax(angle_sum, axis=1)
    rows = np.arange(n_welded)
    out = _finish(vert_n, t_sum[rows, winner], b_sum[rows, winner], np.where(winner == 1, -1.0, 1.0))
    return out[weld]


def _checked(positions, normals, uvs, faces):
    arrays = []
    for value, width, what in ((positions, 3, "positions"), (normals, 3, "normals"), (uvs, 2, "uvs")):
        arr = np.asarray(value, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != width:
            raise InputError(f"generate_tangents: {what} must have shape (V, {width}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"generate_tangents: {what} contain NaN or Inf")
        arrays.append(arr)
    pos, nrm, uv = arrays
    if not len(pos) == len(nrm) == len(uv):
        raise InputError(f"generate_tangents: {len(pos)} positions, {len(nrm)} normals and {len(uv)} uvs "
                         "differ in count")
    tri = np.asarray(faces)
    if tri.ndim != 2 or tri.shape[1] != 3 or not (tri.size == 0 or np.issubdtype(tri.dtype, np.integer)):
        raise InputError("generate_tangents: faces must be an integer array of shape (F, 3), "
                         f"got {tri.dtype} {tri.shape}")
    tri = tri.astype(np.int64)
    if tri.size and (tri.min() < 0 or tri.max() >= len(pos)):
        raise InputError(f"generate_tangents: faces index vertices {tri.min()}..{tri.max()}, "
                         f"but there are {len(pos)} vertices")
    return pos, nrm, uv, tri


def _weld(pos, nrm, uv):
    """(index of each vertex's welded vertex, first original vertex of each welded vertex)."""
    key = np.ascontiguousarray(np.concatenate([pos, nrm, uv], axis=1) + 0.0)  # + 0.0: -0 == +0
    _, rep, weld = np.unique(key.view(np.dtype((np.void, key.dtype.itemsize * key.shape[1]))).ravel(),
                             return_index=True, return_inverse=True)
    return weld.ravel(), rep


def _face_frames(pos, uv, tri):
    """Unit dP/du and dP/dv' per face (v' = 1 - v) and the sign of the UV area (0 if none)."""
    st = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])
    d1 = pos[tri[:, 1]] - pos[tri[:, 0]]
    d2 = pos[tri[:, 2]] - pos[tri[:, 0]]
    t21 = st[tri[:, 1]] - st[tri[:, 0]]
    t31 = st[tri[:, 2]] - st[tri[:, 0]]
    area2 = t21[:, 0] * t31[:, 1] - t21[:, 1] * t31[:, 0]
    sign = np.sign(area2)
    # MikkTSpace eq. 18/19 (d1 = T du1 + B dv1, d2 = T du2 + B dv2 solved, times the area).
    t = t31[:, 1:2] * d1 - t21[:, 1:2] * d2
    b = t21[:, 0:1] * d2 - t31[:, 0:1] * d1
    return _unit(t * sign[:, None]), _unit(b * sign[:, None]), sign


def _corner_angles(pos, tri, plane_normals):
    """Angle at each corner (F, 3); with ``plane_normals`` (F, 3, 3) the edges are first projected
    onto each corner's normal plane, as MikkTSpace does."""
    p = pos[tri]
    e_next = np.roll(p, -1, axis=1) - p
    e_prev = np.roll(p, 1, axis=1) - p
    if plane_normals is not None:
        e_next = e_next - plane_normals * np.sum(e_next * plane_normals, axis=2, keepdims=True)
        e_prev = e_prev - plane_normals * np.sum(e_prev * plane_normals, axis=2, keepdims=True)
    a = _unit(e_next.reshape(-1, 3))
    c = _unit(e_prev.reshape(-1, 3))
    degenerate = (np.sum(a * a, axis=1) == 0.0) | (np.sum(c * c, axis=1) == 0.0)
    angle = np.arccos(np.clip(np.sum(a * c, axis=1), -1.0, 1.0))
    return np.where(degenerate, 0.0, angle).reshape(-1, 3)


def _vertex_normals(nrm, wtri, face_n, corner_angle, count):
    """Unit supplied normals; zero rows replaced by the angle-weighted face normals around them."""
    supplied = _unit(nrm)
    missing = np.sum(supplied * supplied, axis=1) == 0.0
    if np.any(missing):
        fn = _unit(face_n)
        contrib = np.repeat(fn, 3, axis=0) * corner_angle.reshape(-1, 1)
        smooth = _unit(_scatter_sum(wtri.reshape(-1), contrib, count))
        supplied[missing] = smooth[missing]
    return supplied


def _finish(n, t_sum, b_sum, group_sign):
    """Gram-Schmidt, handedness and fallbacks: finite unit tangents perpendicular to ``n``."""
    t = _unit(_project(t_sum, n))
    lost = np.sum(t * t, axis=1) < 0.5
    t[lost] = _any_perpendicular(n[lost])
    handed = np.einsum("ij,ij->i", np.cross(n, t), b_sum)
    w = np.where(handed > 0.0, 1.0, np.where(handed < 0.0, -1.0, group_sign))
    w[lost] = 1.0
    return np.column_stack([t, w])


def _any_perpendicular(n):
    """A unit vector perpendicular to each row of ``n`` (Duff et al. 2017); x for zero rows."""
    out = np.zeros_like(n)
    out[:, 0] = 1.0
    ok = np.sum(n * n, axis=1) > 0.0
    nx, ny, nz = n[ok].T
    s = np.where(nz >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + nz)
    out[ok] = np.column_stack([1.0 + s * nx * nx * a, s * nx * ny * a, -s * nx])
    return out


def _project(v, n):
    """``v`` minus its component along the unit rows ``n``."""
    return v - n * np.sum(v * n, axis=1, keepdims=True)


def _unit(v):
    """Unit rows; rows too short to normalise become zero."""
    sq = np.sum(v * v, axis=1, keepdims=True)
    return np.divide(v, np.sqrt(sq), out=np.zeros_like(v), where=sq > _TINY)


def _scatter_sum(index, values, count):
    """Rows of ``values`` summed into ``count`` bins by ``index``."""
    return np.column_stack([np.bincount(index, values[:, k], minlength=count) for k in range(values.shape[1])])
