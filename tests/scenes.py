"""Small analytic test scenes."""

import numpy as np
import trimesh

import pbrwarp as pw


def quad(size=2.0, z=0.0, material=None, uvs=True, tangents=None):
    """A square in the plane z = const facing +z, UVs (0,0) top-left .. (1,1) bottom-right,
    tangent +x (the direction of increasing u)."""
    h = size / 2
    positions = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float) if uvs else None
    return pw.Primitive(positions, faces, material or lambert_white(), normals, uv, tangents)


def lambert_white():
    return pw.Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=1.0, specular=0.0)


def head_on_camera(distance=3.0, fov=30.0):
    return pw.Camera.look_at(eye=(0, 0, distance), target=(0, 0, 0), fov_y=fov)


def box(extents, center):
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(center))


def rotation_about_y(angle):
    return trimesh.transformations.rotation_matrix(angle, (0, 1, 0))


def render_checked(scene, cam, size=(33, 33), **kw):
    """Render and assert the frame has no NaN, Inf or negative pixel (pw.check)."""
    frame = pw.render(scene, cam, width=size[0], height=size[1], progress=False, **kw)
    report = pw.check(frame)
    assert report.ok, report
    return frame
