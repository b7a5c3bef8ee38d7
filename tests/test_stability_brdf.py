"""Hard cases for the BRDF: roughness -> 0, grazing and back-facing cosines, degenerate half
vectors, fractional metallic, black and white base colours, specular 0. Every value finite and
non-negative, reciprocal, and the worst float32 error against the float64 reference bounded.

Run with ``-s -k error_table`` to print the error table the README quotes.
"""

import itertools
import math

import numpy as np
import pytest
import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

from pbrwarp.kernels import brdf as kb
from pbrwarp.kernels.robust import MIN_COSINE

import reference as ref

# The minimum roughness implied by kernels/microfacet.py's floor alpha^2 = roughness^4 >= 1e-7.
MIN_ROUGHNESS = 1e-7 ** 0.25
ROUGHNESS_GRID = [0.0, 1e-8, 1e-4, MIN_ROUGHNESS, 0.045, 0.5, 1.0]
COSINE_GRID = [1.0, 0.5, 1e-3, 1e-6, 0.0, -1e-3]


# the default model (glTF's mix), every lobe compiled in
default_brdf = kb.brdf_for(True, True)


@wp.kernel(enable_backward=False)
def eval_brdf(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
              base: wp.array(dtype=wp.vec3), metallic: wp.array(dtype=float), roughness: wp.array(dtype=float),
              specular: wp.array(dtype=float), f0_dielectric: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = default_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i], specular[i], wp.vec3(0.0),
                          wp.vec3(0.0), f0_dielectric[i])


def brdf(n, v, l, base, metallic, roughness, specular, f0_dielectric=0.04):
    """Evaluate the kernel's BRDF on numpy batches (one launch); ``f0_dielectric`` is
    ((ior - 1) / (ior + 1))^2 times the specular colour."""
    count = len(v)
    vec = lambda a: wp.array(np.broadcast_to(np.asarray(a, np.float32), (count, 3)).copy(), dtype=wp.vec3)
    sca = lambda a: wp.array(np.broadcast_to(np.asarray(a, np.float32), (count,)).copy(), dtype=float)
    out = wp.zeros(count, dtype=wp.vec3)
    wp.launch(eval_brdf, dim=count, inputs=[vec(n), vec(v), vec(l), vec(base), sca(metallic), sca(roughness), sca(specular),
                                            vec(f0_dielectric), out])
    return out.numpy().astype(np.float64)


def direction(cos_theta, phi):
    s = math.sqrt(max(0.0, 1.0 - cos_theta**2))
    return (s * math.cos(phi), s * math.sin(phi), cos_theta)


def adversarial_grid():
    rows = []
    for r, cv, cl, phi, m, b, s in itertools.product(
            ROUGHNESS_GRID, COSINE_GRID, COSINE_GRID, (0.0, math.pi / 2, math.pi),
            (0.0, 0.37, 1.0), (0.0, 1.0), (0.0, 1.0)):
        rows.append((direction(cv, 0.0), direction(cl, phi), r, m, b, s))
    v, l, r, m, b, s = (np.array(c, dtype=np.float64) for c in zip(*rows))
    return v, l, r, m, b, s


def test_adversarial_grid_is_finite_non_negative_and_bounded():
    v, l, r, m, b, s = adversarial_grid()
    f = brdf((0, 0, 1), v, l, np.repeat(b[:, None], 3, 1), m, r, s)
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)
    # the largest value a punctual light can meet: the clamped GGX peak over the clamped n.v
    peak = 1.0 / (math.pi * 1e-7) * 8.0 * 8.0 / (4.0 * MIN_COSINE)
    assert f.max() <= peak
    # light below the surface contributes nothing
    assert np.all(f[l[:, 2] <= 0.0] == 0.0)


@pytest.mark.parametrize("f0_dielectric", [0.0, 1.0, 3.4e38], ids=["ior 1", "ior 0 (infinite)", "huge specular colour"])
def test_extreme_ior_and_specular_colour_on_the_adversarial_grid(f0_dielectric):
    """An IOR of 1 (no dielectric f0), KHR_materials_ior's 0 (f0 = 1) and the largest specular
    colour float32 holds (clamped to f0 = 1, so exactly the BRDF of f0 = 1): finite,
    non-negative and within the bound of the default's grid."""
    v, l, r, m, b, s = adversarial_grid()
    base = np.repeat(b[:, None], 3, 1)
    f = brdf((0, 0, 1), v, l, base, m, r, s, f0_dielectric)
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)
    assert f.max() <= 1.0 / (math.pi * 1e-7) * 8.0 * 8.0 / (4.0 * MIN_COSINE)
    if f0_dielectric > 1.0:
        assert np.array_equal(f, brdf((0, 0, 1), v, l, base, m, r, s, 1.0))


@pytest.mark.parametrize("roughness", [0.0, 1e-8, 1e-4])
def test_roughness_zero_mirror_peak_is_finite(roughness):
    """n.h = 1 exactly at roughness 0: D would be 0/0 or Inf without the alpha^2 floor."""
    v = np.array([direction(c, 0.0) for c in (1.0, 0.8, 0.3)])
    l = v * np.array([-1, -1, 1])  # the mirror direction: h = n exactly
    f = brdf((0, 0, 1), v, l, (1, 1, 1), 1.0, roughness, 1.0)
    assert np.all(np.isfinite(f)) and np.all(f > 0)
    # at the peak D = 1 / (pi alpha^2) with alpha^2 clamped to 1e-7
    d_peak = 1.0 / (math.pi * 1e-7)
    assert np.all(f[:, 0] <= d_peak * 8.0 / (4.0 * v[:, 2] ** 2) * 1.001)


@pytest.mark.parametrize("eps", [0.0, 1e-30, 1e-12, 1e-6])
def test_opposite_view_and_light_half_vector(eps):
    """v = -l (h undefined) and v ~ -l, both just above the tangent plane."""
    v = np.array([[1.0, 0.0, eps]])
    l = np.array([[-1.0, 0.0, eps]])
    f = brdf((0, 0, 1), v / np.linalg.norm(v), l / np.linalg.norm(l), (1, 1, 1), 0.5, 0.3, 1.0)
    assert np.all(np.isfinite(f)) and np.all(f >= 0)


unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda x: 1e-3 < sum(c * c for c in x) <= 1)
batch = st.lists(st.tuples(unit, unit, unit, st.floats(0, 1), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)),
                 min_size=1, max_size=64)


@settings(max_examples=40, deadline=None)
@given(batch)
def test_random_inputs_are_finite_and_non_negative(rows):
    n, v, l, b, m, r, s = (np.array(c, dtype=np.float64) for c in zip(*rows))
    n, v, l = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in (n, v, l))
    f = brdf(n, v, l, np.repeat(b[:, None], 3, 1), m, r, s)
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)


@settings(max_examples=40, deadline=None)
@given(batch)
def test_reciprocity(rows):
    """f(l, v) = f(v, l) wherever both cosines exceed the n.v clamp."""
    n, v, l, b, m, r, s = (np.array(c, dtype=np.float64) for c in zip(*rows))
    n, v, l = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in (n, v, l))
    keep = (np.sum(n * v, 1) > 1e-2) & (np.sum(n * l, 1) > 1e-2) & (r > 0.1)
    if not keep.any():
        return
    n, v, l, b, m, r, s = (x[keep] for x in (n, v, l, b, m, r, s))
    base = np.repeat(b[:, None], 3, 1)
    forward = brdf(n, v, l, base, m, r, s)
    backward = brdf(n, l, v, base, m, r, s)
    # v.h and l.h are equal in exact arithmetic but round apart in float32 (a few ulps, ~6e-7 at
    # most); Schlick's (1 - v.h)^5 magnifies that by 5 / (1 - v.h), which dominates where f0 = 0
    v_dot_h = np.sum(v * ref.normalize(v + l), axis=1)
    rtol = 2e-5 + 5 * 6e-7 / np.maximum(1.0 - v_dot_h, 1e-12)
    assert np.all(np.abs(forward - backward) <= rtol[:, None] * np.abs(backward) + 1e-30)


def term_errors(v, l, r, m, b, s):
    """Worst and median float32 relative error of D, V, F and the whole BRDF against the float64
    reference, each term fed the float64 values of its own inputs rounded to float32."""
    from pbrwarp.kernels.energy import albedo_tables
    from test_brdf import launch_terms, table_share

    count = len(v)
    n = np.tile([0.0, 0.0, 1.0], (count, 1))
    h = ref.normalize(v + l)
    base = np.repeat(b[:, None], 3, 1)
    inputs = dict(n=n, v=v, l=l, base=base, metallic=m, roughness=r, specular=s,
                  n_dot_h=h[:, 2], sin_sq=np.sum(np.cross(n, h) ** 2, -1), f0_dielectric=np.full((count, 3), 0.04))
    d, g, f, f0_mix, f0_mix_fresnel, gltf, gltf_fresnel = launch_terms(inputs, count)
    outs = (d, g, f, gltf, gltf_fresnel, f0_mix, f0_mix_fresnel)
    x = {k: a.astype(np.float32).astype(np.float64) for k, a in inputs.items()}
    nv, nl = x["v"][:, 2], x["l"][:, 2]
    mm, ss = x["metallic"][:, None], x["specular"][:, None]
    share = table_share(albedo_tables("ggx", "schlick_ggx", "schlick"))
    material = (np.array([0.0, 0.0, 1.0]), x["v"], x["l"], x["base"], x["metallic"], x["roughness"], x["specular"])
    ior, white = np.full(count, 1.5), np.ones((count, 3))
    want = {
        "D_GGX": ref.d_ggx(x["n_dot_h"], x["roughness"] ** 2),
        "V_SmithSchlickGGX": ref.g_schlick_ggx(nv, nl, x["roughness"]) / (4 * nv * nl),
        "F_Schlick": ref.f_schlick((1 - mm) * 0.04 * ss + mm * x["base"], (1 - mm) * ss + mm, np.sum(x["v"] * h, -1)),
        "BRDF": ref.gltf_brdf(*material, ior, white, share),
        "BRDF, 1 - F coupling": ref.gltf_brdf(*material, ior, white),
        "BRDF, f0 mix": ref.brdf(*material, share),
        "BRDF, f0 mix, 1 - F coupling": ref.brdf(*material),
    }
    table = {}
    for (name, w), got in zip(want.items(), outs):
        got = got.reshape(w.shape)
        ok = w > 1e-30
        rel = np.abs(got - w)[ok] / w[ok]
        table[name] = (float(rel.max()), float(np.median(rel)))
    return table


def error_table():
    """Per-term errors over the hard grid, where the reference is defined without the kernel's
    clamps (n.v, n.l >= 1e-3 and roughness >= MIN_ROUGHNESS); inputs exactly representable."""
    v, l, r, m, b, s = adversarial_grid()
    keep = (v[:, 2] >= 1e-3) & (l[:, 2] >= 1e-3) & (r >= MIN_ROUGHNESS)
    return term_errors(*(x[keep] for x in (v, l, r, m, b, s)))


def test_error_table_on_the_hard_grid():
    table = error_table()
    print("\n| term | worst relative error | median |\n|---|---|---|")
    for name, (worst, median) in table.items():
        print(f"| {name} | {worst:.1e} | {median:.1e} |")
    # Each term is a handful of float32 operations on exactly representable inputs: a few ulps
    # (1 ulp = 1.2e-7), times the condition number. D's is 4 alpha^2 (1 - n.h^2) / d <= 2 on
    # its exact inputs. F takes v.h from the float32 half vector (absolute error ~2e-7), which
    # (1 - v.h)^5 turns into 5 * 2e-7 / F, F >= 0.04 where it is not zero: 2.5e-5. The whole
    # BRDF adds that half vector's ~1e-7 rad error in D, up to 2e-7 / alpha: 6e-4 at the
    # smallest alpha (3.2e-4) of the grid. The bounds are those, with about a factor 2 to spare.
    bounds = {"D_GGX": 4e-6, "V_SmithSchlickGGX": 2e-6, "F_Schlick": 5e-5, "BRDF": 1.2e-3, "BRDF, 1 - F coupling": 1.2e-3,
              "BRDF, f0 mix": 1.2e-3, "BRDF, f0 mix, 1 - F coupling": 1.2e-3}
    for name, (worst, _) in table.items():
        assert worst <= bounds[name], (name, worst)
