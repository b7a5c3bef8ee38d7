"""Each BRDF term and the whole BRDF against the float64 reference, on thousands of random inputs."""

import numpy as np
import pytest
import warp as wp

from pbrwarp.kernels import brdf as kb
from pbrwarp.kernels import microfacet as km

import reference as ref

N = 4096


# the default model (glTF's mix) and the "f0" mix of Karis 2013, every lobe compiled in
default_brdf = kb.brdf_for(True, True)
gltf_fresnel_weighted_brdf = kb.brdf_for(True, True, coupling="fresnel")
f0_mix_brdf = kb.brdf_for(True, True, metallic_mix="f0")
fresnel_weighted_brdf = kb.brdf_for(True, True, coupling="fresnel", metallic_mix="f0")
OUTPUTS = 7


@wp.kernel(enable_backward=False)
def eval_terms(
    n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
    base: wp.array(dtype=wp.vec3), metallic: wp.array(dtype=float), roughness: wp.array(dtype=float),
    specular: wp.array(dtype=float), n_dot_h: wp.array(dtype=float), sin_sq: wp.array(dtype=float),
    f0_dielectric: wp.array(dtype=wp.vec3),
    out_d: wp.array(dtype=float), out_g: wp.array(dtype=float), out_f: wp.array(dtype=wp.vec3),
    out_brdf: wp.array(dtype=wp.vec3), out_fresnel_weighted: wp.array(dtype=wp.vec3),
    out_gltf: wp.array(dtype=wp.vec3), out_gltf_fresnel_weighted: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    h = wp.normalize(v[i] + l[i])
    r = roughness[i]
    out_d[i] = km.D_GGX(r * r, n_dot_h[i], sin_sq[i])
    out_g[i] = km.V_SmithSchlickGGX(wp.dot(n[i], v[i]), wp.dot(n[i], l[i]), r)
    f0 = kb.specular_f0(base[i], metallic[i], specular[i], f0_dielectric[i])
    out_f[i] = kb.F_Schlick(f0, kb.specular_f90(metallic[i], specular[i]), wp.dot(v[i], h))
    out_brdf[i] = f0_mix_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i], specular[i], wp.vec3(0.0),
                              wp.vec3(0.0), f0_dielectric[i])
    out_fresnel_weighted[i] = fresnel_weighted_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i],
                                                    specular[i], wp.vec3(0.0), wp.vec3(0.0), f0_dielectric[i])
    out_gltf[i] = default_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i], specular[i], wp.vec3(0.0),
                               wp.vec3(0.0), f0_dielectric[i])
    out_gltf_fresnel_weighted[i] = gltf_fresnel_weighted_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i],
                                                              specular[i], wp.vec3(0.0), wp.vec3(0.0),
                                                              f0_dielectric[i])


def launch_terms(inputs: dict, count: int):
    """eval_terms on float32 copies of ``inputs`` (eval_terms' input names); its OUTPUTS as float64."""
    names = ("n", "v", "l", "base", "metallic", "roughness", "specular", "n_dot_h", "sin_sq", "f0_dielectric")
    dev = [wp.array(np.asarray(inputs[k], np.float32), dtype=wp.vec3 if np.ndim(inputs[k]) == 2 else float)
           for k in names]
    outs = [wp.zeros(count, dtype=float), wp.zeros(count, dtype=float)]
    outs += [wp.zeros(count, dtype=wp.vec3) for _ in range(OUTPUTS - 2)]
    wp.launch(eval_terms, dim=count, inputs=dev + outs)
    return [o.numpy().astype(np.float64) for o in outs]


def random_hemisphere(rng, n, count, min_cos):
    """Unit vectors with n.x >= min_cos around the normals n."""
    out = np.empty_like(n)
    filled = np.zeros(count, bool)
    while not filled.all():
        cand = ref.normalize(rng.normal(size=(count, 3)))
        ok = (np.sum(cand * n, -1) >= min_cos) & ~filled
        out[ok] = cand[ok]
        filled |= ok
    return out


@pytest.fixture(scope="module")
def evaluated():
    rng = np.random.default_rng(1234)
    n = ref.normalize(rng.normal(size=(N, 3)))
    v = random_hemisphere(rng, n, N, 0.05)
    l = random_hemisphere(rng, n, N, 0.05)
    base = rng.uniform(0.0, 1.0, (N, 3))
    metallic = rng.uniform(0, 1, N)
    # Well-conditioned: float32 rounding of h (~1e-7 rad) perturbs D by up to ~2e-7 / alpha
    # relatively, so roughness >= 0.3 keeps the whole BRDF within 1e-5 (low roughness is
    # checked below with the tolerance its conditioning allows).
    roughness = rng.uniform(0.3, 1.0, N)
    specular = rng.uniform(0, 1, N)
    # KHR_materials_ior's range (1 to diamond's 2.4 and beyond, and 0 for an infinite IOR) and
    # specular colours above 1, which the dielectric's f0 clamps
    ior = np.where(rng.random(N) < 0.05, 0.0, rng.uniform(1.0, 3.0, N))
    specular_color = rng.uniform(0.0, 2.5, (N, 3)) * np.where(rng.random((N, 1)) < 0.1, 12.0, 1.0)
    f0_dielectric = ((ior - 1) / (ior + 1))[:, None] ** 2 * specular_color
    h = ref.normalize(v + l)
    n_dot_h = np.sum(n * h, -1)
    sin_sq = np.sum(np.cross(n, h) ** 2, -1)
    arrays = dict(n=n, v=v, l=l, base=base, metallic=metallic, roughness=roughness, specular=specular,
                  n_dot_h=n_dot_h, sin_sq=sin_sq, f0_dielectric=f0_dielectric)
    outs = launch_terms(arrays, N)
    # the reference sees exactly the float32 inputs the kernel saw
    inputs = {k: a.astype(np.float32).astype(np.float64) for k, a in arrays.items()}
    inputs["ior"], inputs["specular_color"] = ior, specular_color
    return inputs, outs


def rel_err(got, want):
    return np.max(np.abs(got - want) / np.maximum(np.abs(want), 1e-30))


@wp.kernel(enable_backward=False)
def alphas_of(roughness: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = km.alpha_from_roughness(roughness[i])


def test_alpha_from_roughness_is_roughness_squared_in_kernels_and_host_code():
    """GGX alpha = roughness^2 (Burley 2012): in a kernel the float32 square, correctly rounded
    (the float64 product of two float32 values is exact); called from Python, the float64 square
    that host code (kernels/prefilter.py) has always computed."""
    roughness = np.concatenate([[0.0, 1e-20, 1e-4, 0.05, 0.5, 1.0], np.random.default_rng(7).uniform(0, 1, 1000)])
    r32 = roughness.astype(np.float32)
    out = wp.zeros(len(r32), dtype=float, device="cpu")
    wp.launch(alphas_of, dim=len(r32), inputs=[wp.array(r32, dtype=float, device="cpu"), out], device="cpu")
    np.testing.assert_array_equal(out.numpy(), (r32.astype(np.float64) ** 2).astype(np.float32))
    for r in (0.0, 0.1, 1.0 / 3.0, 0.7, 1.0):
        alpha = km.alpha_from_roughness(r)
        assert type(alpha) is float and alpha == r * r


def test_d_ggx_matches_reference(evaluated):
    x, (d, *_) = evaluated
    want = ref.d_ggx(x["n_dot_h"], x["roughness"] ** 2)
    assert rel_err(d, want) <= 1e-5


def test_visibility_smith_schlick_ggx_matches_reference(evaluated):
    """V = G / (4 n.l n.v), the reference computing G and dividing."""
    x, (_, g, *_) = evaluated
    nv, nl = np.sum(x["n"] * x["v"], -1), np.sum(x["n"] * x["l"], -1)
    want = ref.g_schlick_ggx(nv, nl, x["roughness"]) / (4 * nl * nv)
    assert rel_err(g, want) <= 1e-5


def test_f_schlick_matches_reference(evaluated):
    x, (_, _, f, *_) = evaluated
    h = ref.normalize(x["v"] + x["l"])
    m, s = x["metallic"][:, None], x["specular"][:, None]
    f0_d = ref.dielectric_f0(x["ior"], x["specular_color"], x["specular"])
    want = ref.f_schlick((1 - m) * f0_d + m * x["base"], (1 - m) * s + m, np.sum(x["v"] * h, -1))
    assert rel_err(f, want) <= 1e-5


def test_whole_fresnel_weighted_brdf_matches_reference(evaluated):
    """The "f0" mix with the 1 - F(v.h) coupling: the real-time model of Karis 2013 exactly, with
    the dielectric's f0 from the IOR and specular colour (KHR_materials_ior, _specular)."""
    x, (_, _, _, _, f, _, _) = evaluated
    f0_d = ref.dielectric_f0(x["ior"], x["specular_color"], x["specular"])
    want = ref.brdf(x["n"], x["v"], x["l"], x["base"], x["metallic"], x["roughness"], x["specular"], f0_d=f0_d)
    assert rel_err(f, want) <= 1e-5


def test_gltf_mix_with_fresnel_coupling_is_the_specs_brdf(evaluated):
    """glTF 2.0 Appendix B with KHR_materials_ior and _specular, exactly as the spec writes it:
    mix(dielectric, metal, metallic), the diffuse lobe weighted by 1 - max_value(F_dielectric)."""
    x, (*_, f) = evaluated
    want = ref.gltf_brdf(x["n"], x["v"], x["l"], x["base"], x["metallic"], x["roughness"], x["specular"], x["ior"],
                         x["specular_color"])
    assert rel_err(f, want) <= 1e-5


def table_share(tables):
    """The albedo coupling (1 - E(v))(1 - E(l)) / (1 - E_avg) in float64, E = f0 (E1 - Ew) + f90 Ew
    read from ``tables`` (rows n.v = (i + 0.5) / size, bilinear, clamped at the edges)."""
    size = tables.size
    albedo = np.array(tables.albedo).reshape(size, size, 2)
    means = np.array(tables.averages).reshape(4, size)

    def bilinear(grid, x, y):
        x = np.clip(x, 0, grid.shape[0] - 1)
        y = np.clip(y, 0, grid.shape[1] - 1)
        i, j = np.minimum(x.astype(int), grid.shape[0] - 2), np.minimum(y.astype(int), grid.shape[1] - 2)
        fx, fy = (x - i)[:, None], (y - j)[:, None]
        return ((grid[i, j] * (1 - fx) + grid[i + 1, j] * fx) * (1 - fy)
                + (grid[i, j + 1] * (1 - fx) + grid[i + 1, j + 1] * fx) * fy)

    def lobe(f0, f90, mu, roughness):
        e = bilinear(albedo, mu * size - 0.5, roughness * (size - 1))
        return f0 * (e[:, :1] - e[:, 1:]) + f90 * e[:, 1:]

    def share(f0, f90, nv, nl, roughness):
        m = bilinear(means.T[None].repeat(2, 0), np.zeros_like(roughness), roughness * (size - 1))
        rest = 1 - (f0 * m[:, :1] + f90 * m[:, 1:2])
        return (1 - lobe(f0, f90, np.maximum(nv, 1e-4), roughness)) * (1 - lobe(f0, f90, nl, roughness)) / rest

    return share


def test_whole_f0_mix_brdf_matches_reference(evaluated):
    """The "f0" mix: Karis 2013's terms with the albedo coupling of the diffuse lobe to the mixed
    specular lobe, per channel."""
    from pbrwarp.kernels.energy import albedo_tables

    x, (_, _, _, f, _, _, _) = evaluated
    share = table_share(albedo_tables("ggx", "schlick_ggx", "schlick"))
    f0_d = ref.dielectric_f0(x["ior"], x["specular_color"], x["specular"])
    want = ref.brdf(x["n"], x["v"], x["l"], x["base"], x["metallic"], x["roughness"], x["specular"], share, f0_d)
    assert rel_err(f, want) <= 1e-5


def test_whole_default_brdf_matches_reference(evaluated):
    """The default: glTF's mix, its dielectric's diffuse lobe coupled by the albedo of the
    dielectric's specular layer at its largest channel (achromatic)."""
    from pbrwarp.kernels.energy import albedo_tables

    x, (_, _, _, _, _, f, _) = evaluated
    share = table_share(albedo_tables("ggx", "schlick_ggx", "schlick"))
    want = ref.gltf_brdf(x["n"], x["v"], x["l"], x["base"], x["metallic"], x["roughness"], x["specular"], x["ior"],
                         x["specular_color"], share)
    assert rel_err(f, want) <= 1e-5


def test_gltf_mix_gives_the_diffuse_lobe_an_achromatic_share(evaluated):
    """The tint the "f0" mix gives partly metallic materials: with metallic = 0.5 and a saturated
    base colour, the diffuse light's chromaticity is the base colour's in the glTF mix (its
    share is a scalar), while the f0 mix shifts it (the mixed f0 is chromatic). Measured on the
    diffuse lobe alone: the BRDF minus its specular lobe (specular = 1, white specular colour)."""
    x, _ = evaluated
    k = 512
    base = np.tile([1.0, 0.2, 0.2], (k, 1))
    inputs = {key: x[key][:k] for key in ("n", "v", "l", "roughness", "n_dot_h", "sin_sq")}
    inputs.update(base=base, metallic=np.full(k, 0.5), specular=np.ones(k), f0_dielectric=np.full((k, 3), 0.04))
    _, _, fresnel, f0_mix, _, gltf, _ = launch_terms(inputs, k)
    h = ref.normalize(inputs["v"] + inputs["l"])
    nv, nl = np.sum(inputs["n"] * inputs["v"], -1), np.sum(inputs["n"] * inputs["l"], -1)
    r = inputs["roughness"]
    specular_brdf = (ref.d_ggx(np.sum(inputs["n"] * h, -1), r**2) * ref.g_schlick_ggx(nv, nl, r) / (4 * nl * nv))
    diffuse_gltf = gltf - fresnel * specular_brdf[:, None]  # both mixes share the specular lobe (Schlick)
    diffuse_f0 = f0_mix - fresnel * specular_brdf[:, None]
    ratio_gltf = diffuse_gltf / base
    # up to float32 rounding of the whole BRDF, of which the specular lobe was subtracted
    assert np.all(np.abs(ratio_gltf - ratio_gltf[:, :1]) <= 4e-6 * np.max(gltf / base, axis=1, keepdims=True))
    ratio_f0 = diffuse_f0 / base
    assert np.max(np.abs(ratio_f0[:, 1] / ratio_f0[:, 0] - 1)) > 0.05  # the f0 mix's tint, for contrast


@pytest.mark.parametrize("roughness", [0.0, 1 / 31, 0.5, 1.0])
def test_albedo_table_matches_float64_integration(roughness):
    """The Warp-integrated table of E1 and Ew (8192 Hammersley samples per cell) against float64 Monte Carlo
    of the formulas, at table nodes from head-on to grazing."""
    from pbrwarp.kernels.energy import albedo_tables

    tables = albedo_tables("ggx", "schlick_ggx", "schlick")
    size = tables.size
    albedo = np.array(tables.albedo).reshape(size, size, 2)
    column = round(roughness * (size - 1))
    for row in (0, 3, size // 2, size - 1):
        e1, ew, err1, errw = ref.ggx_lobe_albedo((row + 0.5) / size, column / (size - 1))
        assert abs(albedo[row, column, 0] - e1) <= 4 * err1 + 0.002 * e1, (row, albedo[row, column], e1)
        assert abs(albedo[row, column, 1] - ew) <= 4 * errw + 0.002 * e1, (row, albedo[row, column], ew)


def test_specular_zero_is_pure_lambert(evaluated):
    """specular = 0 removes the dielectric's specular layer, whatever the IOR and specular colour."""
    x, _ = evaluated
    k = len(x["n"])
    inputs = dict(x, metallic=np.zeros(k), specular=np.zeros(k))
    _, _, fresnel, f0_mix, f0_fresnel, gltf, gltf_fresnel = launch_terms(inputs, k)
    want = x["base"] / np.pi
    for out in (f0_mix, f0_fresnel, gltf, gltf_fresnel):
        assert rel_err(out, want) <= 1e-6
    assert np.all(fresnel == 0.0), "Fresnel must vanish for specular = 0, metallic = 0"


def test_light_below_surface_gives_zero():
    inputs = dict(n=[[0, 0, 1]], v=[[0, 0.6, 0.8]], l=[[0, 0.6, -0.8]], base=[[1, 1, 1]], metallic=[0.5],
                  roughness=[0.5], specular=[0.5], n_dot_h=[0.5], sin_sq=[0.5], f0_dielectric=[[0.04] * 3])
    for out in launch_terms(inputs, 1)[3:]:
        assert np.all(out == 0.0)


def test_d_ggx_low_roughness_and_peak():
    """Near-mirror roughness: D at and around the peak, from exact n.h and 1 - (n.h)^2 inputs."""
    rough = np.array([0.045, 0.05, 0.1, 0.2])
    theta = np.array([0.0, 1e-4, 1e-3, 1e-2])
    r, t = [a.ravel() for a in np.meshgrid(rough, theta)]
    k = len(r)
    nh, s2 = np.cos(t), np.sin(t) ** 2
    zeros, zeros3 = np.zeros(k), np.zeros((k, 3))
    outs = launch_terms(dict(n=zeros3, v=zeros3, l=zeros3, base=zeros3, metallic=zeros, roughness=r, specular=zeros,
                             n_dot_h=nh, sin_sq=s2, f0_dielectric=zeros3), k)
    r32 = r.astype(np.float32).astype(np.float64)
    # at the peak the reference's 1 - n.h^2 is exactly the float32 input 0; elsewhere n.h rounds
    # to 1 in float32 and only the separately passed sin^2 carries the angle
    want = r32**4 / (np.pi * (s2.astype(np.float32) + nh**2 * r32**4) ** 2)
    assert rel_err(outs[0], want) <= 1e-5


def test_dielectric_f0_above_one_is_clamped_before_the_specular_factor(evaluated):
    """KHR_materials_specular: min(f0_ior specularColor, 1) specular. A specular colour taking the
    product above 1 gives exactly the BRDF of a product of 1, in both mixes; below 1 it is not
    clamped."""
    x, _ = evaluated
    k = 256
    inputs = {key: x[key][:k] for key in ("n", "v", "l", "base", "metallic", "roughness", "specular", "n_dot_h",
                                          "sin_sq")}
    product = np.tile([3.0, 1.0, 0.5], (k, 1))
    above = launch_terms(dict(inputs, f0_dielectric=product), k)
    clamped = launch_terms(dict(inputs, f0_dielectric=np.minimum(product, 1.0)), k)
    for got, want in zip(above[2:], clamped[2:]):
        assert np.array_equal(got, want)
    lower = launch_terms(dict(inputs, f0_dielectric=np.tile([1.0, 1.0, 0.25], (k, 1))), k)
    assert not np.array_equal(lower[5], clamped[5])
