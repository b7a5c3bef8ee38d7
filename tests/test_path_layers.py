"""Clear coat and sheen in the path tracer: with one bounce it equals the direct integrator's
unbiased rungs for the same layered BRDF (KHR_materials_clearcoat, KHR_materials_sheen), under a
sphere light (next-event estimation dominates) and, for the coat, under an environment (BSDF
sampling of the coat's lobe matters); coated white spheres in a white furnace reflect at most,
and nearly all of, what they receive; emission lies below the coat; finite at roughness 0 and
grazing views."""

import math

import numpy as np
import pytest
import trimesh

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


def sphere_in_furnace(material, radiance):
    scene = pw.Scene()
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    scene.add_mesh(pw.Primitive(np.asarray(sphere.vertices), np.asarray(sphere.faces), material,
                                np.asarray(sphere.vertex_normals)))
    scene.environment = pw.Environment.uniform((radiance,) * 3)
    return scene


@pytest.mark.parametrize("coat_roughness, sheen", [(0.0, 0.0), (0.5, 1.0)])
def test_a_coated_white_sphere_in_a_white_furnace_reflects_at_most_what_it_receives(coat_roughness, sheen):
    """A white Lambert sphere (specular 0) under a clear coat, and a white sheen, in a uniform
    environment of radiance L reflects (1 - w) (what the layers below reflect, at most L) + w E_coat L
    <= L, and close to L: the coat's lobe (GGX, F = 1) keeps most of what it reflects. At roughness
    0 and at the silhouette's grazing views no pixel is NaN or Inf."""
    radiance = 0.8
    material = pw.Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, specular=0.0, roughness=1.0, clearcoat=1.0,
                           clearcoat_roughness=coat_roughness, sheen_color=(sheen,) * 3, sheen_roughness=0.6)
    camera = pw.Camera.look_at(eye=(0.0, 0.0, 3.2), target=(0.0, 0.0, 0.0), fov_y=40.0)
    frame = pw.render(sphere_in_furnace(material, radiance), camera, width=32, height=32, spp=16, integrator="path",
                      max_bounces=3, seed=5, progress=False)
    assert pw.check(frame).ok
    covered = frame.alpha == 1.0
    assert covered.sum() > 300
    values = frame.rgb[..., 1][covered].astype(np.float64)
    mean, error = values.mean(), values.std(ddof=1) / math.sqrt(values.size)
    assert mean <= radiance + 3 * error, (mean, error)
    assert mean >= 0.9 * radiance, (mean, error)
    # head on (the sphere's centre) the coat reflects 4% and the layers below the rest, within noise
    centre = frame.rgb[12:20, 12:20, 1].astype(np.float64)
    assert centre.mean() <= radiance + 4 * centre.std(ddof=1) / math.sqrt(centre.size)


def test_emission_lies_below_the_coat_as_in_the_direct_integrator():
    """KHR_materials_clearcoat darkens the emission below by 1 - clearcoat F_coat(Nc.v): an
    emissive coated plane seen head on, no lights, shows E (1 - clearcoat F_coat) in both
    integrators (the plane does not light itself)."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0, material=pw.Material(base_color=(0.5, 0.5, 0.5), emissive=(2.0, 1.0, 0.5),
                                                        clearcoat=0.7, clearcoat_roughness=0.3)))
    camera = pw.Camera.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), fov_y=10.0)
    path = pw.render(scene, camera, width=8, height=8, spp=4, integrator="path", max_bounces=2, progress=False).rgb
    direct = pw.render(scene, camera, width=8, height=8, spp=4, progress=False).rgb
    np.testing.assert_allclose(path, direct, rtol=1e-3)
    # head on: F_coat = 0.04 (Schlick at n.v ~ 1, within 1e-6 across a 10 degree view)
    np.testing.assert_allclose(path.mean((0, 1)), np.array([2.0, 1.0, 0.5]) * (1 - 0.7 * 0.04), rtol=1e-4)
