"""glTF 2.0's material model in renders: material = mix(dielectric_brdf, metal_brdf, metallic)
(Appendix B), so a partly metallic surface is exactly the blend of its dielectric and its metal,
under lights and under an environment; the "f0" mix of Karis 2013 is not, which is what tinted
the demo's partly metallic spheres."""

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from pbrwarp.brdf import PRESETS

from scenes import head_on_camera, render_checked

# the demo's sphere colour (pbrwarp.meshes.demo_scene)
GOLD = (0.9, 0.6, 0.2)


def sphere(metallic, roughness, **material):
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3),
                   pw.Material(base_color=GOLD, metallic=metallic, roughness=roughness, **material))
    return scene


def lit(scene, environment):
    if environment:
        scene.environment = pw.Environment.uniform((0.6, 0.7, 0.8))
    else:
        scene.add_light(pw.DirectionalLight(direction=(-0.3, -0.4, -1.0), intensity=3.0))
        scene.add_light(pw.PointLight(position=(2.0, 1.0, 3.0), intensity=20.0))
    return scene


def renders(metallics, roughness, brdf, environment, **material):
    return [render_checked(lit(sphere(m, roughness, **material), environment), head_on_camera(), size=(24, 24),
                           brdf=brdf, background=(0, 0, 0)).rgb.astype(np.float64) for m in metallics]


@pytest.mark.parametrize("environment", [False, True], ids=["lights", "environment"])
@pytest.mark.parametrize("roughness", [0.3, 0.9])
def test_half_metallic_is_the_mean_of_dielectric_and_metal(environment, roughness):
    """Linear in metallic: L(1/2) = (L(0) + L(1)) / 2 to float32 rounding, for the default BRDF
    (with an IOR and a specular colour too), the most exact rungs and the cheapest. The f0 mix loses over a tenth of
    the red light, far less of the blue: its diffuse share is smallest where the mixed f0 (half
    the gold) is largest, which shifts the colour away from the base colour (the tint)."""
    for brdf, material in ((pw.BRDF(), {}), (pw.BRDF(), dict(ior=1.7, specular_color=(1.5, 1.0, 0.6))),
                           (PRESETS["reference"], {}), (PRESETS["fast"], {})):
        dielectric, half, metal = renders((0.0, 0.5, 1.0), roughness, brdf, environment, **material)
        assert half.max() > 0.05
        np.testing.assert_allclose(half, (dielectric + metal) / 2, rtol=2e-5, atol=2e-6 * half.max())
    dielectric, half, metal = renders((0.0, 0.5, 1.0), roughness, pw.BRDF(metallic_mix="f0"), environment)
    shift = np.abs(half.sum((0, 1)) / ((dielectric + metal) / 2).sum((0, 1)) - 1)
    assert shift[0] > 0.1 and shift[0] > 2 * shift[2], shift


def test_the_f0_mix_is_a_named_rung_and_explained():
    scene = lit(sphere(0.5, 0.5), False)
    assert "glTF's mix of a dielectric and a metal BRDF" in pw.explain(scene)
    assert "f0 mixed by metallic" in pw.explain(scene, brdf=pw.BRDF(metallic_mix="f0"))
    with pytest.raises(pw.InputError, match="metallic_mix"):
        pw.BRDF(metallic_mix="average")


@pytest.mark.parametrize("material", [dict(ior=0.0), dict(specular_color=(50.0, 50.0, 50.0)),
                                      dict(ior=2.4, specular_color=(3.0, 1.0, 0.2)), dict(ior=1.0)],
                         ids=["ior 0", "colour 50", "tinted diamond", "ior 1"])
@pytest.mark.parametrize("metallic", [0.0, 0.5])
def test_white_furnace_under_a_uniform_environment(material, metallic):
    """A white sphere under a uniform white environment of radiance 1 reflects its directional
    albedo, which the split sum's glTF mix keeps at most 1 for any IOR and specular colour (the
    dielectric's f0 clamped to 1, its diffuse lobe given what the layer's largest channel leaves)."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3),
                   pw.Material(base_color=(1, 1, 1), metallic=metallic, roughness=0.5, **material))
    scene.environment = pw.Environment.uniform((1, 1, 1))
    frame = render_checked(scene, head_on_camera(), size=(24, 24), background=(0, 0, 0))
    covered = frame.alpha > 0
    assert covered.sum() > 100
    assert frame.rgb[covered].max() <= 1.0 + 1e-3
    assert frame.rgb[covered].min() > 0.5  # and it reflects most of it: white
