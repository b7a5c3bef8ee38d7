"""The BRDF ladder: every rung of every term against a float64 reference written from its paper,
properties that each must have, and every combination rendering finite images."""

import itertools

import numpy as np
import pytest
import warp as wp

import pbrwarp as pw
from pbrwarp.kernels import brdf as kb
from pbrwarp.kernels import microfacet as km

from scenes import head_on_camera, render_checked

N = 2048


@wp.kernel(enable_backward=False)
def eval_scalar_terms(nv: wp.array(dtype=float), nl: wp.array(dtype=float), lh: wp.array(dtype=float),
                      nh: wp.array(dtype=float), r: wp.array(dtype=float), out: wp.array2d(dtype=float)):
    i = wp.tid()
    a = r[i] * r[i]
    out[i, 0] = kb.Fd_Burley(nv[i], nl[i], lh[i], r[i])
    out[i, 1] = km.D_BlinnPhong(a, nh[i])
    out[i, 2] = km.V_SmithGGXSeparable(nv[i], nl[i], a)
    out[i, 3] = km.V_SmithGGXCorrelated(nv[i], nl[i], a)
    out[i, 4] = km.V_SmithGGXCorrelatedFast(nv[i], nl[i], a)
    out[i, 5] = km.V_Implicit(nv[i], nl[i], a)


@wp.kernel(enable_backward=False)
def eval_fresnel(f0: wp.array(dtype=wp.vec3), f90: wp.array(dtype=wp.vec3), vh: wp.array(dtype=float),
                 out: wp.array2d(dtype=wp.vec3)):
    i = wp.tid()
    out[i, 0] = kb.F_None(f0[i], f90[i], vh[i])
    out[i, 1] = kb.F_SphericalGaussian(f0[i], f90[i], vh[i])
    out[i, 2] = kb.F_Exact(f0[i], f90[i], vh[i])
    out[i, 3] = kb.F_Schlick(f0[i], f90[i], vh[i])


def f32(x):
    return np.asarray(x, np.float32).astype(np.float64)


@pytest.fixture(scope="module")
def scalars():
    rng = np.random.default_rng(11)
    x = {k: f32(rng.uniform(lo, 1.0, N)) for k, lo in (("nv", 0.05), ("nl", 0.05), ("lh", 0.05), ("nh", 0.5), ("r", 0.2))}
    out = wp.zeros((N, 6), dtype=float)
    wp.launch(eval_scalar_terms, dim=N, inputs=[wp.array(x[k].astype(np.float32)) for k in ("nv", "nl", "lh", "nh", "r")] + [out])
    return x, out.numpy().astype(np.float64)


def rel(got, want):
    return np.max(np.abs(got - want) / np.abs(want))


def test_burley_diffuse(scalars):
    x, out = scalars
    f90 = 0.5 + 2 * x["r"] * x["lh"] ** 2
    want = (1 + (f90 - 1) * (1 - x["nl"]) ** 5) * (1 + (f90 - 1) * (1 - x["nv"]) ** 5) / np.pi
    assert rel(out[:, 0], want) <= 1e-5


def test_blinn_phong_ndf(scalars):
    x, out = scalars
    power = 2 / x["r"] ** 4 - 2
    want = (power + 2) / (2 * np.pi) * x["nh"] ** power
    keep = want > 1e-20
    # (n.h)^p with p up to ~600 magnifies float32 rounding of n.h by p
    assert rel(out[keep, 1], want[keep]) <= 1e-5 * 600


def smith_lambda(cos, alpha):
    """Heitz 2014, GGX: Lambda = (-1 + sqrt(1 + alpha^2 tan^2)) / 2."""
    tan2 = (1 - cos**2) / cos**2
    return (-1 + np.sqrt(1 + alpha**2 * tan2)) / 2


def test_smith_separable_and_correlated_visibility(scalars):
    x, out = scalars
    a = x["r"] ** 2
    lv, ll = smith_lambda(x["nv"], a), smith_lambda(x["nl"], a)
    denominator = 4 * x["nv"] * x["nl"]
    assert rel(out[:, 2], 1 / ((1 + lv) * (1 + ll)) / denominator) <= 1e-5
    assert rel(out[:, 3], 1 / (1 + lv + ll) / denominator) <= 1e-5
    np.testing.assert_allclose(out[:, 5], 0.25)


def test_fast_correlated_visibility_follows_its_formula_and_approximates_heitz(scalars):
    x, out = scalars
    a = x["r"] ** 2
    want = 0.5 / (x["nl"] * (x["nv"] * (1 - a) + a) + x["nv"] * (x["nl"] * (1 - a) + a))
    assert rel(out[:, 4], want) <= 1e-5
    # the linear fit x (1 - a) + a bounds sqrt(x^2 (1 - a^2) + a^2) from above (their squares
    # differ by 2a(1 - a)x(1 - x) >= 0), so the fast term never exceeds the exact one
    assert np.all(out[:, 4] <= out[:, 3] * (1 + 1e-6))


def snell_fresnel(cos_i, eta):
    """Unpolarized reflectance from the s and p amplitudes (Fresnel 1823) via Snell's law."""
    sin_t = np.sqrt(np.maximum(0, 1 - cos_i**2)) / eta
    cos_t = np.sqrt(np.maximum(0, 1 - sin_t**2))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs**2 + rp**2)


@pytest.fixture(scope="module")
def fresnel():
    rng = np.random.default_rng(12)
    f0 = f32(rng.uniform(0.01, 0.95, (N, 3)))
    f90 = f32(rng.uniform(0.2, 1.0, (N, 1)) * np.ones((1, 3)))
    vh = f32(rng.uniform(0.01, 1.0, N))
    out = wp.zeros((N, 4), dtype=wp.vec3)
    wp.launch(eval_fresnel, dim=N, inputs=[wp.array(f0.astype(np.float32), dtype=wp.vec3), wp.array(f90.astype(np.float32), dtype=wp.vec3),
                                           wp.array(vh.astype(np.float32)), out])
    return f0, f90, vh, out.numpy().astype(np.float64)


def test_fresnel_none_and_spherical_gaussian(fresnel):
    f0, f90, vh, out = fresnel
    np.testing.assert_array_equal(out[:, 0], f0)
    want = f0 + (f90 - f0) * 2.0 ** ((-5.55473 * vh - 6.98316) * vh)[:, None]
    assert rel(out[:, 1], want) <= 1e-5
    # the fit follows Schlick's (1 - v.h)^5 closely
    assert np.max(np.abs(out[:, 1] - out[:, 3])) <= 0.01


def test_exact_fresnel_is_the_dielectric_reflectance_of_the_implied_ior(fresnel):
    f0, f90, vh, out = fresnel
    ratio = np.clip(f0 / f90, 0, 0.9999)
    eta = (1 + np.sqrt(ratio)) / (1 - np.sqrt(ratio))
    want = f90 * snell_fresnel(vh[:, None], eta)
    assert rel(out[:, 2], want) <= 2e-5
    # at normal incidence it is f0 (up to the f0/f90 clamp), at grazing f90
    np.testing.assert_allclose(f90 * snell_fresnel(np.ones((1, 1)), eta), np.minimum(f0, 0.9999 * f90), rtol=1e-9)


@wp.kernel(enable_backward=False)
def eval_conductor(eta: wp.array(dtype=wp.vec3), kappa: wp.array(dtype=wp.vec3), vh: wp.array(dtype=float),
                   out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = kb.F_Conductor(eta[i], kappa[i], vh[i])


def complex_fresnel(cos_i, eta):
    """Unpolarized reflectance of a complex IOR from the s and p amplitudes, in complex arithmetic
    with Snell's law n cos_t = sqrt(n^2 - sin_i^2) (Born & Wolf)."""
    root = np.sqrt(eta.astype(np.complex128) ** 2 - (1 - cos_i**2))
    rs = (cos_i - root) / (cos_i + root)
    rp = (eta**2 * cos_i - root) / (eta**2 * cos_i + root)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def test_conductor_fresnel_matches_complex_arithmetic():
    rng = np.random.default_rng(13)
    eta = f32(rng.uniform(0.05, 3.0, (N, 3)))
    kappa = f32(rng.uniform(0.0, 8.0, (N, 3)))
    vh = f32(np.concatenate([rng.uniform(0.0, 1.0, N - 2), [0.0, 1.0]]))
    out = wp.zeros(N, dtype=wp.vec3)
    wp.launch(eval_conductor, dim=N, inputs=[wp.array(eta.astype(np.float32), dtype=wp.vec3),
                                             wp.array(kappa.astype(np.float32), dtype=wp.vec3), wp.array(vh.astype(np.float32)), out])
    want = complex_fresnel(vh[:, None], eta + 1j * kappa)
    assert rel(out.numpy().astype(np.float64), want) <= 2e-5
    # grazing incidence reflects everything; normal incidence is ((n-1)^2 + k^2) / ((n+1)^2 + k^2)
    np.testing.assert_allclose(out.numpy()[-2], 1.0, rtol=1e-6)
    np.testing.assert_allclose(out.numpy()[-1], ((eta[-1] - 1) ** 2 + kappa[-1] ** 2) / ((eta[-1] + 1) ** 2 + kappa[-1] ** 2), rtol=1e-5)


def test_conductor_material_and_exact_rung():
    """Material.conductor's base colour is its normal-incidence reflectance, so every Fresnel rung
    agrees head-on; at oblique angles the exact rung follows the conductor equations."""
    n, k = (0.2, 0.9, 1.1), (3.9, 2.45, 1.8)
    metal = pw.Material.conductor(n, k, roughness=0.4)
    want_f0 = complex_fresnel(np.ones(1), np.array(n) + 1j * np.array(k))
    np.testing.assert_allclose(metal.base_color[:3], want_f0, rtol=1e-12)
    assert metal.metallic == 1.0 and metal.complex_ior == (n, k)
    cos_v = np.array([1.0, 0.6, 0.2])
    v = wp.array(np.stack([np.sqrt(1 - cos_v**2), np.zeros(3), cos_v], -1).astype(np.float32), dtype=wp.vec3)

    def evaluate(fresnel_model):
        brdf = kb.brdf_for(False, True, fresnel=fresnel_model)

        @wp.kernel(enable_backward=False, module="unique")
        def mirror_pair(v: wp.array(dtype=wp.vec3), base: wp.vec3, eta: wp.vec3, kappa: wp.vec3, out: wp.array(dtype=wp.vec3)):
            i = wp.tid()
            mirrored = wp.vec3(-v[i][0], -v[i][1], v[i][2])
            out[i] = brdf(wp.vec3(0.0, 0.0, 1.0), v[i], mirrored, base, 1.0, 0.4, 1.0, eta, kappa)

        out = wp.zeros(3, dtype=wp.vec3)
        wp.launch(mirror_pair, dim=3, inputs=[v, wp.vec3(*metal.base_color[:3]), wp.vec3(*n), wp.vec3(*k), out])
        return out.numpy().astype(np.float64)

    # l the mirror image of v: h = n, v.h = n.v, so exact / none = F_conductor(n.v) / f0 per channel
    ratio = evaluate("exact") / evaluate("none")
    want = complex_fresnel(cos_v[:, None], np.array(n) + 1j * np.array(k)) / want_f0
    np.testing.assert_allclose(ratio, want, rtol=2e-5)
    with pytest.raises(pw.InputError, match="complex_ior"):
        pw.Material(complex_ior=((1.0, 1.0, 0.0), (1.0, 1.0, 1.0)))
    with pytest.raises(pw.InputError, match="complex_ior"):
        pw.Material(complex_ior=(1.0, 2.0, 3.0))


def test_exact_rung_gives_the_dielectric_the_fresnel_of_its_ior():
    """glTF's mix with fresnel="exact": a dielectric (metallic 0, specular 1, white specular
    colour) reflects with the Fresnel equations of the material's IOR (KHR_materials_ior), the
    f0 it gets from ((ior - 1) / (ior + 1))^2 head-on."""
    cos_v = np.array([1.0, 0.6, 0.2, 0.05])
    v = wp.array(np.stack([np.sqrt(1 - cos_v**2), np.zeros(4), cos_v], -1).astype(np.float32), dtype=wp.vec3)

    def evaluate(fresnel_model, f0):
        brdf = kb.brdf_for(False, True, fresnel=fresnel_model)

        @wp.kernel(enable_backward=False, module="unique")
        def mirror_pair(v: wp.array(dtype=wp.vec3), f0: wp.vec3, out: wp.array(dtype=wp.vec3)):
            i = wp.tid()
            mirrored = wp.vec3(-v[i][0], -v[i][1], v[i][2])
            out[i] = brdf(wp.vec3(0.0, 0.0, 1.0), v[i], mirrored, wp.vec3(0.5), 0.0, 0.4, 1.0, wp.vec3(0.0),
                          wp.vec3(0.0), f0)

        out = wp.zeros(4, dtype=wp.vec3)
        wp.launch(mirror_pair, dim=4, inputs=[v, wp.vec3(f0), out])
        return out.numpy().astype(np.float64)

    for ior in (1.33, 1.5, 2.42):
        f0 = pw.Material(ior=ior).f0_dielectric[0]
        ratio = evaluate("exact", f0) / evaluate("none", f0)
        want = complex_fresnel(cos_v, np.array(ior)) / f0
        np.testing.assert_allclose(ratio, np.repeat(want[:, None], 3, 1), rtol=5e-5)
    with pytest.raises(pw.InputError, match="ior"):
        pw.Material(ior=0.9)
    assert pw.Material(ior=0).f0_dielectric == (1.0, 1.0, 1.0)


@pytest.mark.parametrize("model", ["phong", "blinn_phong"])
def test_legacy_models_follow_seed_002(model):
    """Lambert (1 - c_spec) c_diff / pi plus c_spec times the normalized lobe: Phong
    (a + 2) / (2 pi) (r.v)^a with a a quarter of the Blinn-Phong exponent, Blinn-Phong's
    (a + 8) / (8 pi) (n.h)^a, a = 2 / alpha^2 - 2."""
    brdf = kb.brdf_for(True, True, model=model)

    @wp.kernel(enable_backward=False, module="unique")
    def evaluate(v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3), base: wp.array(dtype=wp.vec3),
                 m: wp.array(dtype=float), r: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        out[i] = brdf(wp.vec3(0.0, 0.0, 1.0), v[i], l[i], base[i], m[i], r[i], 1.0)

    rng = np.random.default_rng(14)
    count = 1024
    v, l = (f32(x / np.linalg.norm(x, axis=1, keepdims=True)) for x in (rng.normal(size=(count, 3)) * [1, 1, 0] + [0, 0, 1.2],
                                                                          rng.normal(size=(count, 3)) * [1, 1, 0] + [0, 0, 1.2]))
    base, m, r = f32(rng.uniform(0, 1, (count, 3))), f32(rng.uniform(0, 1, count)), f32(rng.uniform(0.3, 1, count))
    out = wp.zeros(count, dtype=wp.vec3)
    wp.launch(evaluate, dim=count, inputs=[wp.array(a.astype(np.float32), dtype=wp.vec3) for a in (v, l, base)]
              + [wp.array(m.astype(np.float32)), wp.array(r.astype(np.float32)), out])
    c_spec = 0.04 * (1 - m[:, None]) + m[:, None] * base
    power = 2 / r**4 - 2
    if model == "phong":
        refl = 2 * l[:, 2:3] * np.array([0, 0, 1.0]) - l
        lobe = (power / 4 + 2) / (2 * np.pi) * np.clip(np.sum(refl * v, 1), 0, 1) ** (power / 4)
    else:
        h = (v + l) / np.linalg.norm(v + l, axis=1, keepdims=True)
        lobe = (power + 8) / (8 * np.pi) * h[:, 2] ** power
    want = (1 - c_spec) * (1 - m[:, None]) * base / np.pi + c_spec * lobe[:, None]
    assert rel(out.numpy().astype(np.float64), want) <= 1e-4


def test_normalized_phong_lobe_reflects_all_light_head_on():
    """Lafortune & Willems 1994: with the (a + 2) / (2 pi) factor the Phong BRDF's albedo under
    light along n is 1."""

    @wp.kernel(enable_backward=False)
    def lobe(cos: wp.array(dtype=float), power: float, out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = kb.Fs_Phong(power, cos[i])

    theta = np.linspace(0, np.pi / 2, 20001)
    for power in (1.0, 10.0, 100.0):
        out = wp.zeros(len(theta), dtype=float)
        wp.launch(lobe, dim=len(theta), inputs=[wp.array(np.cos(theta).astype(np.float32)), power, out])
        integral = np.trapezoid(out.numpy() * np.cos(theta) * 2 * np.pi * np.sin(theta), theta)
        assert abs(integral - 1) <= 1e-3, (power, integral)


def test_blinn_phong_ndf_is_normalized():
    """Projected-area normalization: the integral of D(h) n.h over the hemisphere is 1."""
    theta = np.linspace(0, np.pi / 2, 20001)
    for roughness in (0.3, 0.5, 0.8):
        nh = np.cos(theta).astype(np.float32)
        out = wp.zeros((len(theta), 6), dtype=float)
        ones = wp.array(np.ones(len(theta), np.float32))
        wp.launch(eval_scalar_terms, dim=len(theta), inputs=[ones, ones, ones, wp.array(nh), wp.array(np.full(len(theta), roughness, np.float32)), out])
        d = out.numpy()[:, 1].astype(np.float64)
        integral = np.trapezoid(d * np.cos(theta) * 2 * np.pi * np.sin(theta), theta)
        assert abs(integral - 1) <= 1e-3


def test_unknown_rungs_are_rejected():
    with pytest.raises(pw.InputError, match="geometry"):
        pw.BRDF(geometry="smith_magic")
    with pytest.raises(pw.InputError, match="energy"):
        pw.BRDF(energy="triple")
    with pytest.raises(pw.InputTypeError, match="BRDF"):
        pw.render(pw.Scene(), head_on_camera(), brdf="ggx")


@pytest.mark.parametrize("rungs", list(itertools.product(("lambert", "burley"), ("ggx", "blinn_phong"),
                                                         ("implicit", "schlick_ggx", "smith_separable", "smith_correlated",
                                                          "smith_correlated_fast"), ("none", "schlick", "spherical_gaussian", "exact")))[::5])
def test_every_rung_combination_renders_finite(rungs):
    import trimesh

    diffuse, distribution, geometry, fresnel_model = rungs
    scene = pw.Scene()
    for i, (m, r) in enumerate(((0.0, 0.0), (0.5, 0.3), (1.0, 0.7))):
        scene.add_mesh(trimesh.creation.icosphere(subdivisions=2), pw.Material(base_color=(0.9, 0.6, 0.2), metallic=m, roughness=r),
                       transform=np.diag([1.0, 1.0, 1.0, 1.0]) + np.pad(np.array([[0, 0, 0, 2.5 * (i - 1)]]), ((0, 3), (0, 0))))
    scene.add_light(pw.PointLight(position=(2, 3, 4), intensity=40.0))
    coupling = ("albedo", "fresnel", "none")[len(fresnel_model) % 3]
    mix = ("gltf", "f0")[len(geometry) % 2]
    brdf = pw.BRDF(diffuse=diffuse, distribution=distribution, geometry=geometry, fresnel=fresnel_model, coupling=coupling,
                   metallic_mix=mix)
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 8), target=(0, 0, 0)), size=(48, 24), brdf=brdf)
    assert frame.rgb.max() > 0
    text = pw.explain(scene, brdf=brdf)
    assert f"{diffuse} diffuse" in text and f"{geometry} geometry" in text and f"{fresnel_model} Fresnel" in text
    assert f"{coupling} coupling" in text


def test_default_brdf_is_karis_terms_with_the_energy_conserving_coupling():
    assert pw.BRDF() == pw.BRDF(diffuse="lambert", distribution="ggx", geometry="schlick_ggx", fresnel="schlick", energy="single",
                                coupling="albedo", metallic_mix="gltf")


def test_presets_select_the_documented_rungs():
    from pbrwarp.brdf import PRESETS

    assert PRESETS["balanced"] == pw.BRDF()
    assert PRESETS["fast"] == pw.BRDF(distribution="blinn_phong", geometry="implicit", fresnel="spherical_gaussian",
                                      coupling="fresnel")
    assert PRESETS["accurate"] == pw.BRDF(diffuse="burley", geometry="smith_correlated")
    assert PRESETS["reference"] == pw.BRDF(diffuse="burley", geometry="smith_correlated", fresnel="exact", energy="multiscatter")
    import trimesh

    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=1))
    scene.add_light(pw.PointLight(position=(1, 2, 3), intensity=5.0))
    assert "implicit geometry" in pw.explain(scene, quality="fast")
    assert "exact Fresnel" in pw.explain(scene, quality="reference")
    assert "exact Fresnel" in pw.explain(scene, quality="fast", brdf=pw.BRDF(fresnel="exact"))  # overrides win
    with pytest.raises(pw.InputError, match="quality"):
        pw.render(scene, quality="ultra")


def test_more_exact_rungs_are_closer_to_the_reference_at_grazing_angles():
    """On a glossy plane seen at a shallow angle, where Fresnel and G matter most: no geometry
    term (G = n.l n.v) is farther from the exact height-correlated Smith than Schlick-GGX, which is
    farther than exact separable Smith; no Fresnel is farther from exact Fresnel than Schlick."""
    import trimesh

    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.box(extents=(40.0, 0.1, 40.0)), pw.Material(base_color=(0.3, 0.3, 0.35), roughness=0.25))
    scene.add_light(pw.DirectionalLight(direction=(0.0, -0.2, 1.0), intensity=5.0))
    cam = pw.Camera.look_at(eye=(0.0, 0.6, 10.0), target=(0.0, 0.0, -10.0), fov_y=40.0)

    def error(brdf, reference):
        a = render_checked(scene, cam, size=(64, 48), brdf=brdf).rgb
        b = render_checked(scene, cam, size=(64, 48), brdf=reference).rgb
        return np.sqrt(np.mean((a - b) ** 2 / (b**2 + 0.01)))

    exact_smith = pw.BRDF(geometry="smith_correlated")
    errors = {g: error(pw.BRDF(geometry=g), exact_smith) for g in ("implicit", "schlick_ggx", "smith_separable")}
    assert errors["implicit"] >= errors["schlick_ggx"] >= errors["smith_separable"] > 0
    exact_fresnel = pw.BRDF(fresnel="exact")
    assert error(pw.BRDF(fresnel="none"), exact_fresnel) >= error(pw.BRDF(fresnel="schlick"), exact_fresnel)
