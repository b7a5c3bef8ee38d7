"""frame.albedo, the denoiser's albedo guide, from both integrators: the first surface's base
colour (OIDN's albedo for dielectrics and glTF metals alike), averaged over the pixel's samples
with 0 for a miss; and pw.denoise feeding it to the filter."""

import importlib

import numpy as np
import pytest

import pbrwarp as pw

from scenes import head_on_camera, lambert_white, quad

INTEGRATORS = ("direct", "path")


def plane_scene(material, size=0.5):
    """A plane of ``size`` filling the middle of the head-on camera's view (about a third of the
    image across), lit by a point light."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=size, material=material))
    scene.add_light(pw.PointLight(position=(0.3, 0.2, 2.0), intensity=5.0))
    return scene


def render(scene, integrator, **options):
    return pw.render(scene, head_on_camera(), width=15, height=15, spp=4, integrator=integrator, progress=False,
                     **options)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_a_white_lambert_plane_has_albedo_one_and_a_miss_zero(integrator):
    frame = render(plane_scene(lambert_white(), size=40.0), integrator)
    np.testing.assert_array_equal(frame.albedo, 1.0)
    frame = render(plane_scene(lambert_white()), integrator)
    inside, outside = frame.alpha == 1.0, frame.alpha == 0.0
    assert inside.sum() >= 9 and outside.sum() >= 100
    np.testing.assert_array_equal(frame.albedo[inside], 1.0)
    np.testing.assert_array_equal(frame.albedo[outside], 0.0)
    # a pixel the plane covers in part: its albedo is the covered share of it
    edge = (frame.alpha > 0.0) & (frame.alpha < 1.0)
    assert edge.any()
    np.testing.assert_allclose(frame.albedo[edge], np.repeat(frame.alpha[edge][:, None], 3, axis=1), atol=1e-6)


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("metallic", [0.0, 1.0, 0.4])
def test_the_albedo_of_a_rough_plane_is_its_base_colour(integrator, metallic):
    """Base colour c: a rough dielectric's diffuse colour and a metal's normal-incidence
    reflectance are both c, and so is any mix of them; independent of light and view."""
    colour = (0.8, 0.35, 0.1)
    material = pw.Material(base_color=colour, metallic=metallic, roughness=0.7)
    frame = render(plane_scene(material, size=40.0), integrator)
    np.testing.assert_allclose(frame.albedo, np.broadcast_to(colour, frame.albedo.shape), rtol=1e-6)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_a_textured_plane_shows_its_texture_in_the_albedo(integrator):
    """A base colour texture, left half (0.9, 0.1, 0.1), right half (0.1, 0.1, 0.9), times a base
    colour factor of 0.5: the albedo follows it, column by column, away from the seam."""
    texels = np.zeros((4, 4, 3), np.float32)
    texels[:, :2] = (0.9, 0.1, 0.1)
    texels[:, 2:] = (0.1, 0.1, 0.9)
    material = pw.Material(base_color=(0.5, 0.5, 0.5), roughness=1.0,
                           base_color_texture=pw.Texture(texels, srgb=False, wrap_s="clamp", wrap_t="clamp"))
    frame = render(plane_scene(material, size=1.2), integrator, texture_filter="bilinear")
    covered = frame.alpha == 1.0
    left = covered & (np.arange(15) < 6)[None, :]
    right = covered & (np.arange(15) > 8)[None, :]
    assert left.sum() >= 6 and right.sum() >= 6
    np.testing.assert_allclose(frame.albedo[left], np.broadcast_to((0.45, 0.05, 0.05), (left.sum(), 3)), atol=0.02)
    np.testing.assert_allclose(frame.albedo[right], np.broadcast_to((0.05, 0.05, 0.45), (right.sum(), 3)),
                               atol=0.02)


def test_albedo_is_dropped_with_the_other_aovs():
    assert render(plane_scene(lambert_white()), "path", aovs=False).albedo is None
    assert render(plane_scene(lambert_white()), "direct", aovs=False).albedo is None


def test_albedo_does_not_depend_on_threads():
    scene = plane_scene(pw.Material(base_color=(0.3, 0.6, 0.2), roughness=0.5))
    for integrator in INTEGRATORS:
        one = render(scene, integrator, threads=1)
        two = render(scene, integrator, threads=2)
        np.testing.assert_array_equal(one.albedo, two.albedo)


def test_denoise_is_guided_by_the_rendered_albedo_and_normal(monkeypatch):
    """pw.denoise hands a rendered frame's albedo and normal to OIDN by default (a stand-in for
    pyoidn records what it is given)."""
    given = {}

    class FakeOIDN:
        @staticmethod
        def denoise(colour, albedo, normal, hdr, quality):
            given.update(albedo=albedo, normal=normal)
            return colour

    # the module (pw.denoise is its function)
    monkeypatch.setattr(importlib.import_module("pbrwarp.denoise"), "_pyoidn", lambda: FakeOIDN)
    frame = render(plane_scene(pw.Material(base_color=(0.3, 0.6, 0.2), roughness=0.5)), "path", target_error=0.5)
    assert frame.variance is not None
    denoised = pw.denoise(frame)
    np.testing.assert_array_equal(given["albedo"], frame.albedo)
    np.testing.assert_array_equal(given["normal"], frame.normal)
    assert denoised.variance is None  # the noisy image's, not the denoised one's
    assert denoised.spp == frame.spp
