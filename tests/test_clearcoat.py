"""KHR_materials_clearcoat: the coat's terms against float64 references of the extension's
formulas, its energy (white furnace), its layering in renders, its textures and normal map, its
glTF reading, its specialization, and the ClearCoatTest board."""

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.errors import AssetFormatError
from pbrwarp.features import scene_features
from pbrwarp.gltf import load_gltf
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.clearcoat import clearcoat_for
from pbrwarp.kernels.loading import generated_source
from pbrwarp.kernels.render import render_kernel

import reference as ref
from assets import board
from scenes import quad, render_checked
from test_gltf import Builder, loaded_material, material_extension_file

N = 4096
_, schlick_layer, schlick_coat, _ = clearcoat_for("ggx", "schlick_ggx", "schlick")
_, exact_layer, exact_coat, _ = clearcoat_for("ggx", "schlick_ggx", "exact")


@wp.kernel(enable_backward=False)
def eval_coat(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
              clearcoat: wp.array(dtype=float), roughness: wp.array(dtype=float), out_weight: wp.array(dtype=float),
              out_brdf: wp.array(dtype=float), out_exact_weight: wp.array(dtype=float),
              out_exact_brdf: wp.array(dtype=float)):
    i = wp.tid()
    coat = schlick_layer(clearcoat[i], roughness[i], n[i], v[i])
    out_weight[i] = coat.weight
    out_brdf[i] = schlick_coat(coat, v[i], l[i])
    exact = exact_layer(clearcoat[i], roughness[i], n[i], v[i])
    out_exact_weight[i] = exact.weight
    out_exact_brdf[i] = exact_coat(exact, v[i], l[i])


def launch_coat(n, v, l, clearcoat, roughness):
    inputs = [wp.array(np.asarray(x, np.float32), dtype=wp.vec3 if np.ndim(x) == 2 else float)
              for x in (n, v, l, clearcoat, roughness)]
    outs = [wp.zeros(len(clearcoat), dtype=float) for _ in range(4)]
    wp.launch(eval_coat, dim=len(clearcoat), inputs=inputs + outs)
    return [o.numpy().astype(np.float64) for o in outs]


def fresnel_dielectric(cos_i, eta):
    """Unpolarized Fresnel reflectance of a dielectric of relative IOR eta (Born & Wolf), from
    the s and p amplitudes."""
    sin_t = np.sqrt(1 - cos_i**2) / eta
    cos_t = np.sqrt(1 - sin_t**2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs**2 + rp**2)


def coat_reference(n, v, l, clearcoat, roughness, fresnel):
    """The extension's coat: weight clearcoat F(Nc.v) and BRDF weight D(a) G / (4 Nc.l Nc.v),
    a = roughness^2, 0 where Nc.l <= 0."""
    n_dot_v = np.einsum("ij,ij->i", n, v)
    n_dot_l = np.einsum("ij,ij->i", n, l)
    h = ref.normalize(v + l)
    weight = clearcoat * fresnel(n_dot_v)
    lobe = ref.d_ggx(np.einsum("ij,ij->i", n, h), roughness**2) * ref.g_schlick_ggx(n_dot_v, n_dot_l, roughness) / (
        4 * n_dot_l * n_dot_v)
    return weight, np.where(n_dot_l > 0, weight * lobe, 0.0)


def random_directions(rng, n, count, min_cos):
    out = np.empty((count, 3))
    for i in range(count):
        while True:
            d = ref.normalize(rng.normal(size=3))
            if d @ n[i] > min_cos:
                out[i] = d
                break
    return out


@pytest.mark.parametrize("fresnel", ["schlick", "exact"])
def test_coat_weight_and_brdf_match_the_float64_reference(fresnel):
    rng = np.random.default_rng(30)
    n = ref.normalize(rng.normal(size=(N, 3)))
    v = random_directions(rng, n, N, 0.05)
    l = random_directions(rng, n, N, -0.3)  # some below the coat: 0
    clearcoat = rng.uniform(0, 1, N)
    roughness = rng.uniform(0.25, 1.0, N)
    weight, brdf, exact_weight, exact_brdf = launch_coat(n, v, l, clearcoat, roughness)
    if fresnel == "schlick":
        schlick = lambda c: 0.04 + 0.96 * (1 - c) ** 5  # noqa: E731
        want_weight, want_brdf = coat_reference(n, v, l, clearcoat, roughness, schlick)
    else:
        want_weight, want_brdf = coat_reference(n, v, l, clearcoat, roughness, lambda c: fresnel_dielectric(c, 1.5))
        weight, brdf = exact_weight, exact_brdf
    np.testing.assert_allclose(weight, want_weight, rtol=2e-5, atol=1e-7)
    np.testing.assert_allclose(brdf, want_brdf, rtol=2e-4, atol=1e-6)
    assert np.all(brdf[np.einsum("ij,ij->i", n, l) <= 0] == 0)


def hemisphere_grid(count):
    """(directions, solid angles) of a midpoint grid over the upper hemisphere of +z."""
    theta = (np.arange(count) + 0.5) * (np.pi / 2) / count
    phi = (np.arange(2 * count) + 0.5) * np.pi / count
    t, p = np.meshgrid(theta, phi, indexing="ij")
    directions = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    solid_angle = (np.sin(t) * (np.pi / 2 / count) * (np.pi / count)).reshape(-1)
    return directions, solid_angle


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
def test_a_white_base_under_a_coat_reflects_at_most_what_it_receives(roughness):
    """White furnace of the layering: the directional albedo of a white Lambert base (albedo 1)
    under a full coat, (1 - w(v)) + integral of the coat's weighted BRDF Nc.l, stays <= 1 at
    every view (the coat's BRDF, integrated numerically from the kernel's values, reflects at most
    its weight)."""
    l, solid_angle = hemisphere_grid(300)
    count = len(l)
    for n_dot_v in (0.02, 0.1, 0.3, 0.6, 0.9, 1.0):
        v = np.array([np.sqrt(1 - n_dot_v**2), 0.0, n_dot_v])
        weight, brdf, _, _ = launch_coat(np.tile([0.0, 0.0, 1.0], (count, 1)), np.tile(v, (count, 1)), l,
                                         np.ones(count), np.full(count, roughness))
        coat_albedo = np.sum(brdf * l[:, 2] * solid_angle)
        assert coat_albedo <= weight[0] * 1.001, (n_dot_v, coat_albedo, weight[0])
        assert (1 - weight[0]) + coat_albedo <= 1.0 + 1e-3


CAMERA = pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=30.0)
CENTRE = (16, 16)  # of a 33 x 33 image: its ray meets the quad head on, v = n


def coat_scene(material, light=None, environment=None):
    scene = pw.Scene()
    scene.add_mesh(quad(material=material))
    if light is not None:
        scene.add_light(light)
    scene.environment = environment
    return scene


def test_head_on_radiance_is_the_layered_sum():
    """A white Lambert quad under a coat (clearcoat 0.7, roughness 0.4) lit by E lux from l,
    seen head on (v = n): L = E n.l ((1 - w) / pi + w D V), w = 0.7 F(1) = 0.7 * 0.04."""
    l = ref.normalize(np.array([0.3, 0.2, 1.0]))
    irradiance = 2.0
    material = pw.Material(base_color=(1.0, 1.0, 1.0), roughness=1.0, specular=0.0, clearcoat=0.7,
                           clearcoat_roughness=0.4)
    frame = render_checked(coat_scene(material, pw.DirectionalLight(direction=-l, intensity=irradiance)), CAMERA)
    n = np.array([[0.0, 0.0, 1.0]])
    weight, coat = coat_reference(n, n, l[None], np.array([0.7]), np.array([0.4]),
                                  lambda c: 0.04 + 0.96 * (1 - c) ** 5)
    want = irradiance * l[2] * ((1 - weight[0]) / np.pi + coat[0])
    np.testing.assert_allclose(frame.rgb[CENTRE], want, rtol=1e-4)


def test_the_coat_darkens_emission_by_its_fresnel():
    """The coat lies over emission: seen head on, emission times 1 - clearcoat 0.04."""
    material = pw.Material(base_color=(0.2, 0.2, 0.2), emissive=(1.0, 2.0, 3.0), clearcoat=0.5)
    frame = render_checked(coat_scene(material), CAMERA)
    np.testing.assert_allclose(frame.rgb[CENTRE], np.array([1.0, 2.0, 3.0]) * (1 - 0.5 * 0.04), rtol=1e-5)


@pytest.mark.parametrize("coat_roughness,least", [(0.0, 0.97), (0.5, 0.75)])
def test_white_furnace_under_environment_light(coat_roughness, least):
    """A white Lambert sphere under a full coat in a uniform environment of radiance 1 reflects
    (1 - w) + w (A + B) <= 1 at every pixel (split sum): nearly 1 for a smooth coat, whose lobe
    keeps what it reflects (A + B ~ 1); less at the grazing rims of a rough one, whose single
    scattering loses light there (A + B ~ 0.6 where w ~ 0.5)."""
    material = pw.Material(base_color=(1.0, 1.0, 1.0), roughness=1.0, specular=0.0, clearcoat=1.0,
                           clearcoat_roughness=coat_roughness)
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=4), material)
    scene.environment = pw.Environment.uniform(intensity=1.0)
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 4), target=(0, 0, 0)), size=(48, 48),
                           background=(0.0, 0.0, 0.0))
    covered = frame.alpha == 1.0
    assert covered.sum() > 500
    assert frame.rgb[covered].max() <= 1.0 + 2e-3
    assert frame.rgb[covered].min() >= least


def textured_quad_scene(**material):
    fields = dict(base_color=(0.6, 0.3, 0.2), roughness=0.7, clearcoat=1.0, clearcoat_roughness=0.2)
    scene = coat_scene(pw.Material(**{**fields, **material}), pw.PointLight(position=(0.5, 0.8, 2.0), intensity=8.0))
    return scene


def test_textures_scale_the_factors_from_their_channels():
    """clearcoatTexture's R scales the factor (R = 0: no coat at all); clearcoatRoughnessTexture's
    G scales the roughness (G = 0.5 on 0.8 is roughness 0.4); other channels are ignored."""
    plain = render_checked(textured_quad_scene(clearcoat=0.0), CAMERA).rgb
    no_coat = np.zeros((4, 4, 3), np.float32)
    no_coat[..., 1:] = 1.0
    np.testing.assert_array_equal(render_checked(textured_quad_scene(clearcoat_texture=no_coat), CAMERA).rgb, plain)
    half = np.zeros((4, 4, 3), np.float32)
    half[..., 1] = 0.5
    half[..., 0] = half[..., 2] = 0.1
    textured = render_checked(textured_quad_scene(clearcoat_roughness=0.8, clearcoat_roughness_texture=half), CAMERA)
    direct = render_checked(textured_quad_scene(clearcoat_roughness=0.4), CAMERA)
    np.testing.assert_allclose(textured.rgb, direct.rgb, rtol=1e-5)
    assert not np.allclose(direct.rgb, plain)


def normal_map(direction):
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return np.broadcast_to((d + 1) / 2, (4, 4, 3)).astype(np.float32).copy()


def test_the_coat_has_its_own_normal():
    """Without clearcoatNormalTexture the coat follows the interpolated normal, not the base's
    normal map (a flat coat normal map changes nothing); a tilted coat normal map moves the coat's
    highlight."""
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    tilted = normal_map([0.4, 0.0, 0.9])

    def render(**material):
        fields = dict(base_color=(0.6, 0.3, 0.2), roughness=0.7, clearcoat=1.0, clearcoat_roughness=0.15)
        scene = pw.Scene()
        scene.add_mesh(quad(material=pw.Material(**{**fields, **material}), tangents=tangents))
        scene.add_light(pw.PointLight(position=(0.3, 0.3, 2.0), intensity=8.0))
        return render_checked(scene, CAMERA).rgb

    base_mapped = render(normal_texture=tilted)
    flat_coat = render(normal_texture=tilted, clearcoat_normal_texture=normal_map([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(flat_coat, base_mapped, rtol=1e-5, atol=1e-7)
    coat_mapped = render(clearcoat_normal_texture=tilted)
    smooth = render()
    assert np.abs(coat_mapped - smooth).max() > 0.1 * smooth.max()
    # the coat's sharp highlight moves; the base's broad light stays where it was
    assert np.unravel_index(np.argmax(coat_mapped.sum(-1)), coat_mapped.shape[:2]) != \
        np.unravel_index(np.argmax(smooth.sum(-1)), smooth.shape[:2])


def test_clearcoat_is_compiled_in_only_when_a_material_has_a_coat():
    light = pw.DirectionalLight(direction=(-0.3, -0.5, -1.0), intensity=3.0)
    bare = coat_scene(pw.Material(), light)
    features = scene_features(bare, upload(bare), shadows=True, spp=1)
    assert not features.clearcoat and not features.clearcoat_textures
    assert "no clear coat: every clearcoat factor is 0" in pw.explain(bare)
    assert "clearcoat_brdf" not in generated_source(render_kernel(features))
    coated = coat_scene(pw.Material(clearcoat=1.0, clearcoat_texture=np.ones((2, 2, 3), np.float32)), light)
    features = scene_features(coated, upload(coated), shadows=True, spp=1)
    assert features.clearcoat and features.clearcoat_textures
    text = pw.explain(coated)
    assert "clear coat (KHR_materials_clearcoat): 1 material" in text and "clearcoat textures: 1 of 1 meshes" in text
    unused = coat_scene(pw.Material(clearcoat_texture=np.ones((2, 2, 3), np.float32)), light)
    assert "no clearcoat textures read: no clearcoat layer" in pw.explain(unused)


@pytest.mark.parametrize("spp", [1, 4])
def test_specialized_image_equals_the_all_effects_image(spp):
    """Coat textures, a coat normal map, a base normal map, lights and an environment."""
    rng = np.random.default_rng(3)
    material = pw.Material(base_color=(0.5, 0.2, 0.1), roughness=0.6, clearcoat=0.9, clearcoat_roughness=0.3,
                           clearcoat_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32),
                           clearcoat_roughness_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32),
                           clearcoat_normal_texture=normal_map([0.2, -0.1, 0.95]),
                           emissive=(0.05, 0.02, 0.0))
    scene = pw.Scene()
    scene.add_mesh(quad(material=material, tangents=np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))))
    scene.add_light(pw.PointLight(position=(0.5, 0.8, 2.0), intensity=8.0))
    scene.environment = pw.Environment.uniform(intensity=0.3)
    cam = pw.Camera.look_at(eye=(0.5, 0.6, 3.0), target=(0, 0, 0))
    special = render_checked(scene, cam, size=(40, 32), spp=spp)
    general = render_checked(scene, cam, size=(40, 32), spp=spp, specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)


def test_every_clearcoat_property_is_read_from_gltf(tmp_path):
    path = material_extension_file(tmp_path, "KHR_materials_clearcoat", {
        "clearcoatFactor": 0.8, "clearcoatRoughnessFactor": 0.25, "clearcoatTexture": {"index": 0},
        "clearcoatRoughnessTexture": {"index": 0}, "clearcoatNormalTexture": {"index": 0, "scale": 0.5}},
        required=True)
    m = loaded_material(path)
    assert (m.clearcoat, m.clearcoat_roughness, m.clearcoat_normal_scale) == (0.8, 0.25, 0.5)
    slots = {slot: srgb for slot, _, srgb in m.textures()}
    assert slots == {"clearcoat_texture": False, "clearcoat_roughness_texture": False,
                     "clearcoat_normal_texture": False}
    assert load_gltf(path).primitives[0].tangents is not None  # generated for the coat's normal map
    plain = Builder()
    plain.json["materials"] = [{}]
    plain.node(mesh=plain.quad(material=0))
    m = load_gltf(plain.glb(tmp_path / "plain.glb")).primitives[0].material
    assert (m.clearcoat, m.clearcoat_roughness, m.clearcoat_normal_scale) == (0.0, 0.0, 1.0)


def test_clearcoat_board_combines_both_columns_highlights():
    """ClearCoatTest's first row ("Simple coating"): a rough red base (roughness 0.44), the same
    base under a coat of roughness 0.03, and the coat alone (a black material of roughness 0.03).
    Its README: the middle column shows the highlights of both outer ones. Each sample seen from
    the same place relative to it, under one directional light: the coated sample has the coat's
    sharp highlight exactly where the coat alone has it, far brighter than the base's broad one;
    elsewhere it shows the base darkened by the coat's Fresnel, about 4%: coated ~ 0.96 base + coat."""
    scene = pw.Scene.load(board("ClearCoatTest"))
    scene.add_light(pw.DirectionalLight(direction=(-0.2, -0.2, -1.0), intensity=3.0))
    row_y = 5.25
    seen = {}
    for name, x in (("base", -2.1), ("coated", 0.0), ("coat_only", 2.1)):
        cam = pw.Camera.look_at(eye=(x, row_y, 12.0), target=(x, row_y, 0.0), fov_y=8.0)
        seen[name] = render_checked(scene, cam, size=(48, 48), spp=4).rgb @ np.array([0.2126, 0.7152, 0.0722])
    base, coated, coat_only = seen["base"], seen["coated"], seen["coat_only"]
    peak = {name: np.unravel_index(np.argmax(image), image.shape) for name, image in seen.items()}
    assert peak["coated"] == peak["coat_only"]
    assert coated.max() > 2 * base.max() and coated.max() > coat_only.max()
    body = (coat_only < 0.01 * coat_only.max()) & (base > 0.1 * base.max())
    assert 0.9 < np.median(coated[body] / base[body]) < 0.97
    np.testing.assert_allclose(coated.sum(), 0.96 * base.sum() + coat_only.sum(), rtol=0.03)


@pytest.mark.parametrize("body,field", [({"clearcoatFactor": 2.0}, "clearcoat"),
                                        ({"clearcoatRoughnessFactor": -0.5}, "clearcoat_roughness"),
                                        ({"clearcoatFactor": "full"}, "clearcoat")])
def test_out_of_range_clearcoat_values_are_refused_with_their_name(tmp_path, body, field):
    b = Builder()
    b.json["materials"] = [{"extensions": {"KHR_materials_clearcoat": body}}]
    b.node(mesh=b.quad(material=0))
    with pytest.raises(AssetFormatError, match=f"Material.{field}"):
        load_gltf(b.glb(tmp_path / "bad.glb"))
