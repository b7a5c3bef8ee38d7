"""Specialization: kernels built per scene contain only the effects it calls for, render the same
image as the kernel with every effect, and say why an effect was dropped."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.loading import generated_source
from pbrwarp.kernels.render import render_kernel

from scenes import box, render_checked


def sphere_scene(material, lights, sphere=None):
    scene = pw.Scene()
    scene.add_mesh(sphere or trimesh.creation.icosphere(subdivisions=3), material)
    for light in lights:
        scene.add_light(light)
    return scene


def textured_material(**kw):
    rng = np.random.default_rng(0)
    return pw.Material(
        base_color_texture=rng.uniform(0, 1, (16, 16, 3)).astype(np.float32),
        metallic_roughness_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32),
        normal_texture=(np.array([0.2, -0.1, 0.97]) / np.linalg.norm([0.2, -0.1, 0.97]) + 1) / 2 * np.ones((4, 4, 3)),
        emissive_texture=rng.uniform(0, 1, (4, 4, 3)).astype(np.float32), emissive=(0.1, 0.2, 0.05), **kw)


def specular_textured_material(**kw):
    """KHR_materials_specular's strength (alpha) and colour textures, an IOR and a colour above 1."""
    rng = np.random.default_rng(1)
    fields = dict(base_color=(0.8, 0.3, 0.2), metallic=0.3, roughness=0.35, ior=1.8, specular_color=(2.0, 1.5, 1.0),
                  specular_texture=rng.uniform(0, 1, (8, 8, 4)).astype(np.float32),
                  specular_color_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32))
    return pw.Material(**{**fields, **kw})


def anisotropic_material():
    """KHR_materials_anisotropy with a rotation and a direction texture (a swirl)."""
    angle = np.linspace(0, 2 * np.pi, 8 * 8).reshape(8, 8)
    texels = np.stack([0.5 + 0.5 * np.cos(angle), 0.5 + 0.5 * np.sin(angle), np.full_like(angle, 0.8)], -1)
    return pw.Material(base_color=(0.9, 0.6, 0.3), metallic=0.7, roughness=0.25, anisotropy_strength=0.9,
                       anisotropy_rotation=0.4, anisotropy_texture=texels.astype(np.float32))


def iridescent_material():
    """KHR_materials_iridescence with strength and thickness textures, over a partly metallic base."""
    rng = np.random.default_rng(2)
    return pw.Material(base_color=(0.3, 0.5, 0.7), metallic=0.4, roughness=0.2, iridescence=0.9,
                       iridescence_ior=1.6, iridescence_thickness_min=150.0, iridescence_thickness_max=650.0,
                       iridescence_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32),
                       iridescence_thickness_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32))


def uv_sphere():
    mesh = trimesh.creation.uv_sphere(count=(24, 24))
    uv = np.column_stack([np.arctan2(mesh.vertices[:, 1], mesh.vertices[:, 0]) / (2 * np.pi) + 0.5,
                          np.arccos(np.clip(mesh.vertices[:, 2], -1, 1)) / np.pi])
    mesh.visual = trimesh.visual.texture.TextureVisuals(uv=np.column_stack([uv[:, 0], 1 - uv[:, 1]]))
    return mesh


DIRECTIONAL = pw.DirectionalLight(direction=(-0.3, -0.5, -1.0), intensity=3.0)
POINT = pw.PointLight(position=(2.0, 2.0, 2.0), intensity=30.0)
SPOT = pw.SpotLight(position=(-2.0, 2.0, 2.5), direction=(1, -1, -1.2), intensity=50.0, inner_cone=0.2, outer_cone=0.6)


def scenes():
    """(name, scene, features expected absent)."""
    floor_and_sphere = sphere_scene(pw.Material(base_color=(0.7, 0.4, 0.3), roughness=0.4), [POINT, SPOT])
    floor_and_sphere.add_mesh(box((6, 0.2, 6), (0, -1.2, 0)), pw.Material())
    mixed = sphere_scene(pw.Material(metallic=0.5, roughness=0.3), [POINT, DIRECTIONAL, SPOT])
    mixed.add_mesh(box((6, 0.2, 6), (0, -1.2, 0)), pw.Material(double_sided=False, alpha_mode="MASK", alpha_cutoff=0.3,
                                                                 base_color=(0.5, 0.5, 0.5, 0.6)))
    two_sets = sphere_scene(textured_material(), [POINT], uv_sphere())
    two_sets.primitives[0].uvs1 = two_sets.primitives[0].uvs[:, ::-1] * 3.0  # TEXCOORD_1
    two_sets.primitives[0].material.emissive_texture.texcoord = 1
    two_sets.primitives[0].material.normal_texture.texcoord = 1
    return [
        ("bare convex", sphere_scene(pw.Material(), [DIRECTIONAL]),
         {"shadows", "base_color_texture", "normal_mapping", "emission", "point_lights", "spot_lights", "pass_through",
          "texture_filter", "second_uv_set", "clearcoat", "sheen"}),
        ("all metal", sphere_scene(pw.Material(metallic=1.0, roughness=0.3), [POINT]), {"diffuse", "directional_lights"}),
        ("pure lambert", sphere_scene(pw.Material(specular=0.0), [SPOT]), {"specular"}),
        ("no lights", sphere_scene(pw.Material(emissive=(0.5, 0.2, 0.1)), []), {"diffuse", "specular", "shadows"}),
        ("textured", sphere_scene(textured_material(), [POINT, DIRECTIONAL], uv_sphere()),
         {"spot_lights", "shadows", "specular_texture", "specular_color_texture"}),
        ("specular textures", sphere_scene(specular_textured_material(), [POINT], uv_sphere()),
         {"base_color_texture", "metallic_roughness_texture", "emissive_texture", "normal_mapping"}),
        ("shadows", floor_and_sphere, {"directional_lights", "normal_mapping"}),
        ("anisotropic", sphere_scene(anisotropic_material(), [POINT, DIRECTIONAL], uv_sphere()),
         {"base_color_texture", "specular_texture", "normal_mapping", "unlit", "iridescence"}),
        ("iridescent", sphere_scene(iridescent_material(), [POINT, SPOT], uv_sphere()),
         {"base_color_texture", "anisotropy", "normal_mapping"}),
        ("second uv set", two_sets, {"spot_lights", "specular_texture", "specular_color_texture"}),
        ("coat over sheen", sphere_scene(pw.Material(base_color=(0.5, 0.1, 0.1), roughness=0.7, clearcoat=0.8,
                                                     clearcoat_roughness=0.1, sheen_color=(0.6, 0.6, 0.9),
                                                     sheen_roughness=0.4), [POINT, DIRECTIONAL]),
         {"spot_lights", "clearcoat_textures", "sheen_textures", "base_color_texture"}),
        ("everything", mixed, set()),
    ]


@pytest.mark.parametrize("name,scene,absent", scenes(), ids=[s[0] for s in scenes()])
@pytest.mark.parametrize("spp", [1, 4])
def test_specialized_image_equals_the_all_effects_image(name, scene, absent, spp):
    features = scene_features(scene, upload(scene), shadows=True, spp=spp)
    dropped = {k for k, v in features.__dict__.items() if not v}
    assert absent <= dropped, (name, dropped)
    assert features.second_uv_set == (name == "second uv set")
    cam = pw.Camera.look_at(eye=(0.5, 1.5, 4.0), target=(0, -0.3, 0))
    # primary visibility pinned to ray casting: the raster path's agreement is tests/test_visibility_path.py's
    special = render_checked(scene, cam, size=(64, 48), spp=spp, visibility="raycast")
    general = render_checked(scene, cam, size=(64, 48), spp=spp, specialize=False)
    # the math of the dropped code is identical to what it would have added (zeros, ones)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)
    assert np.array_equal(special.alpha, general.alpha)
    assert np.array_equal(special.depth, general.depth) and np.array_equal(special.normal, general.normal)


def test_shadows_false_and_no_aovs():
    scene = scenes()[5][1]
    cam = pw.Camera.look_at(eye=(0.5, 1.5, 4.0), target=(0, -0.3, 0))
    frame = render_checked(scene, cam, size=(32, 24), aovs=False)
    assert frame.depth is None and frame.normal is None
    np.testing.assert_array_equal(frame.rgb, render_checked(scene, cam, size=(32, 24)).rgb)
    features = scene_features(scene, upload(scene), shadows=False, spp=1, aovs=False)
    assert not features.shadows and not features.aovs


def test_bare_scene_kernel_has_no_shadow_rays_textures_or_tangent_frames():
    scene = scenes()[0][1]
    source = generated_source(render_kernel(scene_features(scene, upload(scene), shadows=True, spp=1)))
    for absent in ("light_buffer_occlusion", "sample_texture", "perturb_normal", "orthonormal_tangent",
                   "spot_attenuation", "sample_positional", "multi_jittered_sample", "D_GGX_Anisotropic",
                   "F_Iridescence", "mip_lod", "uv_footprint"):
        assert absent not in source, absent
    assert "mesh_query_ray" in source and "D_GGX" in source  # it is the right file
    everything = generated_source(render_kernel(pw.Features.everything(spp=4)))
    for present in ("light_buffer_occlusion", "sample_texture", "perturb_normal", "spot_attenuation", "multi_jittered_sample",
                   "spot_attenuation", "sample_positional", "multi_jittered_sample", "D_GGX_Anisotropic",
                   "F_Iridescence", "mip_lod", "uv_footprint"):
        assert present in everything, present


@pytest.mark.parametrize("texture_filter", ["trilinear", "bilinear"])
def test_texture_filter_is_compiled_in_as_chosen(texture_filter):
    """The textured scene's kernel for each filter renders as the all-effects kernel with that
    filter; only the trilinear one holds the footprint and mip level code."""
    scene = sphere_scene(textured_material(), [POINT, DIRECTIONAL], uv_sphere())
    features = scene_features(scene, upload(scene), shadows=True, spp=1, texture_filter=texture_filter)
    assert features.texture_filter == texture_filter and not features.second_uv_set
    cam = pw.Camera.look_at(eye=(0.5, 1.5, 4.0), target=(0, -0.3, 0))
    special = render_checked(scene, cam, size=(64, 48), visibility="raycast", texture_filter=texture_filter)
    general = render_checked(scene, cam, size=(64, 48), specialize=False, texture_filter=texture_filter)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)
    source = generated_source(render_kernel(features))
    assert "sample_texture" in source
    for footprint_code in ("mip_lod", "uv_footprint", "sample_texture_lod"):
        assert (footprint_code in source) == (texture_filter == "trilinear"), footprint_code


def test_explain_says_what_and_why():
    text = pw.explain(scenes()[0][1])
    assert "no shadow rays: one convex mesh" in text
    assert "no normal maps" in text and "1 directional light" in text
    assert "no shadow rays: shadows=False" in pw.explain(scenes()[5][1], shadows=False)
    assert "no lights" in pw.explain(scenes()[3][1])
    assert "4 stratified samples per pixel" in pw.explain(scenes()[0][1], spp=4)
    assert "no specular textures" in text and "no specular colour textures" in text
    textured = pw.explain(sphere_scene(specular_textured_material(), [POINT], uv_sphere()))
    assert "specular texture: 1 of 1 meshes" in textured and "specular colour texture: 1 of 1 meshes" in textured
    unlit = pw.explain(sphere_scene(specular_textured_material(specular=0.0, metallic=0.0), [POINT], uv_sphere()))
    assert "no specular textures read: no specular lobe" in unlit


def test_changing_factors_keeps_the_variant_changing_effects_may_not():
    material = pw.Material(metallic=0.5, roughness=0.5)
    scene = sphere_scene(material, [POINT])
    before = scene_features(scene, upload(scene), shadows=True, spp=1)
    material.roughness, material.base_color = 0.1, (0.2, 0.3, 0.4, 1.0)
    scene.lights[0].position = (-1.0, 3.0, 1.0)
    assert scene_features(scene, upload(scene), shadows=True, spp=1) == before
    material.metallic = 1.0
    assert not scene_features(scene, upload(scene), shadows=True, spp=1).diffuse


def test_cli_explain(tmp_path, capsys):
    from pbrwarp.cli import main

    mesh = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2).export(mesh)
    assert main(["render", str(mesh), "-o", str(tmp_path / "out.png"), "--size", "16x16", "--explain",
                 "--light", "dir:0,-1,-1:3"]) == 0
    out = capsys.readouterr().out
    assert "no shadow rays: one convex mesh" in out and "simulated:" in out
    assert (tmp_path / "out.png").exists()
