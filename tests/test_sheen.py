"""KHR_materials_sheen: the Charlie sheen's terms against float64 references of Estevez & Kulla
2017's formulas, its albedo table against a brute-force integral, its energy with the albedo
scaling (white furnaces), its textures, glTF reading, specialization, and the SheenCloth board."""

import warnings

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.errors import AssetFormatError
from pbrwarp.features import scene_features
from pbrwarp.gltf import load_gltf
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.loading import generated_source
from pbrwarp.kernels.render import render_kernel
from pbrwarp.kernels.sheen import SHEEN_TABLE_SIZE, sheen_albedo_table, sheen_for

import reference as ref
from assets import board
from scenes import quad, render_checked
from test_clearcoat import hemisphere_grid, random_directions
from test_gltf import Builder, loaded_material, material_extension_file

N = 4096
_, sheen_layer, sheen_brdf, sheen_scaling, _, sheen_albedo = sheen_for()


@wp.kernel(enable_backward=False)
def eval_sheen(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
               color: wp.array(dtype=wp.vec3), roughness: wp.array(dtype=float), out_brdf: wp.array(dtype=wp.vec3),
               out_scaling: wp.array(dtype=float), out_albedo: wp.array(dtype=float)):
    i = wp.tid()
    sheen = sheen_layer(color[i], roughness[i], n[i], v[i])
    out_brdf[i] = sheen_brdf(sheen, v[i], l[i])
    out_scaling[i] = sheen_scaling(sheen, l[i])
    out_albedo[i] = sheen_albedo(wp.dot(n[i], v[i]), roughness[i])


def launch_sheen(n, v, l, color, roughness):
    inputs = [wp.array(np.asarray(x, np.float32), dtype=wp.vec3 if np.ndim(x) == 2 else float)
              for x in (n, v, l, color, roughness)]
    count = len(roughness)
    outs = [wp.zeros(count, dtype=wp.vec3), wp.zeros(count, dtype=float), wp.zeros(count, dtype=float)]
    wp.launch(eval_sheen, dim=count, inputs=inputs + outs)
    return [o.numpy().astype(np.float64) for o in outs]


def charlie_lambda(cos_theta, alpha):
    """Estevez & Kulla 2017's fitted Lambda: exp(L(x)) below x = 1/2, exp(2 L(1/2) - L(1 - x))
    above, L(x) = a / (1 + b x^c) + d x + e with the coefficients of their Table 1 interpolated
    in (1 - alpha)^2."""
    t = (1 - alpha) ** 2
    a, b, c, d, e = ((1 - t) * p0 + t * p1 for p0, p1 in ((21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801),
                                                           (-1.97760, -1.27393), (-4.32054, -4.85967)))

    def fit(x):
        return a / (1 + b * x**c) + d * x + e

    x = np.abs(cos_theta)
    return np.where(x < 0.5, np.exp(fit(x)), np.exp(2 * fit(0.5) - fit(1 - x)))


def charlie_brdf(n_dot_v, n_dot_l, n_dot_h, roughness):
    """D_Charlie V_Charlie: D = (2 + 1/a) sin(theta_h)^(1/a) / (2 pi), V = 1 / ((1 + Lambda(v)
    + Lambda(l)) 4 n.l n.v), a = roughness^2 (KHR_materials_sheen)."""
    alpha = np.maximum(roughness**2, 1e-4)
    d = (2 + 1 / alpha) * (1 - n_dot_h**2) ** (0.5 / alpha) / (2 * np.pi)
    return d / ((1 + charlie_lambda(n_dot_v, alpha) + charlie_lambda(n_dot_l, alpha)) * 4 * n_dot_v * n_dot_l)


def table_lookup(n_dot, roughness):
    """Bilinear in the clamped table, rows at n.v = (i + 0.5) / size, columns at roughness j / (size - 1)."""
    table = np.minimum(sheen_albedo_table(), 1.0)
    size = SHEEN_TABLE_SIZE
    x = np.clip(n_dot * size - 0.5, 0, size - 1)
    y = np.clip(roughness * (size - 1), 0, size - 1)
    i0, j0 = np.minimum(x.astype(int), size - 2), np.minimum(y.astype(int), size - 2)
    fx, fy = x - i0, y - j0
    top = table[i0, j0] * (1 - fy) + table[i0, j0 + 1] * fy
    bottom = table[i0 + 1, j0] * (1 - fy) + table[i0 + 1, j0 + 1] * fy
    return top * (1 - fx) + bottom * fx


def test_sheen_brdf_and_scaling_match_the_float64_reference():
    rng = np.random.default_rng(31)
    n = ref.normalize(rng.normal(size=(N, 3)))
    v = random_directions(rng, n, N, 0.05)
    l = random_directions(rng, n, N, -0.3)
    color = rng.uniform(0, 1, (N, 3))
    roughness = rng.uniform(0.2, 1.0, N)
    brdf, scaling, albedo = launch_sheen(n, v, l, color, roughness)
    n_dot_v, n_dot_l = np.einsum("ij,ij->i", n, v), np.einsum("ij,ij->i", n, l)
    n_dot_h = np.einsum("ij,ij->i", n, ref.normalize(v + l))
    lit = n_dot_l > 1e-3
    want = color * charlie_brdf(n_dot_v, np.maximum(n_dot_l, 1e-4), n_dot_h, roughness)[:, None]
    np.testing.assert_allclose(brdf[lit], want[lit], rtol=2e-4, atol=1e-7)
    assert np.all(brdf[n_dot_l <= 0] == 0)
    m = color.max(axis=1)
    want_scaling = np.minimum(1 - m * table_lookup(n_dot_v, roughness), 1 - m * table_lookup(np.maximum(n_dot_l, 0),
                                                                                              roughness))
    np.testing.assert_allclose(scaling, want_scaling, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(albedo, table_lookup(n_dot_v, roughness), rtol=1e-4, atol=1e-6)


def brute_force_albedo(n_dot_v, roughness, count=1200):
    """The integral of D_Charlie V_Charlie n.l over the hemisphere of l, float64, midpoint rule in
    (theta_l, phi_l): independent of the table's quadrature over half vectors."""
    l, solid_angle = hemisphere_grid(count)
    v = np.array([np.sqrt(1 - n_dot_v**2), 0.0, n_dot_v])
    n_dot_h = ref.normalize(l + v)[:, 2]
    return np.sum(charlie_brdf(n_dot_v, l[:, 2], n_dot_h, roughness) * l[:, 2] * solid_angle)


@pytest.mark.parametrize("column", [6, 12, 20, 31])
def test_albedo_table_matches_a_brute_force_integral(column):
    table = sheen_albedo_table()
    size = SHEEN_TABLE_SIZE
    roughness = column / (size - 1)
    for row in (0, 3, 8, 16, 31):
        n_dot_v = (row + 0.5) / size
        want = brute_force_albedo(n_dot_v, roughness)
        assert table[row, column] == pytest.approx(want, rel=0.01, abs=2e-3), (row, column)


def test_the_albedo_stays_below_one_away_from_grazing():
    """The fitted Lambda lets E exceed 1 only at grazing views of smooth sheens (n.v < 0.05,
    roughness < 0.3), where the kernels' table is clamped to 1."""
    table = sheen_albedo_table()
    size = SHEEN_TABLE_SIZE
    n_dot_v = (np.arange(size) + 0.5) / size
    roughness = np.arange(size) / (size - 1)
    assert np.all(table >= 0) and np.all(np.isfinite(table))
    assert np.all(table[n_dot_v >= 0.05] <= 1.0)
    assert np.all(table[:, roughness >= 0.3] <= 1.0)


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
def test_a_white_base_under_a_white_sheen_reflects_at_most_what_it_receives(roughness):
    """White furnace of the layering under lights: the directional albedo of a white Lambert base
    under a white sheen, the integral of (sheen BRDF + scaling / pi) n.l, stays <= 1 (it would be
    1 + E(v) without the scaling)."""
    l, solid_angle = hemisphere_grid(300)
    count = len(l)
    for n_dot_v in (0.1, 0.3, 0.6, 0.9, 1.0):
        v = np.array([np.sqrt(1 - n_dot_v**2), 0.0, n_dot_v])
        brdf, scaling, albedo = launch_sheen(np.tile([0.0, 0.0, 1.0], (count, 1)), np.tile(v, (count, 1)), l,
                                             np.ones((count, 3)), np.full(count, roughness))
        sheen = np.sum(brdf[:, 0] * l[:, 2] * solid_angle)
        base = np.sum(scaling / np.pi * l[:, 2] * solid_angle)
        # the lobe reflects its table albedo, up to the table's bilinear interpolation
        assert sheen == pytest.approx(albedo[0], rel=0.1, abs=5e-3)
        assert sheen + base <= 1.0 + 2e-3, (n_dot_v, sheen, base)


def test_white_furnace_under_environment_light():
    """A white Lambert sphere under a white sheen in a uniform environment of radiance 1:
    (1 - E(v)) + E(v) = 1 at every pixel."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=4),
                   pw.Material(base_color=(1.0, 1.0, 1.0), roughness=1.0, specular=0.0, sheen_color=(1.0, 1.0, 1.0),
                               sheen_roughness=0.4))
    scene.environment = pw.Environment.uniform(intensity=1.0)
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 4), target=(0, 0, 0)), size=(40, 40),
                           background=(0.0, 0.0, 0.0))
    covered = frame.alpha == 1.0
    assert covered.sum() > 300
    np.testing.assert_allclose(frame.rgb[covered], 1.0, atol=2e-3)


CAMERA = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=30.0)


def sheen_quad_scene(**material):
    fields = dict(base_color=(0.4, 0.1, 0.1), roughness=0.8, sheen_color=(0.9, 0.8, 0.7), sheen_roughness=0.6)
    scene = pw.Scene()
    scene.add_mesh(quad(material=pw.Material(**{**fields, **material})))
    scene.add_light(pw.PointLight(position=(0.5, 0.8, 0.4), intensity=4.0))
    scene.environment = pw.Environment.uniform(intensity=0.2)
    return scene


def test_textures_scale_the_factors_from_their_channels():
    """sheenColorTexture's RGB multiplies the colour (linear float texels: srgb=False); the
    roughness texture's alpha, the roughness (alpha 0.5 on 0.8 is 0.4)."""
    tint = np.broadcast_to([0.5, 0.25, 1.0], (4, 4, 3)).astype(np.float32)
    textured = render_checked(sheen_quad_scene(sheen_color_texture=pw.Texture(tint, srgb=False)), CAMERA).rgb
    direct = render_checked(sheen_quad_scene(sheen_color=(0.45, 0.2, 0.7)), CAMERA).rgb
    np.testing.assert_allclose(textured, direct, rtol=1e-5, atol=1e-7)
    half = np.zeros((4, 4, 4), np.float32)
    half[..., 3] = 0.5
    textured = render_checked(sheen_quad_scene(sheen_roughness=0.8, sheen_roughness_texture=half), CAMERA).rgb
    direct = render_checked(sheen_quad_scene(sheen_roughness=0.4), CAMERA).rgb
    np.testing.assert_allclose(textured, direct, rtol=1e-5, atol=1e-7)
    plain = render_checked(sheen_quad_scene(sheen_color=(0.0, 0.0, 0.0)), CAMERA).rgb
    assert not np.allclose(direct, plain)


def test_sheen_is_compiled_in_only_when_a_material_has_one():
    bare = sheen_quad_scene(sheen_color=(0.0, 0.0, 0.0))
    features = scene_features(bare, upload(bare), shadows=True, spp=1)
    assert not features.sheen and not features.sheen_textures
    assert "no sheen: every sheen colour is black" in pw.explain(bare)
    assert "D_Charlie" not in generated_source(render_kernel(features))
    sheened = sheen_quad_scene(sheen_roughness_texture=np.ones((2, 2, 4), np.float32))
    features = scene_features(sheened, upload(sheened), shadows=True, spp=1)
    assert features.sheen and features.sheen_textures
    text = pw.explain(sheened)
    assert "sheen (KHR_materials_sheen): 1 material" in text and "sheen textures: 1 of 1 meshes" in text
    dark = pw.Scene()
    dark.add_mesh(quad(material=pw.Material(sheen_color=(1.0, 1.0, 1.0))))
    assert "no sheen: no lights" in pw.explain(dark)


@pytest.mark.parametrize("spp", [1, 4])
def test_specialized_image_equals_the_all_effects_image(spp):
    """Sheen textures under a clear coat (coat over sheen over the base), lights and an environment."""
    rng = np.random.default_rng(4)
    material = pw.Material(base_color=(0.5, 0.2, 0.1), roughness=0.6, sheen_color=(0.9, 0.7, 0.5), sheen_roughness=0.5,
                           sheen_color_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32),
                           sheen_roughness_texture=rng.uniform(0, 1, (8, 8, 4)).astype(np.float32),
                           clearcoat=0.5, clearcoat_roughness=0.2)
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), pw.Material(sheen_color=(0.3, 0.3, 0.3)))
    scene.add_mesh(quad(size=3.0, z=-1.2, material=material))
    scene.add_light(pw.PointLight(position=(0.5, 0.8, 2.0), intensity=8.0))
    scene.environment = pw.Environment.uniform(intensity=0.3)
    cam = pw.Camera.look_at(eye=(0.5, 0.6, 4.0), target=(0, 0, 0))
    special = render_checked(scene, cam, size=(40, 32), spp=spp)
    general = render_checked(scene, cam, size=(40, 32), spp=spp, specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)


def test_every_sheen_property_is_read_from_gltf(tmp_path):
    m = loaded_material(material_extension_file(tmp_path, "KHR_materials_sheen", {
        "sheenColorFactor": [0.9, 0.5, 0.25], "sheenRoughnessFactor": 0.7, "sheenColorTexture": {"index": 0},
        "sheenRoughnessTexture": {"index": 0}}))
    assert m.sheen_color == (0.9, 0.5, 0.25) and m.sheen_roughness == 0.7
    slots = {slot: srgb for slot, _, srgb in m.textures()}
    assert slots == {"sheen_color_texture": True, "sheen_roughness_texture": False}
    plain = Builder()
    plain.json["materials"] = [{}]
    plain.node(mesh=plain.quad(material=0))
    m = load_gltf(plain.glb(tmp_path / "plain.glb")).primitives[0].material
    assert m.sheen_color == (0.0, 0.0, 0.0) and m.sheen_roughness == 0.0


def test_sheen_cloth_brightens_at_grazing_angles():
    """SheenCloth (a fabric with a white sheen factor and a sheen texture; only in
    PBRWARP_TEST_ASSETS): the sheen brightens the cloth most where it is seen at grazing angles,
    the fabric look of its reference render; without it the folds' rims are dark."""
    try:
        path = board("SheenCloth")
    except FileNotFoundError:
        pytest.skip("SheenCloth is in the shared assets only (PBRWARP_TEST_ASSETS=../shared/assets)")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the sheen is honoured: nothing to warn about
        scene = pw.Scene.load(path)
    scene.environment = pw.Environment.uniform(intensity=1.0)
    cam = pw.Camera.frame(scene, direction=(0.3, 0.5, 1.0), aspect=1.0)
    with_sheen = render_checked(scene, cam, size=(64, 64))
    for prim in scene.primitives:
        prim.material.sheen_color = (0.0, 0.0, 0.0)
    without = render_checked(scene, cam, size=(64, 64))
    covered = with_sheen.alpha == 1.0
    assert covered.sum() > 500
    gain = with_sheen.rgb.sum(-1)[covered] / np.maximum(without.rgb.sum(-1)[covered], 1e-6)
    assert np.median(gain) > 1.0
    # seen from afar, the view direction is about the same at every pixel
    to_eye = -np.asarray(cam.forward, float)
    facing = np.abs(with_sheen.normal[covered] @ to_eye)
    assert np.median(gain[facing < 0.3]) > np.median(gain[facing > 0.8])


@pytest.mark.parametrize("body,field", [({"sheenColorFactor": [1.5, 0.0, 0.0]}, "sheen_color"),
                                        ({"sheenRoughnessFactor": 3.0}, "sheen_roughness")])
def test_out_of_range_sheen_values_are_refused_with_their_name(tmp_path, body, field):
    b = Builder()
    b.json["materials"] = [{"extensions": {"KHR_materials_sheen": body}}]
    b.node(mesh=b.quad(material=0))
    with pytest.raises(AssetFormatError, match=f"Material.{field}"):
        load_gltf(b.glb(tmp_path / "bad.glb"))
