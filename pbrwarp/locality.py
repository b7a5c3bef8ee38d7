"""Triangle and vertex order for memory locality.

The kernels read a triangle's three vertices through its indices: rasterization for every
triangle of the mesh, ray casting and shading for the ones rays meet. Meshes come in whatever
order their source left them (a subdivision appends each level's new vertices at the end, a scan
follows its scanner), so neighbouring triangles may read vertices megabytes apart. Sorted along a
Morton (Z-order) curve of their centroids, triangles near each other in space lie near each other
in memory, and vertices renumbered in the order the sorted triangles first use them follow.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from pbrwarp.kernels import locality as lk


def locality_order(positions: wp.array, indices: wp.array) -> tuple[np.ndarray, np.ndarray]:
    """(face_order, vertex_order) of a mesh (CPU wp.arrays of vec3 and of int32, 3 per triangle,
    every index valid): triangles sorted along the Morton curve of their centroids over the
    vertices' bounding cube (ties keep their order), and the vertices in the order those triangles
    first use them, unused vertices last in their own order."""
    points = positions.numpy()
    triangles = len(indices) // 3
    if triangles == 0 or len(points) == 0:
        return np.arange(triangles), np.arange(len(points))
    lo = points.min(axis=0)
    extent = float((points.max(axis=0) - lo).max())
    scale = (2**lk.MORTON_BITS - 1) / extent if extent > 0.0 else 0.0
    codes = wp.empty(triangles, dtype=wp.uint64, device="cpu")
    wp.launch(lk.centroid_morton_codes, dim=triangles, inputs=[positions, indices, wp.vec3(*lo), scale, codes],
              device="cpu")
    face_order = np.argsort(codes.numpy(), kind="stable")
    corners = indices.numpy().reshape(-1, 3)[face_order].reshape(-1)
    first_use = np.full(len(points), len(corners), dtype=np.int64)
    np.minimum.at(first_use, corners, np.arange(len(corners)))
    return face_order, np.argsort(first_use, kind="stable")


def inverse_permutation(order: np.ndarray) -> np.ndarray:
    """inverse[order] = arange(len(order))."""
    inverse = np.empty(len(order), dtype=np.int64)
    inverse[order] = np.arange(len(order))
    return inverse
