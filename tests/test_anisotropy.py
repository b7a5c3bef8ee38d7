"""KHR_materials_anisotropy: anisotropic GGX and its Smith term against float64 references of the
formulas, their normalization and energy bound, and renders whose highlights stretch along the
tangent direction the material gives."""

import warnings

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.kernels import anisotropy as ka
from pbrwarp.kernels import brdf as kb

import reference as ref
from assets import BOARDS, board
from test_gltf import loaded_material, material_extension_file

N = 4096


def d_ggx_anisotropic(n_dot_h, t_dot_h, b_dot_h, at, ab):
    """Anisotropic GGX (Burley 2012): 1 / (pi at ab ((t.h/at)^2 + (b.h/ab)^2 + (n.h)^2)^2)."""
    return 1.0 / (np.pi * at * ab * ((t_dot_h / at) ** 2 + (b_dot_h / ab) ** 2 + n_dot_h**2) ** 2)


def v_smith_correlated_anisotropic(n_dot_v, n_dot_l, t_dot_v, b_dot_v, t_dot_l, b_dot_l, at, ab):
    """Height-correlated Smith G2 of anisotropic GGX over 4 n.l n.v (Heitz 2014):
    G2 = 1 / (1 + Lambda(v) + Lambda(l)), Lambda(x) = (-1 + sqrt(1 + (at^2 (t.x)^2 + ab^2 (b.x)^2) / (n.x)^2)) / 2."""
    def lam(t_dot, b_dot, n_dot):
        return 0.5 * (-1.0 + np.sqrt(1.0 + ((at * t_dot) ** 2 + (ab * b_dot) ** 2) / n_dot**2))

    g2 = 1.0 / (1.0 + lam(t_dot_v, b_dot_v, n_dot_v) + lam(t_dot_l, b_dot_l, n_dot_l))
    return g2 / (4.0 * n_dot_v * n_dot_l)


@wp.kernel(enable_backward=False)
def eval_terms(h: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
               alphas: wp.array(dtype=wp.vec2), out_d: wp.array(dtype=float), out_v: wp.array(dtype=float)):
    # a local frame: t = x, b = y, n = z
    i = wp.tid()
    a = alphas[i]
    out_d[i] = ka.D_GGX_Anisotropic(a[0], a[1], h[i][2], h[i][0], h[i][1])
    out_v[i] = ka.V_SmithGGXCorrelated_Anisotropic(a[0], a[1], v[i][2], l[i][2], v[i][0], v[i][1], l[i][0], l[i][1])


def upper_hemisphere(rng, count, min_cos=0.02):
    x = ref.normalize(rng.normal(size=(count, 3)))
    x[:, 2] = np.abs(x[:, 2])
    return ref.normalize(np.where(x[:, 2:3] < min_cos, x + [0, 0, min_cos], x))


def launch_terms(h, v, l, alphas):
    arrays = [wp.array(np.asarray(x, np.float32), dtype=wp.vec3) for x in (h, v, l)]
    arrays.append(wp.array(np.asarray(alphas, np.float32), dtype=wp.vec2))
    out_d, out_v = wp.zeros(len(h), dtype=float), wp.zeros(len(h), dtype=float)
    wp.launch(eval_terms, dim=len(h), inputs=arrays + [out_d, out_v])
    return out_d.numpy().astype(np.float64), out_v.numpy().astype(np.float64)


def test_terms_match_float64_references():
    rng = np.random.default_rng(7)
    h, v, l = (upper_hemisphere(rng, N) for _ in range(3))
    alphas = rng.uniform(0.03, 1.0, (N, 2))
    d, vis = launch_terms(h, v, l, alphas)
    at, ab = alphas[:, 0], alphas[:, 1]
    np.testing.assert_allclose(d, d_ggx_anisotropic(h[:, 2], h[:, 0], h[:, 1], at, ab), rtol=2e-4)
    np.testing.assert_allclose(vis, v_smith_correlated_anisotropic(v[:, 2], l[:, 2], v[:, 0], v[:, 1], l[:, 0],
                                                                   l[:, 1], at, ab), rtol=2e-4)


def test_equal_alphas_give_isotropic_ggx():
    rng = np.random.default_rng(8)
    h, v, l = (upper_hemisphere(rng, N) for _ in range(3))
    alpha = rng.uniform(0.03, 1.0, N)
    d, vis = launch_terms(h, v, l, np.column_stack([alpha, alpha]))
    np.testing.assert_allclose(d, ref.d_ggx(h[:, 2], alpha), rtol=2e-4)
    a2 = alpha**2
    nv, nl = v[:, 2], l[:, 2]
    correlated = 0.5 / (nl * np.sqrt(nv**2 * (1 - a2) + a2) + nv * np.sqrt(nl**2 * (1 - a2) + a2))
    np.testing.assert_allclose(vis, correlated, rtol=2e-4)


def hemisphere_grid(thetas=3000, phis=720):
    """Directions at cell centres of a (theta, phi) grid of the upper hemisphere, with their solid angles."""
    theta = (np.arange(thetas) + 0.5) * (np.pi / 2 / thetas)
    phi = (np.arange(phis) + 0.5) * (2 * np.pi / phis)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    solid_angle = (np.sin(th) * (np.pi / 2 / thetas) * (2 * np.pi / phis)).ravel()
    return d, solid_angle


@pytest.mark.parametrize("at,ab", [(0.5, 0.2), (1.0, 0.1), (0.3, 0.3), (0.15, 0.6)])
def test_distribution_is_normalized(at, ab):
    """The projected area of the microfacets is the macro-surface's: integral of D (n.h) = 1."""
    h, solid_angle = hemisphere_grid()
    d, _ = launch_terms(h, h, h, np.tile([at, ab], (len(h), 1)))
    assert np.sum(d * h[:, 2] * solid_angle) == pytest.approx(1.0, abs=2e-3)


# the glTF BRDF with every lobe, anisotropic, and the Fresnel coupling the float64 reference models
anisotropic_brdf = kb.brdf_for(True, True, coupling="fresnel", anisotropic=True)
isotropic_brdf = kb.brdf_for(True, True, coupling="fresnel")


@wp.kernel(enable_backward=False)
def eval_brdf(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
              t: wp.array(dtype=wp.vec3), base: wp.array(dtype=wp.vec3), metallic: wp.array(dtype=float),
              roughness: wp.array(dtype=float), strength: wp.array(dtype=float),
              out: wp.array(dtype=wp.vec3), out_isotropic: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = anisotropic_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i], 1.0, wp.vec3(0.0),
                              wp.vec3(0.0), wp.vec3(0.04), t[i], strength[i])
    out_isotropic[i] = isotropic_brdf(n[i], v[i], l[i], base[i], metallic[i], roughness[i], 1.0, wp.vec3(0.0),
                                      wp.vec3(0.0), wp.vec3(0.04))


def launch_brdf(n, v, l, t, base, metallic, roughness, strength):
    vectors = [wp.array(np.asarray(x, np.float32), dtype=wp.vec3) for x in (n, v, l, t, base)]
    scalars = [wp.array(np.asarray(x, np.float32), dtype=float) for x in (metallic, roughness, strength)]
    out, out_iso = wp.zeros(len(n), dtype=wp.vec3), wp.zeros(len(n), dtype=wp.vec3)
    wp.launch(eval_brdf, dim=len(n), inputs=vectors + scalars + [out, out_iso])
    return out.numpy().astype(np.float64), out_iso.numpy().astype(np.float64)


def test_brdf_swaps_the_isotropic_lobe_for_the_anisotropic_one():
    """f = glTF's BRDF with D V of its specular lobes replaced by the anisotropic terms:
    f_iso + mix(F_d, F_m, metallic) (D_a V_a - D V), in a random frame; strength 0 is f_iso."""
    rng = np.random.default_rng(9)
    n = ref.normalize(rng.normal(size=(N, 3)))
    t = ref.normalize(np.cross(n, rng.normal(size=(N, 3))))
    b = np.cross(n, t)
    frame = np.stack([t, b, n], 1)  # rows t, b, n
    v, l = (np.einsum("kij,ki->kj", frame, upper_hemisphere(rng, N, 0.05)) for _ in range(2))
    base = rng.uniform(0, 1, (N, 3))
    metallic, roughness = rng.uniform(0, 1, N), rng.uniform(0.1, 1, N)
    strength = rng.uniform(0, 1, N)
    strength[: N // 8] = 0.0
    f, f_iso = launch_brdf(n, v, l, t, base, metallic, roughness, strength)
    specular = np.ones(N)
    expected_iso = ref.gltf_brdf(n, v, l, base, metallic, roughness, specular, np.full(N, 1.5), np.ones((N, 3)))
    np.testing.assert_allclose(f_iso, expected_iso, rtol=5e-4, atol=1e-6)
    h = ref.normalize(v + l)
    dot = lambda a, c: np.sum(a * c, -1)  # noqa: E731
    alpha = roughness**2
    at, ab = alpha + (1 - alpha) * strength**2, alpha
    d_v_aniso = (d_ggx_anisotropic(dot(n, h), dot(t, h), dot(b, h), at, ab)
                 * v_smith_correlated_anisotropic(dot(n, v), dot(n, l), dot(t, v), dot(b, v), dot(t, l), dot(b, l),
                                                  at, ab))
    d_v_iso = ref.d_ggx(dot(n, h), alpha) * ref.g_schlick_ggx(dot(n, v), dot(n, l), roughness) / (4 * dot(n, v) * dot(n, l))
    m = metallic[:, None]
    fresnel = (1 - m) * ref.f_schlick(np.full((N, 3), 0.04), 1.0, dot(v, h)) + m * ref.f_schlick(base, 1.0, dot(v, h))
    expected = expected_iso + np.where(strength[:, None] > 0, fresnel * (d_v_aniso - d_v_iso)[:, None], 0.0)
    np.testing.assert_allclose(f, expected, rtol=5e-4, atol=1e-6)


@pytest.mark.parametrize("roughness,strength", [(0.3, 0.5), (0.3, 1.0), (0.6, 0.8)])
def test_white_furnace_bound(roughness, strength):
    """A white metal's anisotropic lobe reflects at most what it receives, from every direction
    (single scattering loses a little, never gains): the integral of f n.l over the hemisphere
    is at most 1 (and no less than single scattering keeps of the roughest lobe, alpha = 1)."""
    l, solid_angle = hemisphere_grid(2000, 720)
    count = len(l)
    for theta, phi in ((0.1, 0.0), (1.2, 0.0), (1.2, np.pi / 2), (1.45, np.pi / 4)):
        view = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        f, _ = launch_brdf(np.tile([0, 0, 1.0], (count, 1)), np.tile(view, (count, 1)), l,
                           np.tile([1.0, 0, 0], (count, 1)), np.ones((count, 3)), np.ones(count),
                           np.full(count, roughness), np.full(count, strength))
        albedo = np.sum(f[:, 0] * l[:, 2] * solid_angle)
        assert 0.4 < albedo <= 1.0 + 3e-3, (theta, phi, albedo)


def test_bent_normal_is_the_normal_without_anisotropy():
    @wp.kernel(enable_backward=False)
    def bend(strength: wp.array(dtype=float), roughness: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        out[i] = ka.anisotropic_bent_normal(wp.vec3(0.0, 0.0, 1.0), wp.vec3(1.0, 0.0, 0.0),
                                            wp.normalize(wp.vec3(0.3, 0.4, 0.8)), strength[i], roughness[i])

    strength = np.array([0.0, 0.5, 1.0, 1.0], np.float32)
    roughness = np.array([0.3, 0.3, 1.0, 0.0], np.float32)
    out = wp.zeros(4, dtype=wp.vec3)
    wp.launch(bend, dim=4, inputs=[wp.array(strength), wp.array(roughness), out])
    bent = out.numpy()
    np.testing.assert_allclose(bent[0], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(bent[2], [0, 0, 1], atol=1e-6)  # roughness 1: no stretch to bend for
    np.testing.assert_allclose(np.linalg.norm(bent, axis=1), 1.0, atol=1e-5)
    # fully bent: the normal of the plane of v and the smooth direction b = n x t = y, perpendicular to b
    assert abs(bent[3][1]) < 1e-5 and bent[3][2] < 1.0 - 1e-3


# ---------------------------------------------------------------------------- renders

def plane(uvs=True):
    mesh = trimesh.Trimesh(vertices=[[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], faces=[[0, 1, 2], [0, 2, 3]],
                           process=False)
    if uvs:
        mesh.visual = trimesh.visual.texture.TextureVisuals(uv=np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float))
    return mesh


CAMERA = pw.Camera(eye=(0, 0, 3), forward=(0, 0, -1), up=(0, 1, 0), fov_y=60)


def highlight(uvs=True, **material):
    """The red channel of a smooth white metal plane (tangent +x) under a point light above its
    centre, seen from above."""
    scene = pw.Scene()
    scene.add_mesh(plane(uvs), pw.Material(base_color=(1, 1, 1), metallic=1.0, roughness=0.15, **material))
    scene.add_light(pw.PointLight(position=(0, 0, 1.0), intensity=5.0))
    image = np.asarray(pw.render(scene, CAMERA, width=96, height=96).rgb, np.float64)
    assert np.isfinite(image).all()
    return image[..., 0]


def spreads(image):
    """The highlight's standard deviations along image x and y (pixels), weighted by radiance."""
    w = image / image.sum()
    ys, xs = np.mgrid[: image.shape[0], : image.shape[1]]
    mx, my = (w * xs).sum(), (w * ys).sum()
    return np.sqrt((w * (xs - mx) ** 2).sum()), np.sqrt((w * (ys - my) ** 2).sum())


def test_highlight_stretches_along_the_tangent_and_turns_with_the_rotation():
    round_x, round_y = spreads(highlight())
    assert round_x == pytest.approx(round_y, rel=1e-3)
    along_x, across_y = spreads(highlight(anisotropy_strength=0.8))
    assert along_x > 4 * across_y and along_x > 3 * round_x
    turned_x, turned_y = spreads(highlight(anisotropy_strength=0.8, anisotropy_rotation=np.pi / 2))
    assert turned_y == pytest.approx(along_x, rel=0.02) and turned_x == pytest.approx(across_y, rel=0.02)


def test_texture_direction_and_strength_match_the_factors():
    """A texel pointing along the bitangent (r, g) = (0.5, 1) turns the direction as a rotation of
    pi/2 does; its blue channel scales the strength."""
    texel = np.ones((4, 4, 3), np.float32) * np.array([0.5, 1.0, 0.5], np.float32)
    by_texture = highlight(anisotropy_strength=1.0, anisotropy_texture=texel)
    by_factors = highlight(anisotropy_strength=0.5, anisotropy_rotation=np.pi / 2)
    np.testing.assert_allclose(by_texture, by_factors, rtol=2e-3, atol=1e-4 * by_factors.max())


def test_no_tangent_frame_shades_isotropically():
    np.testing.assert_array_equal(highlight(uvs=False, anisotropy_strength=0.8), highlight(uvs=False))


@pytest.mark.parametrize("method", ["split_sum", "monte_carlo"])
def test_anisotropy_under_an_environment(method):
    """Both IBL rungs shade an anisotropic metal with finite radiance that differs from the
    isotropic one (the split sum through its bent normal, Monte Carlo through the BRDF), and agree
    with each other about as well as they do on the isotropic material."""
    def render(ibl_method, **material):
        scene = pw.Scene()
        floor = plane().apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))  # normal +y
        scene.add_mesh(floor, pw.Material(base_color=(1, 1, 1), metallic=1.0, roughness=0.3, **material))
        scene.environment = pw.Environment.sky()  # zenith +y
        camera = pw.Camera(eye=(-2.5, 1.5, 0), forward=(2.5, -1.5, 0), up=(0, 1, 0), fov_y=50)  # along t
        image = np.asarray(pw.render(scene, camera, width=32, height=32, spp=4,
                                     ibl=pw.IBL(method=ibl_method, samples=256)).rgb, np.float64)
        assert np.isfinite(image).all()
        return image

    stretched, round_ = render(method, anisotropy_strength=0.9), render(method)
    assert np.abs(stretched - round_).mean() > 1e-3 * round_.mean()  # a smooth sky: small, but there
    if method == "monte_carlo":
        split = render("split_sum", anisotropy_strength=0.9)
        gap = np.abs(split - stretched).mean() / stretched.mean()
        isotropic_gap = np.abs(render("split_sum") - round_).mean() / round_.mean()
        assert gap < max(2 * isotropic_gap, 0.05), (gap, isotropic_gap)


# ---------------------------------------------------------------------------- glTF

def test_gltf_anisotropy_is_read_without_a_warning(tmp_path):
    material = loaded_material(material_extension_file(tmp_path, "KHR_materials_anisotropy", {
        "anisotropyStrength": 0.6, "anisotropyRotation": 1.25, "anisotropyTexture": {"index": 0}}))
    assert material.anisotropy_strength == pytest.approx(0.6)
    assert material.anisotropy_rotation == pytest.approx(1.25)
    assert material.anisotropy_texture is not None


@pytest.mark.skipif("AnisotropyStrengthTest" not in BOARDS, reason="needs PBRWARP_TEST_ASSETS (shared assets)")
def test_anisotropy_strength_board_stretches_highlights_with_strength():
    """AnisotropyStrengthTest: spheres of increasing anisotropy strength (rows) and roughness
    (columns); its README: the effect shows most at roughness 0 and not at all at roughness 1.
    Here: the board loads without a warning, renders finite, and its materials carry the strengths."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = pw.Scene.load(board("AnisotropyStrengthTest"))
    strengths = {p.material.anisotropy_strength for p in scene.primitives}
    assert len(strengths) >= 3 and max(strengths) > 0.5
    image = np.asarray(pw.render(scene, pw.Camera.frame(scene), width=64, height=48).rgb)
    assert np.isfinite(image).all()


def test_anisotropy_set_after_a_render_gets_its_tangent_frame():
    """A mesh without tangents gets them generated only when a material reads a frame: setting
    anisotropy on after a render rebuilds the cached geometry with them."""
    scene = pw.Scene()
    material = pw.Material(base_color=(1, 1, 1), metallic=1.0, roughness=0.15)
    scene.add_mesh(plane(), material)
    scene.add_light(pw.PointLight(position=(0, 0, 1.0), intensity=5.0))
    pw.render(scene, CAMERA, width=96, height=96)
    material.anisotropy_strength = 0.8
    again = np.asarray(pw.render(scene, CAMERA, width=96, height=96).rgb, np.float64)[..., 0]
    np.testing.assert_array_equal(again, highlight(anisotropy_strength=0.8))
