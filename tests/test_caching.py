"""Kernels compile once per feature set: warm renders, and renders after editing the camera,
lights or material factors, compile nothing (in this process or a new one)."""

import subprocess
import sys
import textwrap

import numpy as np
import warp as wp
import trimesh

import pbrwarp as pw
from pbrwarp.kernels.render import render_kernel


def scene_with(material):
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=2), material)
    scene.add_light(pw.PointLight(position=(2, 2, 2), intensity=20.0))
    return scene


def test_editing_camera_lights_and_factors_reuses_the_kernel():
    material = pw.Material(base_color=(0.5, 0.5, 0.5), roughness=0.5)
    scene = scene_with(material)
    cam = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0))
    first = pw.render(scene, cam, width=24, height=24, progress=False)
    misses = render_kernel.cache_info().misses

    scene.lights[0].position = (-2.0, 1.0, 2.0)
    scene.lights[0].color = (1.0, 0.5, 0.25)
    material.roughness = 0.2
    material.base_color = (0.9, 0.1, 0.1, 1.0)
    moved = pw.Camera.look_at(eye=(0.5, 0.2, 3.2), target=(0, 0, 0))
    second = pw.render(scene, moved, width=24, height=24, progress=False)

    assert render_kernel.cache_info().misses == misses
    assert not np.allclose(first.rgb, second.rgb)  # the edits took effect


def test_the_upload_is_reused_until_a_material_or_light_changes():
    """upload keeps the scene's rows while nothing changed, and an edit of any material or light
    field takes effect in the next frame: doubling the light's intensity doubles every pixel
    (exactly: radiance is linear in it, and a factor of 2 rounds nothing), and undoing the edits
    gives the first frame back bit for bit."""
    from pbrwarp.gpu_scene import upload

    material = pw.Material(base_color=(0.5, 0.5, 0.5), roughness=0.5)
    scene = scene_with(material)
    cam = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0))
    assert upload(scene) is upload(scene)
    first = pw.render(scene, cam, width=24, height=24, progress=False).rgb
    scene.lights[0].intensity = 40.0
    doubled = pw.render(scene, cam, width=24, height=24, progress=False).rgb
    assert np.array_equal(doubled, 2.0 * first) and np.any(first > 0)
    scene.lights[0].intensity = 20.0
    for edit, value in (("roughness", 0.2), ("metallic", 1.0), ("base_color", (0.9, 0.1, 0.1, 1.0)),
                        ("double_sided", False)):
        kept = getattr(material, edit)
        setattr(material, edit, value)
        edited = pw.render(scene, cam, width=24, height=24, progress=False).rgb
        setattr(material, edit, kept)
        if edit != "double_sided":  # a closed sphere seen from outside looks the same single-sided
            assert not np.array_equal(edited, first), edit
    assert np.array_equal(pw.render(scene, cam, width=24, height=24, progress=False).rgb, first)


def test_a_new_process_loads_kernels_from_the_disk_cache():
    script = textwrap.dedent("""
        import warp as wp
        import trimesh, pbrwarp as pw
        wp.config.log_level = wp.LOG_INFO  # after the import, which keeps Warp quiet
        s = pw.Scene()
        s.add_mesh(trimesh.creation.icosphere(subdivisions=1), pw.Material())
        s.add_light(pw.DirectionalLight(direction=(0, -1, -1), intensity=2.0))
        f = pw.render(s, pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0)), width=8, height=8, progress=False)
        f.to_srgb8()
    """)
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    warm = runs[1].stdout + runs[1].stderr
    assert "render_tile" in warm, warm
    assert "(compiled)" not in warm, warm


def test_dfg_table_is_cached_on_disk_and_read_back_exactly():
    import os

    from pbrwarp.kernels import dfg

    dfg.dfg_table()
    files = [f for f in os.listdir(wp.config.kernel_cache_dir) if f.startswith(f"pbrwarp_dfg_v{dfg.DFG_TABLE_VERSION}_")]
    assert files
    integrated = wp.zeros((dfg.DFG_TABLE_SIZE,) * 2, dtype=wp.vec2, device="cpu")
    wp.launch(dfg.integrate_dfg, dim=integrated.shape, device="cpu", inputs=[dfg.DFG_SAMPLES, integrated])
    np.testing.assert_array_equal(dfg.dfg_table.__wrapped__().numpy(), integrated.numpy())


def test_assigning_a_primitives_or_textures_field_rebuilds_what_depends_on_it():
    """A field set anew (not an array changed in place) is seen by the next render: the geometry,
    its facts and the texels are keyed by the objects' revisions, not only their identity."""
    import trimesh

    scene = pw.Scene()
    texture = pw.Texture(np.full((2, 2, 3), 255, dtype=np.uint8))
    box = trimesh.creation.box()
    prim = scene.add_mesh(pw.Primitive(box.vertices, box.faces, pw.Material(base_color_texture=texture, specular=0.0),
                                       uvs=np.zeros((len(box.vertices), 2))))
    scene.add_light(pw.DirectionalLight(direction=(0, 0, -1), intensity=3.0))
    camera = pw.Camera.look_at((0, 0, 5), (0, 0, 0), fov_y=30.0)
    first = pw.render(scene, camera, width=32, height=32, progress=False)
    prim.positions = prim.positions * 0.5  # the box shrinks: it covers fewer pixels
    second = pw.render(scene, camera, width=32, height=32, progress=False)
    assert second.alpha.sum() < 0.5 * first.alpha.sum()
    texture.image = np.zeros((2, 2, 3), dtype=np.uint8)  # black Lambert (no specular lobe): dark
    third = pw.render(scene, camera, width=32, height=32, progress=False)
    assert third.rgb[third.alpha > 0].max() == 0.0 < second.rgb[second.alpha > 0].max()
    assert np.array_equal(pw.Camera.frame(scene).eye, pw.Camera.frame(scene).eye)


def test_a_cut_out_texture_set_anew_rerenders_the_shadow_maps():
    """Shadow maps keep the alpha-masked materials' cut-outs; a base-colour image set anew on a
    masked material's texture (same Texture object) gives maps with the new cut-outs."""
    import trimesh

    scene = pw.Scene()
    texture = pw.Texture(np.full((2, 2, 4), 255, dtype=np.uint8))  # opaque: casts a shadow
    quad = pw.Primitive(np.array([[-1, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1]], float),
                        np.array([[0, 2, 1], [0, 3, 2]]),
                        pw.Material(base_color_texture=texture, alpha_mode="MASK", alpha_cutoff=0.5),
                        uvs=np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    scene.add_mesh(quad)
    floor = trimesh.creation.box(extents=(4, 0.1, 4))
    scene.add_mesh(floor, pw.Material(), transform=np.diag([1.0, 1.0, 1.0, 1.0]))
    scene.add_light(pw.DirectionalLight(direction=(0, -1, 0), intensity=3.0))
    camera = pw.Camera.look_at((0, 0.5, 0), (0, -1, 0), up=(0, 0, 1), fov_y=40.0)  # under the quad
    shadowed = pw.render(scene, camera, width=16, height=16, shadows="map", progress=False)
    texture.image = np.zeros((2, 2, 4), dtype=np.uint8)  # transparent: cut out entirely
    lit = pw.render(scene, camera, width=16, height=16, shadows="map", progress=False)
    assert shadowed.rgb.max() < 0.01 * lit.rgb.max()
