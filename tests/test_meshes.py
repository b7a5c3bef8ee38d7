"""Procedural scenes of pbrwarp.meshes: the sphere grid's parameter sweep and the conventions of
the normal-mapped models (UVs, tangents, normal-map encoding)."""

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp import meshes


def test_sphere_grid_sweeps_metallic_up_and_roughness_right():
    scene = meshes.sphere_grid(rows=3, cols=4, subdivisions=1)
    assert len(scene.primitives) == 12 and not scene.lights
    centres = np.array([p.positions.mean(axis=0) for p in scene.primitives])
    metallic = np.array([p.material.metallic for p in scene.primitives])
    roughness = np.array([p.material.roughness for p in scene.primitives])
    bottom, top = centres[:, 1] < -1, centres[:, 1] > 1
    left, right = centres[:, 0] == centres[:, 0].min(), centres[:, 0] == centres[:, 0].max()
    assert np.all(metallic[bottom] == 0.0) and np.all(metallic[top] == 1.0)
    assert np.all(roughness[left] == meshes.MIN_GRID_ROUGHNESS) and np.all(roughness[right] == 1.0)
    assert len({id(p.material) for p in scene.primitives}) == 12
    np.testing.assert_allclose(centres.mean(axis=0), 0.0, atol=1e-9)


def test_height_to_normal_map_is_glTF_green_up():
    # a ridge along the middle row: rows above it face up (+Y, green > 0.5), rows below face down
    h = np.zeros((16, 16))
    h[8, :] = 1.0
    n = meshes.height_to_normal_map(h, strength=1.0).astype(float) / 255 * 2 - 1
    assert n[7, 3, 1] > 0.3 and n[9, 3, 1] < -0.3
    assert abs(n[7, 3, 0]) < 0.01
    # a ridge along a column: the texels left of it face left (-X, red < 0.5)
    n = meshes.height_to_normal_map(h.T, strength=1.0).astype(float) / 255 * 2 - 1
    assert n[3, 7, 0] < -0.3 and n[3, 9, 0] > 0.3


def test_brick_textures_tile_seamlessly():
    colour, normal, height = meshes.brick_textures(size=128)
    assert colour.dtype == np.uint8 and colour.shape == (128, 128, 3)
    assert normal.dtype == np.uint8 and normal.shape == (128, 128, 3)
    # the wrap-around seam is no stronger than the texture's usual texel-to-texel change
    inner = np.abs(np.diff(height, axis=1)).max()
    seam = np.abs(height[:, 0] - height[:, -1]).max()
    assert seam <= inner + 1e-6


@pytest.mark.parametrize("build", [meshes.normal_mapped_torus, meshes.normal_mapped_tile])
def test_tangent_frame_follows_glTF(build):
    prim = build()
    n, t, w = prim.normals, prim.tangents[:, :3], prim.tangents[:, 3]
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.sum(n * t, axis=1), 0.0, atol=1e-9)
    assert set(np.unique(w)) <= {-1.0, 1.0}
    # per triangle: t goes along +u and cross(n, t) w along -v (towards the top of the image)
    p, uv = prim.positions[prim.faces], prim.uvs[prim.faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-12
    dp_du = (e1 * d2[:, 1:] - e2 * d1[:, 1:])[ok] / det[ok, None]
    dp_dv = (e2 * d1[:, :1] - e1 * d2[:, :1])[ok] / det[ok, None]
    corner = prim.faces[ok, 0]
    b = np.cross(n[corner], t[corner]) * w[corner, None]
    assert np.mean(np.sum(t[corner] * dp_du, axis=1) > 0) > 0.99
    assert np.mean(np.sum(b * -dp_dv, axis=1) > 0) > 0.99
    # faces wind counter-clockwise around the outward normals
    geometric = np.cross(e1, e2)
    assert np.all(np.sum(geometric * n[prim.faces].sum(axis=1), axis=1) > 0)


def test_bricks_lit_from_above_have_bright_top_edges():
    """End to end: a normal-mapped tile lit from above is brighter where the height map rises
    downwards (edges facing up) than where it falls (edges facing down)."""
    scene = pw.Scene()
    scene.add_mesh(meshes.normal_mapped_tile(size=4.0))
    scene.add_light(pw.DirectionalLight(direction=(0.0, -1.0, -0.6), intensity=3.0))
    size, half = 128, 2.0
    camera = pw.Camera.look_at((0, 0, 8), (0, 0, 0), fov_y=2 * np.degrees(np.arctan(half / 8)))
    frame = pw.render(scene, camera, size, size, spp=1, progress=False)
    _, _, height = meshes.brick_textures()
    # the tile fills the frame exactly: pixel (row, col) -> texel (row, col) * 512 / size
    texel = (np.arange(size) + 0.5) * height.shape[0] / size
    idx = texel.astype(int)
    slope = (np.roll(height, -2, 0) - np.roll(height, 2, 0))[np.ix_(idx, idx)]
    luminance = frame.rgb.mean(axis=2)
    assert luminance[slope > 0.2].mean() > 3 * luminance[slope < -0.2].mean()


def test_mesh_scene_and_icosphere():
    scene, camera = meshes.mesh_scene(meshes.icosphere(2))
    assert scene.triangle_count == 320 and len(scene.lights) == 1
    frame = pw.render(scene, camera, 24, 24, progress=False)
    assert frame.rgb[12, 12].max() > 0.1
    with pytest.raises(pw.InputError):
        meshes.icosphere(-1)


def test_missing_asset_raises_asset_not_found():
    with pytest.raises(pw.AssetNotFoundError, match="shared asset not found"):
        meshes.asset("meshes/no-such-mesh.off")
    with pytest.raises(FileNotFoundError):
        meshes.asset("meshes/no-such-mesh.off")


def test_bunny():
    mesh = meshes.bunny()
    assert len(mesh.faces) > 1000
    lo, hi = mesh.bounds
    assert np.all(hi > lo)
