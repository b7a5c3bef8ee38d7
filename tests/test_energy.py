"""The weak white furnace test (Heitz 2014): a white surface's directional albedo
a(v) = integral of f(l, v) n.l over the hemisphere never exceeds 1.

The integral is estimated in float64 by Monte Carlo with a fixed seed, sampling l from an equal
mixture of a cosine-weighted distribution and GGX half-vector sampling (Walter et al. 2007),
weighted by the mixture pdf; the BRDF values come from the kernel.
"""

import math

import numpy as np
import warp as wp

from pbrwarp.kernels import brdf as kb

SAMPLES = 60_000
ROUGHNESS = (0.05, 0.1, 0.25, 0.5, 0.75, 1.0)
COS_VIEW = (1.0, 0.7, 0.3, 0.1, 0.02)


# the default model, every lobe compiled in
default_brdf = kb.brdf_for(True, True)


def white_evaluator(brdf):
    @wp.kernel(enable_backward=False, module="unique")
    def eval_white(v: wp.vec3, l: wp.array(dtype=wp.vec3), metallic: float, roughness: float, out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = brdf(wp.vec3(0.0, 0.0, 1.0), v, l[i], wp.vec3(1.0), metallic, roughness, 1.0)[0]

    return eval_white


eval_white = white_evaluator(default_brdf)


def dielectric_evaluator(brdf, f0_dielectric):
    """A white surface's BRDF (red channel) with the dielectric f0 ``f0_dielectric`` =
    ((ior - 1) / (ior + 1))^2 specular_color, unclamped."""
    @wp.kernel(enable_backward=False, module="unique")
    def eval_white(v: wp.vec3, l: wp.array(dtype=wp.vec3), metallic: float, roughness: float, out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = brdf(wp.vec3(0.0, 0.0, 1.0), v, l[i], wp.vec3(1.0), metallic, roughness, 1.0, wp.vec3(0.0),
                      wp.vec3(0.0), wp.vec3(f0_dielectric))[0]

    return eval_white


def directional_albedo(cos_view, metallic, roughness, seed=7, kernel=eval_white):
    """(estimate, standard error) of a(v) for a white surface."""
    rng = np.random.default_rng(seed)
    v = np.array([math.sqrt(1 - cos_view**2), 0.0, cos_view])
    a2 = max(roughness**4, 1e-7)
    u1, u2, pick = rng.random(SAMPLES), rng.random(SAMPLES), rng.random(SAMPLES) < 0.5
    phi = 2 * np.pi * u2
    r = np.sqrt(u1)
    l_cos = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], -1)
    cos_h = np.sqrt((1 - u1) / (1 + (a2 - 1) * u1))
    sin_h = np.sqrt(1 - cos_h**2)
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], -1)
    l_ggx = 2 * (h @ v)[:, None] * h - v
    l = np.where(pick[:, None], l_cos, l_ggx)
    half = (v + l) / np.linalg.norm(v + l, axis=-1, keepdims=True)
    n_dot_h, v_dot_h, n_dot_l = half[:, 2], np.maximum(half @ v, 1e-300), l[:, 2]
    d = a2 / (np.pi * (n_dot_h**2 * (a2 - 1) + 1) ** 2)
    pdf = 0.5 * np.maximum(n_dot_l, 0) / np.pi + 0.5 * d * n_dot_h / (4 * v_dot_h)
    out = wp.empty(SAMPLES, dtype=float)
    wp.launch(kernel, dim=SAMPLES, inputs=[wp.vec3(*v), wp.array(l.astype(np.float32), dtype=wp.vec3), metallic, roughness, out])
    w = np.where(n_dot_l > 0, out.numpy().astype(np.float64) * n_dot_l / np.maximum(pdf, 1e-300), 0.0)
    return w.mean(), w.std() / math.sqrt(SAMPLES)


def furnace_excess(metallics):
    """Largest a(v) - (1 + 4 standard errors + 1e-3) over the grid, with where it happens."""
    worst = (-np.inf, None)
    for m in metallics:
        for r in ROUGHNESS:
            for c in COS_VIEW:
                est, err = directional_albedo(c, m, r)
                excess = est - (1.0 + 4 * err + 1e-3)
                if excess > worst[0]:
                    worst = (excess, dict(metallic=m, roughness=r, cos_view=c, albedo=est))
    return worst


@wp.kernel(enable_backward=False)
def eval_lambert(v: wp.vec3, l: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = default_brdf(wp.vec3(0.0, 0.0, 1.0), v, l[i], wp.vec3(1.0), 0.0, 0.5, 0.0)


def test_lambert_alone_integrates_to_one():
    """The estimator itself: with specular 0 a white Lambert surface has albedo exactly 1."""
    albedos = []
    for c in (1.0, 0.3, 0.02):
        v = np.array([math.sqrt(1 - c**2), 0.0, c])
        u1, u2 = np.random.default_rng(3).random((2, SAMPLES))
        r, phi = np.sqrt(u1), 2 * np.pi * u2
        l = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], -1)
        out = wp.empty(SAMPLES, dtype=wp.vec3)
        wp.launch(eval_lambert, dim=SAMPLES, inputs=[wp.vec3(*v), wp.array(l.astype(np.float32), dtype=wp.vec3), out])
        albedos.append(np.mean(out.numpy()[:, 0] * np.pi))  # f cos / (cos/pi)
    np.testing.assert_allclose(albedos, 1.0, rtol=1e-6)


def test_white_metal_furnace():
    """Metals are the specular lobe alone: single scattering loses energy, never creates it."""
    excess, where = furnace_excess([1.0])
    assert excess <= 0.0, where


def test_white_dielectric_and_mixed_furnace():
    """The default albedo coupling gives the diffuse lobe only the light the specular lobe left."""
    excess, where = furnace_excess([0.0, 0.5])
    assert excess <= 0.0, where


def test_default_furnace_over_ior_and_specular_colour():
    """glTF's mix never reflects more than it receives, whatever the IOR (1, glass, diamond-like
    2.5, and 0, KHR_materials_ior's infinite IOR) and specular colour, including colours above 1,
    whose product with the IOR's f0 KHR_materials_specular clamps to 1 (an unclamped f0 of 3
    would reflect up to three times the light), with single and multiple scattering (which
    restores energy only up to the albedo table's error, as the tests below allow it)."""
    for energy, table_error in (("single", 1e-3), ("multiscatter", 0.01)):
        brdf = kb.brdf_for(True, True, energy=energy)
        for ior, specular_color in ((1.0, 1.0), (2.5, 1.0), (0.0, 1.0), (1.5, 2.0), (1.5, 75.0), (2.5, 40.0)):
            kernel = dielectric_evaluator(brdf, ((ior - 1) / (ior + 1)) ** 2 * specular_color)
            for metallic in (0.0, 0.5):
                for r in (0.05, 0.25, 0.5, 1.0):
                    for c in (1.0, 0.3, 0.02):
                        est, err = directional_albedo(c, metallic, r, kernel=kernel)
                        assert est <= 1.0 + 4 * err + table_error, (energy, ior, specular_color, metallic, r, c, est)


def test_albedo_coupling_conserves_white_dielectric_energy():
    """With Lambert and the albedo coupling a white dielectric reflects exactly what it receives,
    a(v) = E(v) + (1 - E(v)) = 1, with single or multiple scattering, up to the albedo table's
    error (MC-integrated 32 x 32 table, interpolated) and the test's own Monte Carlo error."""
    for energy in ("single", "multiscatter"):
        kernel = white_evaluator(kb.brdf_for(True, True, energy=energy))
        for r in ROUGHNESS:
            for c in COS_VIEW:
                est, err = directional_albedo(c, 0.0, r, kernel=kernel)
                assert abs(est - 1.0) <= 0.01 + 4 * err, (energy, r, c, est)


def coupled_evaluator(scaled_brdf, diffuse_share_scale, brdf):
    @wp.kernel(enable_backward=False, module="unique")
    def evaluate(v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3), base: wp.array(dtype=wp.vec3),
                 params: wp.array(dtype=wp.vec3), f0_dielectric: wp.array(dtype=wp.vec3),
                 given: wp.array(dtype=wp.vec3), whole: wp.array(dtype=wp.vec3), scales: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        n = wp.vec3(0.0, 0.0, 1.0)
        p = params[i]
        scale = diffuse_share_scale(base[i], p[0], p[1], p[2], f0_dielectric[i])
        scales[i] = scale
        given[i] = scaled_brdf(n, v[i], l[i], base[i], p[0], p[1], p[2], wp.vec3(0.0), wp.vec3(0.0), f0_dielectric[i],
                               scale)
        whole[i] = brdf(n, v[i], l[i], base[i], p[0], p[1], p[2], wp.vec3(0.0), wp.vec3(0.0), f0_dielectric[i])

    return evaluate


def test_the_albedo_coupling_normalization_given_once_is_the_brdf_itself():
    """Renders compute the coupling's 1 / (1 - E_avg) once per material (albedo_coupled_brdf_for):
    given it, the BRDF is brdf_for's bit for bit, for every material; it is 1 where the specular
    lobe under which the diffuse lobe lies reflects nothing (f0 = f90 = 0: specular 0, and in the
    "f0" mix not metallic) and above 1 elsewhere."""
    rng = np.random.default_rng(5)
    count = 2000

    def unit(rows):
        return (rows / np.linalg.norm(rows, axis=1, keepdims=True)).astype(np.float32)

    v = unit(rng.normal(size=(count, 3)) * [1, 1, 0] + [0, 0, 1] * rng.uniform(0.01, 1, (count, 1)))
    l = unit(rng.normal(size=(count, 3)) * [1, 1, 0] + [0, 0, 1] * rng.uniform(0.01, 1, (count, 1)))
    base = rng.uniform(0, 1, (count, 3)).astype(np.float32)
    params = np.column_stack([rng.choice([0.0, 0.3, 1.0], count), rng.uniform(0, 1, count),
                              rng.choice([0.0, 0.5, 1.0], count)]).astype(np.float32)  # metallic, roughness, specular
    f0_dielectric = (rng.choice([0.0, 0.04, 0.17, 1.0], (count, 1)) * rng.uniform(0, 2, (count, 3))).astype(np.float32)
    for rungs in ({}, {"energy": "multiscatter"}, {"geometry": "smith_correlated", "diffuse": "burley"},
                  {"metallic_mix": "f0"}, {"metallic_mix": "f0", "energy": "multiscatter"}):
        scaled_brdf, diffuse_share_scale = kb.albedo_coupled_brdf_for(True, True, **rungs)
        out = [wp.empty(count, dtype=wp.vec3) for _ in range(3)]
        wp.launch(coupled_evaluator(scaled_brdf, diffuse_share_scale, kb.brdf_for(True, True, **rungs)), dim=count,
                  inputs=[wp.array(a, dtype=wp.vec3) for a in (v, l, base, params, f0_dielectric)], outputs=out)
        given, whole, scales = (a.numpy() for a in out)
        assert np.array_equal(given, whole), rungs
        # the lobe the diffuse one is coupled to: the dielectric's in glTF's mix, the mixed one's else
        reflects_nothing = (params[:, 2] == 0) & ((params[:, 0] == 0) | (rungs.get("metallic_mix") != "f0"))
        assert np.all(scales[reflects_nothing] == 1.0) and np.all(scales[~reflects_nothing] > 1.0), rungs
    for other in ({"coupling": "fresnel"}, {"coupling": "none"}, {"model": "phong"}):
        assert kb.albedo_coupled_brdf_for(True, True, **other) is None
    assert kb.albedo_coupled_brdf_for(False, True) is None and kb.albedo_coupled_brdf_for(True, False) is None


def test_diffuse_weight_one_minus_fresnel_creates_energy_at_grazing_views():
    """Why the default coupling is not the diffuse weight 1 - F(v.h) with F Schlick's Fresnel of
    the f0 mix (the kD = 1 - kS of LearnOpenGL's PBR tutorial, after Karis 2013): it ignores the
    light the specular lobe took at other half vectors, so smooth white dielectrics seen at grazing
    views reflect more than they receive."""
    fresnel_weighted = white_evaluator(kb.brdf_for(True, True, coupling="fresnel"))
    est, err = directional_albedo(0.1, 0.0, 0.1, kernel=fresnel_weighted)
    assert est > 1.0 + 4 * err + 1e-3


def test_multiscatter_compensation_brings_white_metal_to_one():
    """With energy compensation, a white metal (f0 = 1) reflects all the light it receives: the
    single-scattering loss (albedo down to ~0.3 for rough metal) is restored, up to the 32 x 32
    table's interpolation and Monte Carlo error."""
    compensated = white_evaluator(kb.brdf_for(True, True, geometry="smith_correlated", energy="multiscatter"))
    single = white_evaluator(kb.brdf_for(True, True, geometry="smith_correlated"))
    for roughness in (0.25, 0.5, 0.75, 1.0):
        for cos_view in (1.0, 0.7, 0.3):
            est, err = directional_albedo(cos_view, 1.0, roughness, kernel=compensated)
            assert abs(est - 1.0) <= 0.03 + 4 * err, (roughness, cos_view, est)
    lossy, _ = directional_albedo(1.0, 1.0, 1.0, kernel=single)
    assert lossy < 0.8  # what the compensation restored


def test_albedo_integration_is_kept_on_disk_and_recomputed_where_the_copy_is_damaged(tmp_path):
    """integrated_albedo: the banded launches give the numbers one launch over the whole table
    gives; the copy it keeps is loaded back unchanged; a damaged copy (not an array, cut short,
    of another shape, holding NaN) is recomputed and replaced; a directory it cannot write to
    only costs the computation."""
    from pbrwarp.kernels.energy import (ALBEDO_SAMPLES, ALBEDO_TABLE_SIZE, FRESNEL_SHAPES, albedo_kernel,
                                        integrated_albedo)

    def integrate(cache_dir=tmp_path):
        return integrated_albedo("ggx", "schlick_ggx", "schlick", cache_dir=str(cache_dir))

    size = ALBEDO_TABLE_SIZE
    whole = wp.zeros((size, size, 2), dtype=float, device="cpu")
    wp.launch(albedo_kernel("ggx", "schlick_ggx"), dim=(size, size), device="cpu",
              inputs=[ALBEDO_SAMPLES, FRESNEL_SHAPES["schlick"], 0, whole])
    computed = integrate()
    assert np.array_equal(computed, whole.numpy())
    (kept,) = tmp_path.glob("pbrwarp_albedo_*.npy")
    assert not list(tmp_path.glob("*.tmp"))
    assert np.array_equal(integrate(), computed)
    valid = kept.read_bytes()
    nan_table = computed.copy()
    nan_table[3, 4, 1] = np.nan
    for damage in (b"not an array", valid[: len(valid) // 2]):
        kept.write_bytes(damage)
        assert np.array_equal(integrate(), computed)
        assert kept.read_bytes() == valid
    for wrong in (computed[:-1], nan_table):
        np.save(kept, wrong)
        assert np.array_equal(integrate(), computed)
        assert kept.read_bytes() == valid
    assert np.array_equal(integrate(cache_dir=tmp_path / "missing" / "directory"), computed)
