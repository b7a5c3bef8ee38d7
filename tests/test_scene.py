"""The scene layer: trimesh intake (materials, colours, normals, UVs), transforms, bounds."""

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial, SimpleMaterial
from trimesh.visual.texture import TextureVisuals

import pbrwarp as pw
from pbrwarp.textures import srgb_to_linear


def srgb8_to_linear(c):
    c = np.asarray(c, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_pbr_material_factors_map_slot_by_slot():
    mesh = trimesh.creation.box()
    mesh.visual = TextureVisuals(material=PBRMaterial(baseColorFactor=(0.5, 0.25, 1.0, 1.0), metallicFactor=0.3,
                                                      roughnessFactor=0.7, emissiveFactor=(0.1, 0.2, 0.3), doubleSided=True))
    mat = pw.Scene.from_trimesh(mesh).primitives[0].material
    np.testing.assert_allclose(mat.base_color, np.array([128, 64, 255, 255]) / 255.0)  # trimesh stores uint8
    assert (mat.metallic, mat.roughness, mat.double_sided) == (0.3, 0.7, True)
    np.testing.assert_allclose(mat.emissive, (0.1, 0.2, 0.3))


def test_simple_material_colour_is_decoded_from_srgb():
    mesh = trimesh.creation.box()
    mesh.visual = TextureVisuals(material=SimpleMaterial(diffuse=(200, 100, 50, 255)))
    mat = pw.Scene.from_trimesh(mesh).primitives[0].material
    np.testing.assert_allclose(mat.base_color[:3], srgb8_to_linear([200, 100, 50]), rtol=1e-6)


def test_vertex_colours_become_linear_per_vertex_colours():
    mesh = trimesh.creation.icosphere(subdivisions=1)
    rgba = np.random.default_rng(0).integers(0, 256, (len(mesh.vertices), 4)).astype(np.uint8)
    mesh.visual.vertex_colors = rgba
    prim = pw.Scene.from_trimesh(mesh).primitives[0]
    assert prim.material.base_color[:3] == (1.0, 1.0, 1.0)
    np.testing.assert_allclose(prim.colors[:, :3], srgb8_to_linear(rgba[:, :3]), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(prim.colors[:, 3], rgba[:, 3] / 255.0)  # alpha is linear


def test_uniform_face_colour_becomes_base_colour():
    mesh = trimesh.creation.box()
    mesh.visual.face_colors = (255, 128, 0, 255)
    prim = pw.Scene.from_trimesh(mesh).primitives[0]
    assert prim.colors is None
    np.testing.assert_allclose(prim.material.base_color[:3], srgb8_to_linear([255, 128, 0]), rtol=1e-6)


def test_meshes_without_normals_get_creased_smooth_normals():
    box = pw.Scene.from_trimesh(trimesh.creation.box()).primitives[0]
    # a cube's corners are split: every vertex normal is one of the six face normals
    assert len(box.positions) == 24
    assert np.all(np.isclose(np.abs(box.normals).max(axis=1), 1.0))
    sphere = pw.Scene.from_trimesh(trimesh.creation.icosphere(subdivisions=2)).primitives[0]
    radial = sphere.positions / np.linalg.norm(sphere.positions, axis=1, keepdims=True)
    assert np.min(np.sum(radial * sphere.normals, 1)) > 0.99  # smooth, not faceted


def test_trimesh_uvs_are_flipped_to_gltf_convention():
    mesh = trimesh.creation.box()
    uv = np.random.default_rng(1).uniform(0, 1, (len(mesh.vertices), 2))
    mesh.visual = TextureVisuals(uv=uv)
    prim = pw.Scene.from_trimesh(mesh).primitives[0]
    np.testing.assert_allclose(prim.uvs, np.column_stack([uv[:, 0], 1 - uv[:, 1]]))


def test_scene_graph_transforms_and_mirroring():
    scene = trimesh.Scene()
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    mirror[:3, 3] = (5.0, 0.0, 0.0)
    scene.add_geometry(trimesh.creation.box(), transform=mirror)
    prim = pw.Scene.from_trimesh(scene).primitives[0]
    np.testing.assert_allclose(prim.positions.mean(axis=0), (5.0, 0.0, 0.0), atol=1e-12)
    # winding reversed by the mirror: geometric normals still point out of the box
    p = prim.positions[prim.faces]
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = p.mean(axis=1) - (5.0, 0.0, 0.0)
    assert np.all(np.sum(ng * outward, 1) > 0)
    assert np.all(np.sum(prim.normals[prim.faces[:, 0]] * ng, 1) > 0)


def test_bounds_and_triangle_count():
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.box(extents=(2, 4, 6)))
    scene.add_mesh(trimesh.creation.box(), transform=trimesh.transformations.translation_matrix((10, 0, 0)))
    lo, hi = scene.bounds()
    np.testing.assert_allclose(lo, (-1, -2, -3))
    np.testing.assert_allclose(hi, (10.5, 2, 3))
    assert scene.triangle_count == 24


def test_srgb_decode_matches_the_standard():
    x = np.linspace(0, 1, 101)
    want = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(srgb_to_linear(x), want, rtol=1e-6, atol=1e-9)
