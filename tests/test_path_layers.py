"""Clear coat and sheen in the path tracer: with one bounce it equals the direct integrator's
unbiased rungs for the same layered BRDF (KHR_materials_clearcoat, KHR_materials_sheen), under a
sphere light (next-event estimation dominates) and, for the coat, under an environment (BSDF
sampling of the coat's lobe matters), and stays finite at roughness 0 and grazing views."""

import numpy as np
import pytest

import pbrwarp as pw

from scenes import box, quad
from test_path_lights import DOWN, assert_path_matches_direct

COATED = pw.Material(base_color=(0.8, 0.2, 0.1), roughness=0.6, clearcoat=1.0, clearcoat_roughness=0.15)
SHEENED = pw.Material(base_color=(0.1, 0.2, 0.6), roughness=0.7, sheen_color=(0.9, 0.8, 0.7), sheen_roughness=0.5)


def floor_of(material) -> pw.Scene:
    """A floor of ``material`` (z = 0, facing +z) with a box on it that casts shadows."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=6.0, material=material))
    scene.add_mesh(box((0.6, 0.6, 0.6), (0.4, 0.2, 0.3)), pw.Material(base_color=(0.8, 0.8, 0.8), specular=0.0))
    return scene


@pytest.mark.parametrize("material", [COATED, SHEENED], ids=["clearcoat", "sheen"])
def test_one_bounce_equals_direct_monte_carlo_under_a_sphere_light(material):
    scene = floor_of(material)
    scene.add_light(pw.SphereLight(position=(-0.5, 0.6, 1.5), radius=0.4, intensity=8.0))
    assert_path_matches_direct(scene, dict(spp=4, area_lighting=pw.AreaLighting("monte_carlo", 64)))


def test_one_bounce_equals_direct_monte_carlo_under_an_environment():
    """For the coat. (The direct integrator's environment term of a sheen is an approximation even
    on its Monte Carlo rung: a Lambertian lobe of the sheen's albedo, and the layer below scaled by
    the view's albedo only, kernels/sheen.py sheen_environment; the path tracer evaluates the
    sheen's lobe per direction, 8% darker on this floor.)"""
    scene = floor_of(COATED)
    scene.environment = pw.Environment.sky(zenith=(0.4, 0.6, 1.5), horizon=(1.0, 1.0, 1.0), ground=(0.1, 0.1, 0.1))
    assert_path_matches_direct(scene, dict(spp=4, ibl=pw.IBL(method="monte_carlo", samples=256, shadowed=True)))


@pytest.mark.parametrize("roughness", [0.0, 0.3])
def test_layers_stay_finite_at_roughness_zero_and_grazing_views(roughness):
    material = pw.Material(base_color=(0.9, 0.9, 0.9), roughness=roughness, clearcoat=1.0,
                           clearcoat_roughness=roughness, sheen_color=(1.0, 1.0, 1.0), sheen_roughness=roughness)
    scene = floor_of(material)
    scene.environment = pw.Environment.uniform((1.0, 1.0, 1.0))
    grazing = pw.Camera.look_at(eye=(0.0, -6.0, 0.02), target=(0.0, 3.0, 0.0), up=(0.0, 0.0, 1.0), fov_y=40.0)
    for camera in (DOWN, grazing):
        frame = pw.render(scene, camera, width=16, height=16, spp=4, integrator="path", max_bounces=4,
                          progress=False)
        assert np.all(np.isfinite(frame.rgb)) and frame.rgb.min() >= 0.0
