"""The rasterized visibility path inside pw.render: the same image as ray casting wherever both pick
the same triangle, pass-through surfaces handled, the choice explained."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp import meshes
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload

from assets import ASSETS, mesh_file
from scenes import render_checked
from test_specialize import scenes


def assert_same_image_where_the_paths_agree(scene, cam, size, spp, **options):
    raster = render_checked(scene, cam, size=size, spp=spp, visibility="raster", **options)
    raycast = render_checked(scene, cam, size=size, spp=spp, visibility="raycast", **options)
    differs = ~np.all(np.isclose(raster.rgb, raycast.rgb, rtol=1e-6, atol=1e-30), axis=-1)
    # a differing pixel is one where a sample's nearest triangle is a tie or lies on an edge,
    # which the two paths may resolve differently: never more than a sliver of the image
    assert differs.mean() <= 2e-3, differs.mean()
    coverage_differs = raster.alpha != raycast.alpha
    assert coverage_differs.mean() <= 2e-3
    return raster, raycast


@pytest.mark.parametrize("name,scene,absent", scenes(), ids=[s[0] for s in scenes()])
@pytest.mark.parametrize("spp", [1, 4])
def test_raster_and_raycast_render_the_same_image(name, scene, absent, spp):
    """Including single-sided and alpha-masked surfaces (the "everything" scene), which camera
    rays pass through: the raster names the nearest triangle, rays continue from there."""
    cam = pw.Camera.look_at(eye=(0.5, 1.5, 4.0), target=(0, -0.3, 0))
    assert_same_image_where_the_paths_agree(scene, cam, (64, 48), spp)


@pytest.mark.parametrize("asset", [ASSETS / "gltf/WaterBottle/glTF/WaterBottle.gltf",
                                   ASSETS / "gltf/Suzanne/glTF/Suzanne.gltf", mesh_file("bunny-decimated.off")],
                         ids=lambda path: path.name)
def test_pixels_whose_samples_pick_the_same_triangle_shade_identically(asset):
    """Where raster and ray caster name the same triangle for a pixel's sample, the shaded pixel is
    the same to 1e-6: the hit is recomputed by the same ray-triangle test."""
    from test_raster import Geometry, camera_data, cast, random_cameras, raster

    scene = pw.Scene.load(asset)
    scene.add_light(pw.PointLight(position=tuple(scene.bounds()[1] * 2.0 + 1.0), intensity=50.0))
    geom = Geometry(scene)
    for camera in random_cameras(scene, 4, seed=5):
        cam = camera_data(camera, 48, 36)
        same = raster(geom, cam)[0] == cast(geom, cam)[0]
        assert same.mean() >= 0.999
        frames = [render_checked(scene, camera, size=(48, 36), visibility=mode) for mode in ("raster", "raycast")]
        np.testing.assert_allclose(frames[0].rgb[same], frames[1].rgb[same], rtol=1e-6, atol=1e-30)


def test_demo_scene_agrees():
    scene, cam = meshes.demo_scene()
    assert_same_image_where_the_paths_agree(scene, cam, (160, 120), 1)


def test_camera_inside_a_closed_mesh():
    """Every triangle crosses or surrounds the camera: the raster's clipped fallback must still see
    the walls exactly as the rays do."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=2, radius=3.0), pw.Material(base_color=(0.6, 0.7, 0.8)))
    scene.add_light(pw.PointLight(position=(0.5, 0.5, 0.5), intensity=20.0))
    cam = pw.Camera.look_at(eye=(0.2, -0.1, 0.3), target=(1.0, 0.2, -1.0), fov_y=100.0)
    raster, _ = assert_same_image_where_the_paths_agree(scene, cam, (64, 48), 1)
    assert raster.alpha.min() == 1.0


def test_visibility_is_a_compile_time_choice_and_explained():
    scene = scenes()[0][1]
    gpu = upload(scene)
    for mode in ("raster", "raycast"):
        assert scene_features(scene, gpu, shadows=True, spp=1, visibility=mode).visibility == mode
        assert "visibility=" + repr(mode) in pw.explain(scene, visibility=mode)
    assert scene_features(scene, gpu, shadows=True, spp=1, visibility="auto").visibility in ("raster", "raycast")
    assert "primary visibility" in pw.explain(scene)
    with pytest.raises(pw.InputError, match="visibility"):
        pw.render(scene, width=8, height=8, visibility="zbuffer")
    # auto does not hold a visibility buffer beyond 1 GiB (16 bytes a sample)
    assert "would take 2,025 MiB" in pw.explain(scene, width=3840, height=2160, spp=16)


def test_back_faces_are_culled_only_where_no_camera_ray_shows_them():
    from pbrwarp.gpu_scene import back_face_culling

    sphere = trimesh.creation.icosphere(subdivisions=2)
    plane = trimesh.Trimesh([[-1, 0, -1], [1, 0, -1], [1, 0, 1]], [[0, 2, 1]])
    cases = [
        # (mesh, material, eye, culled)
        (sphere, pw.Material(double_sided=False), (0.0, 0.0, 0.0), True),  # single-sided: never shaded
        (sphere, pw.Material(), (0.0, 0.0, 3.0), True),  # closed, seen from outside
        (sphere, pw.Material(), (0.0, 0.0, 0.5), False),  # inside: only back faces show
        (sphere, pw.Material(alpha_mode="MASK"), (0.0, 0.0, 3.0), False),  # seen through cut-outs
        (plane, pw.Material(), (0.0, 2.0, 0.0), False),  # open and double-sided
        (sphere.copy().invert(), pw.Material(), (0.0, 0.0, 3.0), False),  # faces turned inwards
        (trimesh.creation.torus(1.0, 0.3), pw.Material(), (0.0, 0.0, 3.0), True),  # closed, genus 1
        (sphere.copy().subdivide(face_index=[0]), pw.Material(), (0.0, 0.0, 3.0), False),  # T-junctions: open
    ]
    for mesh, material, eye, culled in cases:
        scene = pw.Scene()
        scene.add_mesh(mesh, material)
        flags, meshes_culled = back_face_culling(scene, upload(scene), eye)
        assert meshes_culled == int(culled)
        if culled:
            assert flags.numpy().all() and len(flags) == len(mesh.faces)
        else:
            assert flags is None


def test_culled_back_faces_render_as_rays_see_them():
    """A single-sided sphere inside a closed double-sided one, both culled from outside, and the
    camera moved inside the outer one, where its back faces must be drawn again."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3, radius=0.5), pw.Material(double_sided=False))
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3, radius=3.0), pw.Material(base_color=(0.3, 0.6, 0.9)))
    scene.add_light(pw.PointLight(position=(1.0, 1.0, 1.0), intensity=20.0))
    for eye in ((0.0, 0.5, 6.0), (0.0, 0.5, 2.0)):
        cam = pw.Camera.look_at(eye=eye, target=(0.0, 0.0, 0.0), fov_y=60.0)
        raster, _ = assert_same_image_where_the_paths_agree(scene, cam, (64, 48), 1)
        assert raster.alpha.mean() > 0.1


@pytest.mark.parametrize("spp", [1, 4])
def test_samples_the_raster_finds_empty_show_the_background_as_ray_casting_does(spp):
    """The raster path computes no camera ray for a sample its visibility buffer finds empty; its
    pixel still holds the background (alpha 0, depth inf, normal 0), and a pixel partly covered
    mixes it in by coverage, exactly as the ray caster's."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), pw.Material(base_color=(0.8, 0.6, 0.4)))
    scene.add_light(pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    cam = pw.Camera.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0))
    background = (0.2, 0.4, 0.6)
    raster, raycast = assert_same_image_where_the_paths_agree(scene, cam, (40, 30), spp, background=background)
    empty = (raster.alpha == 0.0) & (raycast.alpha == 0.0)
    assert 0.3 < empty.mean() < 0.9
    np.testing.assert_array_equal(raster.rgb[empty], np.broadcast_to(np.float32(background), raster.rgb[empty].shape))
    assert np.all(np.isinf(raster.depth[empty])) and np.all(raster.normal[empty] == 0.0)
    covered_alike = raster.alpha == raycast.alpha
    if spp > 1:
        assert np.any((raster.alpha > 0.0) & (raster.alpha < 1.0))  # partly covered pixels are compared too
    np.testing.assert_allclose(raster.rgb[covered_alike], raycast.rgb[covered_alike], rtol=1e-6, atol=1e-7)
