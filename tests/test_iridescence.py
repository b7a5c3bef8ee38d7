"""KHR_materials_iridescence: the thin-film Fresnel term against a float64 reference of the
extension's formulas and against a spectral integration of the film's reflectance, its physical
limits, and renders of iridescent materials."""

import warnings

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.kernels import iridescence as ki

from assets import BOARDS, board
from test_gltf import loaded_material, material_extension_file

XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])


def schlick(f0, cos):
    return f0 + (1 - f0) * np.clip(1 - cos, 0, 1) ** 5


def film_terms(outside, film, thickness, base_f0, cos1):
    """The interfaces' reflectances and phases of KHR_materials_iridescence (Belcour & Barla 2017):
    (R12 (N,), R23 (N, 3), phase shift (N, 3), optical path difference (N,), total internal reflection (N,))."""
    sin2_sq = (outside / film) ** 2 * (1 - cos1**2)
    tir = sin2_sq >= 1
    cos2 = np.sqrt(np.clip(1 - sin2_sq, 0, 1))
    r12 = schlick(((film - outside) / (film + outside)) ** 2, cos1)
    sqrt_f0 = np.sqrt(np.clip(base_f0, 0, 0.9999))
    base_ior = (1 + sqrt_f0) / (1 - sqrt_f0)
    r23 = schlick(((base_ior - film[:, None]) / (base_ior + film[:, None])) ** 2, cos2[:, None])
    phi21 = np.where(film < outside, 0.0, np.pi)
    phase = phi21[:, None] + np.where(base_ior < film[:, None], np.pi, 0.0)
    return r12, r23, phase, 2 * film * thickness * cos2, tir


def sensitivity(opd, shift):
    """Belcour & Barla's Gaussian fits of the CIE functions' Fourier transforms, in Rec. 709."""
    phase = (2 * np.pi * opd * 1e-9)[:, None]
    val = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
    pos = np.array([1.6810e6, 1.7953e6, 2.2084e6])
    var = np.array([4.3278e9, 9.3046e9, 6.6121e9])
    xyz = val * np.sqrt(2 * np.pi * var) * np.cos(pos * phase + shift) * np.exp(-phase**2 * var)
    xyz[:, 0] += (9.7470e-14 * np.sqrt(2 * np.pi * 4.5282e9) * np.cos(2.2399e6 * phase[:, 0] + shift[:, 0])
                  * np.exp(-4.5282e9 * phase[:, 0] ** 2))
    return (xyz / 1.0685e-7) @ XYZ_TO_REC709.T


def f_iridescence(outside, film, thickness, base_f0, cos1, terms=2, spectral=False):
    """The film's reflectance: the mean R12 + T121^2 R23 / (1 - R12 R23) plus ``terms`` oscillating
    terms 2 C_m S_m, C_m = (Rs - T121) (R12 R23)^(m/2); with ``spectral``, S_m is integrated over
    wavelength against the CIE 1931 functions (Wyman, Sloan & Shirley 2013's fit) instead of the fit."""
    r12, r23, phase, opd, tir = film_terms(outside, film, thickness, base_f0, cos1)
    t121 = 1 - r12
    r123 = np.clip(r12[:, None] * r23, 1e-5, 0.9999)
    rs = t121[:, None] ** 2 * r23 / (1 - r123)
    out = r12[:, None] + rs
    cm = rs - t121[:, None]
    for m in range(1, terms + 1):
        cm = cm * np.sqrt(r123)
        s = spectral_sensitivity(m * opd, m * phase) if spectral else sensitivity(m * opd, m * phase)
        out = out + 2 * cm * s
    return np.where(tir[:, None], 1.0, np.clip(out, 0.0, 1.0))


def spectral_sensitivity(opd, shift):
    """Rec. 709 RGB of the integral over wavelength of cos(2 pi opd / lambda + shift) against the
    CIE 1931 functions, over the integral of y."""
    lam = np.linspace(360.0, 830.0, 2001)

    def lobe(mu, s1, s2):
        return np.exp(-0.5 * ((lam - mu) / np.where(lam < mu, s1, s2)) ** 2)

    x = 1.056 * lobe(599.8, 37.9, 31.0) + 0.362 * lobe(442.0, 16.0, 26.7) - 0.065 * lobe(501.1, 20.4, 26.2)
    y = 0.821 * lobe(568.8, 46.9, 40.5) + 0.286 * lobe(530.9, 16.3, 31.1)
    z = 1.217 * lobe(437.0, 11.8, 36.0) + 0.681 * lobe(459.0, 26.0, 13.8)
    out = np.empty((len(opd), 3))
    for c, cmf in enumerate((x, y, z)):
        wave = np.cos(2 * np.pi * opd[:, None] / lam + shift[:, c : c + 1])
        out[:, c] = np.trapezoid(wave * cmf, lam, axis=1) / np.trapezoid(y, lam)
    return out @ XYZ_TO_REC709.T


@wp.kernel(enable_backward=False)
def eval_film(outside: wp.array(dtype=float), film: wp.array(dtype=float), thickness: wp.array(dtype=float),
              base_f0: wp.array(dtype=wp.vec3), cos1: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = ki.F_Iridescence(outside[i], film[i], thickness[i], base_f0[i], cos1[i])


def kernel_film(outside, film, thickness, base_f0, cos1):
    args = [wp.array(np.asarray(a, np.float32), dtype=float) for a in (outside, film, thickness)]
    args.append(wp.array(np.asarray(base_f0, np.float32), dtype=wp.vec3))
    args.append(wp.array(np.asarray(cos1, np.float32), dtype=float))
    out = wp.zeros(len(cos1), dtype=wp.vec3)
    wp.launch(eval_film, dim=len(cos1), inputs=args + [out])
    return out.numpy().astype(np.float64)


def random_films(count, seed):
    rng = np.random.default_rng(seed)
    return (rng.uniform(1.0, 1.6, count), rng.uniform(1.0, 2.4, count), rng.uniform(0.0, 1200.0, count),
            rng.uniform(0.0, 1.0, (count, 3)), rng.uniform(0.0, 1.0, count))


def test_film_fresnel_matches_the_extensions_formulas_in_float64():
    inputs = random_films(4096, 11)
    np.testing.assert_allclose(kernel_film(*inputs), f_iridescence(*inputs), rtol=2e-4, atol=2e-5)


def test_film_fresnel_agrees_with_a_spectral_integration():
    """The analytic spectral integration (Gaussian fits, two oscillating terms) against the
    wavelength integral of the series to 30 terms, for films of a few hundred nanometres whose
    interfaces reflect little (where the cut series holds)."""
    rng = np.random.default_rng(12)
    count = 512
    outside, film = np.ones(count), rng.uniform(1.2, 1.8, count)
    thickness, base_f0, cos1 = rng.uniform(50, 800, count), rng.uniform(0.0, 0.3, (count, 3)), rng.uniform(0.3, 1.0, count)
    spectral = f_iridescence(outside, film, thickness, base_f0, cos1, terms=30, spectral=True)
    got = kernel_film(outside, film, thickness, base_f0, cos1)
    assert np.abs(got - spectral).max() < 0.05  # the fits stray most at long path differences
    assert np.abs(got - spectral).mean() < 0.005


def test_index_matched_film_is_invisible():
    """A film of the outside medium's IOR leaves the base's own (Schlick) reflectance, seen from
    near the normal (Schlick's approximation, which the extension uses at both interfaces, gives
    even an index-matched interface (1 - cos)^5 at grazing angles)."""
    count = 256
    rng = np.random.default_rng(13)
    base_f0, cos1 = rng.uniform(0.0, 1.0, (count, 3)), rng.uniform(0.8, 1.0, count)
    got = kernel_film(np.ones(count), np.ones(count), rng.uniform(0, 1000, count), base_f0, cos1)
    np.testing.assert_allclose(got, schlick(base_f0, cos1[:, None]), atol=0.03)


def test_film_reflectance_is_bounded_and_finite_everywhere():
    count = 4096
    outside, film, thickness, base_f0, cos1 = random_films(count, 14)
    cos1[:64] = 0.0
    cos1[64:128] = 1.0
    thickness[:32] = 0.0
    got = kernel_film(outside, film, thickness, base_f0, cos1)
    assert np.isfinite(got).all() and got.min() >= 0.0 and got.max() <= 1.0
    # from a denser outside medium at grazing angles the film reflects everything
    tir = kernel_film(np.full(4, 2.0), np.full(4, 1.2), np.full(4, 300.0), np.full((4, 3), 0.04), np.full(4, 0.1))
    np.testing.assert_array_equal(tir, 1.0)


def test_sensitivity_at_zero_path_difference_is_the_matching_functions_white():
    @wp.kernel(enable_backward=False)
    def at_zero(out: wp.array(dtype=wp.vec3)):
        out[0] = ki.thin_film_sensitivity(0.0, wp.vec3(0.0))

    out = wp.zeros(1, dtype=wp.vec3)
    wp.launch(at_zero, dim=1, inputs=[out])
    np.testing.assert_allclose(out.numpy()[0], XYZ_TO_REC709 @ np.ones(3), rtol=2e-3)


# ---------------------------------------------------------------------------- renders

def sphere(**material):
    scene = pw.Scene()
    mesh = trimesh.creation.icosphere(subdivisions=4)
    mesh.visual = trimesh.visual.texture.TextureVisuals(uv=0.5 + 0.5 * mesh.vertices[:, :2])  # for the textures
    scene.add_mesh(mesh,
                   pw.Material(base_color=(0.02, 0.02, 0.02), metallic=0.0, roughness=0.05, **material))
    scene.environment = pw.Environment.uniform(1.0)
    camera = pw.Camera(eye=(0, 0, 3.2), forward=(0, 0, -1), up=(0, 1, 0), fov_y=45)
    image = np.asarray(pw.render(scene, camera, width=48, height=48).rgb, np.float64)
    assert np.isfinite(image).all()
    return image


def test_film_colours_a_grey_sphere_by_angle():
    """A near-black dielectric under white light reflects grey; with a film its reflection is
    coloured, and the colour changes from the centre (head-on) to the rim (grazing)."""
    plain = sphere()
    filmed = sphere(iridescence=1.0, iridescence_ior=1.8, iridescence_thickness_max=500.0)
    chroma = lambda rgb: rgb.max(-1) - rgb.min(-1)  # noqa: E731
    assert chroma(plain[24, 24]) < 1e-3
    centre, rim = filmed[24, 24], filmed[24, 10]
    assert chroma(centre) > 0.02
    assert np.argmax(centre) != np.argmax(rim) or np.abs(centre / centre.sum() - rim / rim.sum()).max() > 0.02


def test_thickness_texture_blends_between_min_and_max():
    texel = np.full((4, 4, 3), 0.25, np.float32)
    by_texture = sphere(iridescence=1.0, iridescence_thickness_min=200.0, iridescence_thickness_max=600.0,
                        iridescence_thickness_texture=texel)
    by_factor = sphere(iridescence=1.0, iridescence_thickness_max=300.0)
    np.testing.assert_allclose(by_texture, by_factor, rtol=1e-4, atol=1e-6)


# ---------------------------------------------------------------------------- glTF

def test_gltf_iridescence_is_read_without_a_warning(tmp_path):
    material = loaded_material(material_extension_file(tmp_path, "KHR_materials_iridescence", {
        "iridescenceFactor": 0.8, "iridescenceIor": 1.4, "iridescenceThicknessMinimum": 150.0,
        "iridescenceThicknessMaximum": 700.0, "iridescenceThicknessTexture": {"index": 0}}, required=True))
    assert (material.iridescence, material.iridescence_ior) == pytest.approx((0.8, 1.4))
    assert (material.iridescence_thickness_min, material.iridescence_thickness_max) == pytest.approx((150.0, 700.0))
    assert material.iridescence_thickness_texture is not None and material.iridescence_texture is None


@pytest.mark.skipif("IridescenceSuzanne" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
def test_iridescence_suzanne_board_shows_coloured_reflections():
    """IridescenceSuzanne requires the extension; its README: thin-film colours over the heads."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its transmission and volume are warned about elsewhere
        scene = pw.Scene.load(board("IridescenceSuzanne"))
    scene.environment = pw.Environment.uniform(1.0)
    image = np.asarray(pw.render(scene, pw.Camera.frame(scene), width=64, height=48, background=(0, 0, 0)).rgb)
    assert np.isfinite(image).all()
    covered = image.sum(-1) > 0
    assert (image.max(-1) - image.min(-1))[covered].mean() > 0.02
