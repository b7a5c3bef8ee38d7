"""The real models in the test assets load, render without NaN/Inf, and come out right."""

import numpy as np
import pytest

import pbrwarp as pw

from assets import ASSETS, GLTF, MESHES, asset_id, mesh_file
from scenes import render_checked


def render_small(scene, size=48, **kw):
    if not scene.lights:
        scene.add_light(pw.DirectionalLight(direction=(-0.3, -0.5, -1.0), intensity=3.0))
        scene.add_light(pw.PointLight(position=tuple(scene.bounds()[1] * 2.0 + 0.1), intensity=10.0))
    return render_checked(scene, pw.Camera.frame(scene), size=(size, size), **kw)


@pytest.mark.parametrize("path", GLTF + MESHES, ids=asset_id)
def test_every_asset_loads_and_renders_finite(path):
    scene = pw.Scene.load(path)
    assert scene.triangle_count > 0
    frame = render_small(scene, spp=2)
    assert frame.alpha.max() > 0, "the framing camera sees the model"
    assert frame.rgb.max() > 0, "the default lights light it"


def test_metal_rough_spheres_material_slots():
    """98 factor-only materials: a 7 x 7 metallic x roughness grid, grey and gold."""
    scene = pw.Scene.load(ASSETS / "gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb")
    pairs = {(round(p.material.metallic * 6), round(p.material.roughness * 6)) for p in scene.primitives}
    assert pairs >= {(m, r) for m in range(7) for r in range(7)}
    bases = {tuple(np.round(p.material.base_color[:3], 2)) for p in scene.primitives}
    assert (0.6, 0.6, 0.6) in bases and (0.6, 0.44, 0.01) in bases


# Pixels by which two tiles' crops, found from their silhouettes, may be misaligned.
MAX_CROP_SHIFT = 2


def best_aligned_median_dot(a, b, shift: int) -> float:
    """The largest median of dot(a, b) per pixel over integer shifts of ``b`` by up to ``shift``
    pixels in x and y (over the crop less its ``shift``-wide border)."""
    h, w = a.shape[:2]
    inner = a[shift:h - shift, shift:w - shift]
    return max(float(np.median(np.sum(inner * b[shift + dy:h - shift + dy, shift + dx:w - shift + dx], -1)))
               for dy in range(-shift, shift + 1) for dx in range(-shift, shift + 1))


def test_normal_tangent_mirror_tiles_shade_like_their_twins():
    """Every normal-mapped tile (plain, V-mirrored, U-mirrored) bends normals like the real
    geometry in the first column: a flipped green channel or ignored handedness breaks this."""
    scene = pw.Scene.load(ASSETS / "gltf/NormalTangentMirrorTest/glTF-Binary/NormalTangentMirrorTest.glb")
    cam = pw.Camera.frame(scene, direction=(0, 0, 1))
    frame = pw.render(scene, cam, width=600, height=600, progress=False)
    assert pw.check(frame).ok
    bent = (frame.normal[..., 2] < 0.97) & (frame.alpha > 0)
    bent[:, 300:] = False  # the front panel is the left half of the view

    def runs(profile):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], (profile > 0).astype(int), [0]])))
        return list(zip(edges[::2], edges[1::2]))

    cols, rows = runs(bent.sum(0)), runs(bent.sum(1))
    assert len(cols) == 4 and len(rows) == 5, (cols, rows)
    width = min(b - a for a, b in cols)
    height = min(b - a for a, b in rows)
    for y0, _ in rows:
        geometry, plain, v_mirror, u_mirror = (frame.normal[y0:y0 + height, x0:x0 + width] for x0, _ in cols)
        for mirrored in (v_mirror, u_mirror):
            # the mirrored tiles reproduce their un-mirrored twin almost exactly
            assert np.median(np.sum(mirrored * plain, -1)) > 0.995
        for mapped in (plain, v_mirror, u_mirror):
            # and all of them the real bumps, up to the bake's resolution, at the best alignment
            # within the crops' 1-2 px of misalignment (a flipped green channel tilts half of
            # each bump the wrong way at every shift)
            assert best_aligned_median_dot(mapped, geometry, MAX_CROP_SHIFT) > 0.97


def test_texture_settings_sampler_wrap_modes():
    """REPEAT, CLAMP and MIRRORED_REPEAT samplers reach the materials (trimesh alone drops
    them); the file's five samplers combine repeat on one axis with each mode on the other."""
    scene = pw.Scene.load(ASSETS / "gltf/TextureSettingsTest/glTF-Binary/TextureSettingsTest.glb")
    wraps = {(tex.wrap_s, tex.wrap_t) for p in scene.primitives for _, tex, _ in p.material.textures()}
    assert wraps == {("repeat", "repeat"), ("repeat", "clamp"), ("clamp", "repeat"), ("repeat", "mirror"), ("mirror", "repeat")}


def test_spot_texture_lands_on_the_cow(tmp_path):
    """An OBJ with UVs and no .mtl: attach the texture yourself, then render it."""
    import trimesh
    from PIL import Image

    mesh = trimesh.load(mesh_file("spot/spot_triangulated.obj"), force="mesh")
    texture = Image.open(mesh_file("spot/spot_texture.png"))
    scene = pw.Scene()
    scene.add_mesh(mesh, pw.Material(base_color_texture=texture, roughness=0.6))
    frame = render_small(scene, size=64)
    covered = frame.alpha > 0
    # the texture is far from uniform: so is the cow
    assert frame.rgb[covered].std(axis=0).max() > 0.01
