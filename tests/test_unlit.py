"""KHR_materials_unlit: an unlit surface's radiance is its base colour, whatever lights it."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload

from assets import board
from scenes import box, render_checked

ORANGE = (0.9, 0.4, 0.1)
CAMERA = pw.Camera.look_at(eye=(0.5, 2.0, 4.0), target=(0.0, -0.3, 0.0))


def lit_scene(sphere_material, environment=True):
    """A sphere on a floor under a point and a directional light (and a uniform environment)."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), sphere_material)
    scene.add_mesh(box((6, 0.2, 6), (0, -1.2, 0)), pw.Material(base_color=(0.6, 0.6, 0.6)))
    scene.add_light(pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    scene.add_light(pw.DirectionalLight(direction=(0.2, -1.0, -0.3), intensity=3.0))
    if environment:
        scene.environment = pw.Environment.uniform(intensity=0.5)
    return scene


def sphere_pixels(size):
    """The pixels the sphere covers whole (in front of the floor from CAMERA): where a render of
    the sphere alone is fully covered."""
    alone = pw.Scene()
    alone.add_mesh(trimesh.creation.icosphere(subdivisions=3), pw.Material())
    return render_checked(alone, CAMERA, size=size).alpha == 1.0


@pytest.mark.parametrize("environment", [False, True])
def test_an_unlit_surface_shows_its_base_colour_under_any_light(environment):
    """Unlit: radiance = base colour in nits at every pixel, though lights, an environment, an
    emissive factor and a metallic-roughness setting would all change a lit surface."""
    material = pw.Material(base_color=ORANGE, emissive=(5.0, 5.0, 5.0), metallic=0.7, roughness=0.2, unlit=True)
    frame = render_checked(lit_scene(material, environment), CAMERA, size=(64, 48))
    on_sphere = sphere_pixels((64, 48))
    assert on_sphere.sum() > 200
    np.testing.assert_allclose(frame.rgb[on_sphere], np.broadcast_to(ORANGE, (on_sphere.sum(), 3)), rtol=1e-6)


def test_an_unlit_base_colour_texture_multiplies_its_colour():
    """A constant 8-bit sRGB texel 188 is 188/255 decoded by the sRGB transfer function."""
    texel = 188 / 255
    linear = ((texel + 0.055) / 1.055) ** 2.4
    mesh = trimesh.creation.icosphere(subdivisions=3)
    mesh.visual = trimesh.visual.texture.TextureVisuals(uv=np.full((len(mesh.vertices), 2), 0.5))
    material = pw.Material(base_color=ORANGE, base_color_texture=np.full((4, 4, 3), 188, dtype=np.uint8), unlit=True)
    scene = pw.Scene()
    scene.add_mesh(mesh, material)
    scene.add_light(pw.DirectionalLight(direction=(0.2, -1.0, -0.3), intensity=3.0))
    frame = render_checked(scene, CAMERA, size=(48, 36))
    hit = frame.alpha == 1.0
    np.testing.assert_allclose(frame.rgb[hit], np.broadcast_to(np.multiply(ORANGE, linear), (hit.sum(), 3)), rtol=1e-5)


def test_an_unlit_surface_still_casts_shadows():
    """The floor under an unlit sphere is shadowed from the overhead light as under a lit one."""
    def floor_under_sphere(material):
        scene = pw.Scene()
        scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), material)
        scene.add_mesh(box((6, 0.2, 6), (0, -1.2, 0)), pw.Material(base_color=(0.6, 0.6, 0.6)))
        scene.add_light(pw.DirectionalLight(direction=(0.0, -1.0, 0.0), intensity=3.0))
        camera = pw.Camera.look_at(eye=(0.0, -1.05, 0.0), target=(0.0, -2.0, 0.0), up=(0.0, 0.0, -1.0))
        return render_checked(scene, camera, size=(8, 8)).rgb
    unlit = floor_under_sphere(pw.Material(unlit=True))
    lit = floor_under_sphere(pw.Material())
    np.testing.assert_array_equal(unlit, lit)
    assert np.all(unlit < 1e-6)  # straight under the sphere: no direct light reaches the floor


def test_unlit_is_compiled_in_only_when_a_material_is_unlit():
    lit = lit_scene(pw.Material(base_color=ORANGE))
    assert not scene_features(lit, upload(lit), shadows=True, spp=1).unlit
    assert "no unlit materials" in pw.explain(lit)
    mixed = lit_scene(pw.Material(base_color=ORANGE, unlit=True))
    assert scene_features(mixed, upload(mixed), shadows=True, spp=1).unlit
    assert "unlit (KHR_materials_unlit): 1 material show" in pw.explain(mixed)
    special = render_checked(mixed, CAMERA, size=(48, 36))
    general = render_checked(mixed, CAMERA, size=(48, 36), specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)


def test_every_material_unlit_drops_the_brdf():
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=2), pw.Material(unlit=True))
    scene.add_light(pw.PointLight(position=(2.0, 3.0, 2.0), intensity=40.0))
    features = scene_features(scene, upload(scene), shadows=True, spp=1)
    assert not features.diffuse and not features.specular
    assert "every material is unlit" in pw.explain(scene)


def test_unlit_board_shows_two_flat_colours():
    """UnlitTest: an orange and a blue object (base colours (1, 0.2176, 0) and (0, 0.2176, 1),
    #FF7F00 and #007FFF in sRGB) that must look uniformly coloured, "so much so that the 3D
    effect is intentionally lost" (its README), however lit."""
    scene = pw.Scene.load(board("UnlitTest"))
    assert scene.load_warnings == ()
    scene.add_light(pw.DirectionalLight(direction=(0.3, -1.0, -0.5), intensity=5.0))
    scene.environment = pw.Environment.uniform(intensity=0.8)
    frame = render_checked(scene, pw.Camera.frame(scene, direction=(0.2, 0.3, 1.0), aspect=4 / 3), size=(64, 48))
    covered = frame.alpha == 1.0
    colours = {tuple(round(float(x), 5) for x in c) for c in frame.rgb[covered]}
    assert colours == {(1.0, 0.21764, 0.0), (0.0, 0.21764, 1.0)}, colours
