"""KHR_materials_transmission, _volume and _ior, ray traced: camera rays pass through smooth
transmissive surfaces, straight on through thin walls, refracted into and out of volumes with
Beer-Lambert absorption inside and total internal reflection."""

import math
import warnings

import numpy as np
import pytest
import trimesh
import warp as wp

import pbrwarp as pw
from pbrwarp.features import scene_features
from pbrwarp.gpu_scene import upload
from pbrwarp.kernels.transmission import (beer_lambert, refract, refract_through, sample_rough_interface,
                                          sample_thin_lobe, transmitted_share)
from pbrwarp.scene import Primitive

import reference as ref
from assets import BOARDS, board
from scenes import head_on_camera, quad, render_checked
from goodness_of_fit import chi_square_ok

GLOW = np.array([0.2, 0.5, 0.9])  # nits of the emitter behind the glass
TINT = (0.9, 0.6, 0.3)


# ---------------------------------------------------------------------------- float64 references
def refract_reference(wi, n, eta):
    """Snell's law in float64: (refracts, direction)."""
    cos_i = np.clip(wi @ n, 0.0, 1.0)
    sin2_t = (1.0 - cos_i**2) / eta**2
    if sin2_t >= 1.0:
        return False, np.zeros(3)
    cos_t = math.sqrt(1.0 - sin2_t)
    return True, -wi / eta + (cos_i / eta - cos_t) * n


def fresnel_schlick_reference(f0, f90, cos):
    return f0 + (f90 - f0) * (1.0 - cos) ** 5


@wp.kernel
def refract_kernel(wi: wp.array(dtype=wp.vec3), n: wp.array(dtype=wp.vec3), eta: wp.array(dtype=float),
                   ok: wp.array(dtype=int), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    refracts, direction = refract(wi[i], n[i], eta[i])
    ok[i] = wp.where(refracts, 1, 0)
    out[i] = direction


def run_refract(wi, n, eta):
    count = len(eta)
    ok = wp.zeros(count, dtype=int, device="cpu")
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    wp.launch(refract_kernel, dim=count, device="cpu",
              inputs=[wp.array(wi.astype(np.float32), dtype=wp.vec3, device="cpu"),
                      wp.array(n.astype(np.float32), dtype=wp.vec3, device="cpu"),
                      wp.array(eta.astype(np.float32), dtype=float, device="cpu"), ok, out])
    return ok.numpy().astype(bool), out.numpy()


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_refraction_follows_snells_law_and_reflects_totally_past_the_critical_angle():
    rng = np.random.default_rng(3)
    count = 4000
    n = unit(rng.normal(size=(count, 3)))
    wi = unit(rng.normal(size=(count, 3)))
    wi = np.where((np.sum(wi * n, axis=1) < 0)[:, None], -wi, wi)  # on n's side
    eta = rng.choice([1.0, 1.33, 1.5, 2.4, 1 / 1.5, 1 / 2.4, 1e6], size=count)
    ok, out = run_refract(wi, n, eta)
    assert np.all(np.isfinite(out))
    for i in range(count):
        expect_ok, expect = refract_reference(wi[i].astype(np.float32).astype(float),
                                              n[i].astype(np.float32).astype(float), float(np.float32(eta[i])))
        cos_i = wi[i] @ n[i]
        critical = eta[i] < 1.0 and abs((1 - cos_i**2) / eta[i] ** 2 - 1.0) < 1e-5
        if critical:
            continue  # float32 and float64 may disagree within a rounding of the critical angle
        assert ok[i] == expect_ok, (wi[i], n[i], eta[i])
        if expect_ok:
            # cos_t = sqrt(1 - sin2_t) loses precision near the critical angle as 1 / cos_t^2
            cos2_t = 1.0 - (1.0 - cos_i**2) / eta[i] ** 2
            np.testing.assert_allclose(out[i], unit(expect), atol=2e-6 + 2e-7 / cos2_t)
            # Snell: eta sin_t = sin_i, and the ray crosses to the other side
            sin_i = np.linalg.norm(np.cross(wi[i], n[i]))
            sin_t = np.linalg.norm(np.cross(out[i], n[i]))
            assert abs(eta[i] * sin_t - sin_i) < 1e-5 * max(1.0, eta[i] * sin_t) or eta[i] > 1e5
            assert out[i] @ n[i] < 0.0
        else:
            # total internal reflection happens only leaving the denser medium past asin(eta)
            assert eta[i] < 1.0 and math.sqrt(max(0.0, 1 - cos_i**2)) > eta[i] - 1e-6


def test_grazing_and_normal_incidence_stay_finite():
    n = np.tile([0.0, 0.0, 1.0], (6, 1))
    wi = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 1e-8], [1.0, 0.0, 1e-30], [0.0, 0.0, 1.0], [0.6, 0.0, 0.8],
                   [1.0, 0.0, -1e-7]])
    ok, out = run_refract(wi, n, np.array([1.5, 1.5, 1 / 1.5, 1.5, 1e6, 1.5]))
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[3], [0.0, 0.0, -1.0], atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(out[ok], axis=1), 1.0, atol=1e-6)
    assert not ok[2]  # grazing from inside: totally reflected


@wp.kernel
def share_kernel(base: wp.array(dtype=wp.vec3), metallic: wp.array(dtype=float), t: wp.array(dtype=float),
                 specular: wp.array(dtype=float), f0: wp.array(dtype=wp.vec3), cos: wp.array(dtype=float),
                 sigma: wp.array(dtype=wp.vec3), distance: wp.array(dtype=float),
                 share: wp.array(dtype=wp.vec3), absorbed: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    share[i] = transmitted_share(base[i], metallic[i], t[i], specular[i], f0[i], cos[i])
    absorbed[i] = beer_lambert(sigma[i], distance[i])


def test_transmitted_share_and_beer_lambert_match_their_formulas():
    rng = np.random.default_rng(5)
    count = 500
    base, f0, sigma = rng.random((count, 3)), rng.random((count, 3)) * 0.2, rng.random((count, 3)) * 3.0
    sigma[::7] = 0.0
    metallic, t, specular, cos = rng.random(count), rng.random(count), rng.random(count), rng.random(count)
    distance = rng.random(count) * 2.0
    distance[::7] = np.inf  # no absorption: 1 even infinitely far
    arrays = [wp.array(a.astype(np.float32), dtype=wp.vec3 if a.ndim == 2 else float, device="cpu")
              for a in (base, metallic, t, specular, f0, cos, sigma, distance)]
    share = wp.zeros(count, dtype=wp.vec3, device="cpu")
    absorbed = wp.zeros(count, dtype=wp.vec3, device="cpu")
    wp.launch(share_kernel, dim=count, inputs=arrays + [share, absorbed], device="cpu")
    F = fresnel_schlick_reference(np.minimum(f0, 1.0) * specular[:, None], specular[:, None], cos[:, None])
    expected = base * ((1 - metallic) * t * (1 - F.max(axis=1)))[:, None]
    np.testing.assert_allclose(share.numpy(), expected, rtol=2e-5, atol=1e-7)
    with np.errstate(invalid="ignore"):
        expected = np.where(sigma > 0, np.exp(-sigma * distance[:, None]), 1.0)
    np.testing.assert_allclose(absorbed.numpy(), expected, rtol=2e-5, atol=1e-30)


def test_a_white_dielectric_reflects_and_transmits_no_more_than_arrives():
    """Energy: transmitted share + Schlick reflectance F = 1 - max(F) + F <= 1 for a white,
    non-metallic, fully transmissive dielectric at every angle."""
    for cos in np.linspace(0.0, 1.0, 101):
        F = fresnel_schlick_reference(0.04, 1.0, cos)
        assert (1 - F) + F <= 1.0 + 1e-15


# ---------------------------------------------------------------------------- rendered
def glowing(colour=GLOW):
    return pw.Material(base_color=(0.0, 0.0, 0.0), specular=0.0, emissive=tuple(colour))


def glass(**kwargs):
    return pw.Material(**{"base_color": (1.0, 1.0, 1.0), "roughness": 0.0, "transmission": 1.0, **kwargs})


def flat(mesh, material):
    """``mesh`` with its faces unshared: flat normals, as the box's faces are."""
    positions = mesh.vertices[mesh.faces].reshape(-1, 3)
    normals = np.repeat(mesh.face_normals, 3, axis=0)
    return Primitive(positions, np.arange(len(positions)).reshape(-1, 3), material, normals)


def slab(depth, material, z_top=0.5, size=4.0):
    """A closed box, flat-shaded, whose top face is at z_top, ``depth`` thick."""
    box = trimesh.creation.box(extents=(size, size, depth),
                               transform=trimesh.transformations.translation_matrix((0, 0, z_top - depth / 2)))
    return flat(box, material)


NARROW = head_on_camera(distance=3.0, fov=2.0)  # rays within 1 degree of the normal: F = f0 to 1e-12


def test_a_thin_glass_sheet_transmits_one_minus_fresnel_times_its_colour():
    """A smooth thin-walled sheet (thickness 0, ior 1.5, so f0 = 0.04) before an emitter:
    (1 - 0.04) base colour of it; no light, so the sheet itself shows nothing else."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, z=0.5, material=glass(base_color=TINT)))
    scene.add_mesh(quad(size=4.0, z=0.0, material=glowing()))
    frame = render_checked(scene, NARROW, size=(9, 9))
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), np.broadcast_to(0.96 * np.multiply(TINT, GLOW), (81, 3)),
                               rtol=1e-5)
    np.testing.assert_array_equal(frame.alpha, 1.0)


def test_a_thin_glass_sheet_over_the_background_covers_the_pixel():
    background = (0.3, 0.2, 0.1)
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, z=0.5, material=glass(base_color=TINT)))
    frame = render_checked(scene, NARROW, size=(9, 9), background=background)
    np.testing.assert_array_equal(frame.alpha, 1.0)
    np.testing.assert_allclose(frame.rgb[4, 4], 0.96 * np.multiply(TINT, background), rtol=1e-5)


@pytest.mark.parametrize("colour,distance", [((0.5, 0.8, 0.95), 1.0), ((0.1, 1.0, 0.6), 0.25)])
def test_a_volume_absorbs_by_beer_lambert_over_its_thickness(colour, distance):
    """A glass box 0.6 thick seen head-on before an emitter: (1 - 0.04) on entering, exp(-sigma
    0.6) inside with sigma = -ln(attenuationColor) / attenuationDistance, (1 - 0.04) leaving (the
    exact Fresnel of 1/1.5 at normal incidence is ((1.5 - 1) / (1.5 + 1))^2 too)."""
    depth = 0.6
    scene = pw.Scene()
    scene.add_mesh(slab(depth, glass(thickness=1.0, attenuation_color=colour, attenuation_distance=distance)))
    scene.add_mesh(quad(size=4.0, z=-0.5, material=glowing()))
    frame = render_checked(scene, NARROW, size=(9, 9))
    sigma = -np.log(colour) / distance
    expected = 0.96 * np.exp(-sigma * depth) * 0.96 * GLOW
    np.testing.assert_allclose(frame.rgb[4, 4], expected, rtol=1e-4)  # the centre ray, at normal incidence
    # the others, within a degree of it, travel up to 1 / cos(0.7 degrees) further inside
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), np.broadcast_to(expected, (81, 3)), rtol=2e-3)


def test_a_volume_refracts_what_lies_behind_it():
    """A glass slab 1 thick tilted by 40 degrees shifts what lies behind it sideways by
    t sin(i - r) / cos r, sin r = sin i / 1.5: an emitter's edge moves by that many pixels."""
    depth, angle = 1.0, math.radians(40.0)
    box = trimesh.creation.box(extents=(6, 6, depth))
    box.apply_transform(trimesh.transformations.rotation_matrix(angle, (0, 1, 0)))
    scene = pw.Scene()
    scene.add_mesh(Primitive(np.array([[0, -10, -2], [10, -10, -2], [10, 10, -2], [0, 10, -2]], float),
                             np.array([[0, 1, 2], [0, 2, 3]]), glowing()))
    camera, fov, size = head_on_camera(distance=20.0, fov=0.12), 0.12, 201  # pixels 0.015 across

    def edge_column():
        frame = render_checked(scene, camera, size=(size, 3), aovs=False)
        return int(np.argmax(frame.rgb[1, :, 2] > 0.5 * GLOW[2]))

    bare = edge_column()
    scene.add_mesh(flat(box, glass(thickness=1.0)))
    seen = edge_column()
    r = math.asin(math.sin(angle) / 1.5)
    shift = depth * math.sin(angle - r) / math.cos(r)  # towards -x, so the edge is seen further right
    pixel = 2 * 22.0 * math.tan(math.radians(fov / 2)) / 3  # at the emitter, 22 from the eye (3 rows)
    assert seen - bare == pytest.approx(shift / pixel, abs=1.5)


def prism(material):
    """A right prism along y whose cross-section is the triangle (0, 0), (0, 2), (2, 2) in (x, z):
    a horizontal top face at z = 2, a vertical face at x = 0 and the hypotenuse z = x."""
    corners = [(0.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    vertices = [(x, y, z) for y in (-1.0, 1.0) for x, z in corners]
    faces = [(0, 1, 2), (3, 5, 4), (0, 3, 4), (0, 4, 1), (1, 4, 5), (1, 5, 2), (2, 5, 3), (2, 3, 0)]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.fix_normals()  # wound outwards
    assert mesh.is_watertight and mesh.volume > 0
    return flat(mesh, material)


def test_total_internal_reflection_turns_the_ray_inside_a_prism():
    """Looking straight down into the prism: the rays meet the hypotenuse at 45 degrees, past
    the critical angle asin(1/1.5) = 41.8, reflect totally towards -x and leave through the
    vertical face to the green emitter, never reaching the red one below."""
    scene = pw.Scene()
    scene.add_mesh(prism(glass(thickness=1.0)))
    green, red = np.array([0.0, 0.7, 0.0]), np.array([0.8, 0.0, 0.0])
    scene.add_mesh(Primitive(np.array([[-1, -3, -3], [-1, 3, -3], [-1, 3, 5], [-1, -3, 5]], float),
                             np.array([[0, 1, 2], [0, 2, 3]]), glowing(green)))  # x = -1, facing +x
    scene.add_mesh(Primitive(np.array([[-3, -3, -1], [5, -3, -1], [5, 3, -1], [-3, 3, -1]], float),
                             np.array([[0, 1, 2], [0, 2, 3]]), glowing(red)))  # z = -1, facing +z
    camera = pw.Camera.look_at(eye=(1.2, 0.0, 10.0), target=(1.2, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=5.0)
    frame = render_checked(scene, camera, size=(9, 9))
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), np.broadcast_to(0.96 * 0.96 * green, (81, 3)), rtol=1e-4)


def test_a_white_glass_sheet_in_a_white_furnace_returns_no_more_than_it_receives():
    """Reflected F L plus transmitted (1 - F) L: the environment's L at every angle, never more
    but for the split-sum environment term's own error, which reflects up to 0.3 % more than F L
    at grazing angles (docs/accuracy.md)."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), glass())  # thin-walled: a soap bubble
    scene.environment = pw.Environment.uniform(intensity=1.0)
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 3.5), target=(0, 0, 0), fov_y=40.0), size=(48, 48))
    on = frame.alpha == 1.0
    assert on.sum() > 500
    assert frame.rgb[on].max() <= 1.0 + 3e-3
    assert frame.rgb[on].mean() > 0.97


def test_a_glass_ball_renders_finite_at_every_angle():
    """A smooth glass ball with interpolated normals, lights and an environment: every pixel
    finite and non-negative (render_checked), grazing ones included, at most the environment."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=2), glass(thickness=2.0, attenuation_color=(0.9, 0.5, 0.5),
                                                                      attenuation_distance=1.0))
    scene.add_mesh(quad(size=8.0, z=-1.5, material=pw.Material(base_color=(0.5, 0.5, 0.5))))
    scene.add_light(pw.PointLight(position=(2.0, 2.0, 3.0), intensity=20.0))
    scene.environment = pw.Environment.uniform(intensity=0.7)
    render_checked(scene, pw.Camera.look_at(eye=(0, 0.3, 3.2), target=(0, 0, 0), fov_y=45.0), size=(48, 48), spp=2)


def test_transmission_is_compiled_in_only_when_a_material_transmits():
    opaque = pw.Scene()
    opaque.add_mesh(quad(size=4.0, z=0.5, material=pw.Material()))
    features = scene_features(opaque, upload(opaque), shadows=True, spp=1)
    assert not features.transmission and not features.volume and not features.transmission_texture
    assert "no transmission: no transmissive material" in pw.explain(opaque)
    scene = pw.Scene()
    scene.add_mesh(slab(0.6, glass(thickness=1.0, attenuation_color=(0.5, 0.8, 0.9), roughness=0.3)))
    scene.add_mesh(quad(size=4.0, z=-0.5, material=glowing()))
    scene.environment = pw.Environment.sky()
    features = scene_features(scene, upload(scene), shadows=True, spp=1)
    assert features.transmission and features.volume
    text = pw.explain(scene)
    assert "smooth transmissive surfaces (KHR_materials_transmission: 1 material" in text
    assert "closed volumes, absorbed inside (KHR_materials_volume: 1 material)" in text
    camera = pw.Camera.look_at(eye=(1.0, 1.5, 3.0), target=(0, 0, 0), fov_y=40.0)
    special = render_checked(scene, camera, size=(32, 24))
    general = render_checked(scene, camera, size=(32, 24), specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)


def test_material_checks_its_transmission_fields():
    with pytest.raises(pw.InputError, match="transmission must lie in"):
        pw.Material(transmission=1.5)
    with pytest.raises(pw.InputError, match="attenuation_distance must be > 0"):
        pw.Material(attenuation_distance=0.0)
    with pytest.raises(pw.InputError, match="attenuation_color components must lie in"):
        pw.Material(attenuation_color=(1.0, 2.0, 1.0))
    m = pw.Material(attenuation_color=(0.5, 1.0, 0.0), attenuation_distance=2.0)
    assert m.attenuation_coefficient == (math.log(2.0) / 2.0, 0.0, math.inf)
    assert pw.Material().attenuation_coefficient == (0.0, 0.0, 0.0)


def load_board_quietly(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # rough transmission is named (only the environment is blurred)
        return pw.Scene.load(board(name))


def load_transmission_board():
    return load_board_quietly("TransmissionTest")


@pytest.mark.skipif("TransmissionTest" not in BOARDS, reason="TransmissionTest needs PBRWARP_TEST_ASSETS")
def test_transmission_board_spheres_show_what_lies_behind_them():
    """TransmissionTest: transmissive spheres before a cloth backdrop. Where a non-metallic one
    without a transmission texture is seen, darkening the backdrop darkens the pixel: the sphere
    shows what lies behind it. With every transmission factor set to 0 it does not."""
    camera = pw.Camera.frame(load_transmission_board(), aspect=1.0)
    size = (96, 96)

    def backdrop_shows(transmissive):
        """Where darkening the backdrop changes the image."""
        frames = []
        for backdrop_scale in (1.0, 0.5):
            scene = load_transmission_board()
            for prim in scene.primitives:
                if prim.material.name == "Cloth Backdrop":
                    prim.material.base_color = (backdrop_scale,) * 3
                if not transmissive:
                    prim.material.transmission = 0.0
            scene.environment = pw.Environment.uniform(intensity=1.0)
            frames.append(render_checked(scene, camera, size=size))
        return np.abs(frames[0].rgb - frames[1].rgb).max(axis=-1) > 1e-4

    def footprint(select):
        scene = pw.Scene()
        for prim in load_transmission_board().primitives:
            if select(prim.material):
                scene.add_mesh(prim)
        return render_checked(scene, camera, size=size).alpha == 1.0

    # the spheres transmitting everywhere (others' transmission textures have opaque stripes)
    glassy = footprint(lambda m: m.transmission > 0 and m.transmission_texture is None and m.metallic == 0
                       and m.alpha_mode == "OPAQUE")
    assert glassy.sum() > 40
    assert backdrop_shows(True)[glassy].mean() > 0.9
    assert backdrop_shows(False)[glassy].mean() < 0.05


def test_gltf_transmission_and_volume_are_read(tmp_path):
    from test_gltf_unhonoured import load_warned, materials, quad_file

    spec = {"name": "glass", "pbrMetallicRoughness": {"roughnessFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.8},
                           "KHR_materials_ior": {"ior": 1.33},
                           "KHR_materials_volume": {"thicknessFactor": 0.5, "attenuationColor": [0.5, 0.25, 1.0],
                                                    "attenuationDistance": 3.0}}}
    scene, messages = load_warned(quad_file(tmp_path, materials(spec)))
    assert messages == []
    m = scene.primitives[0].material
    assert (m.transmission, m.ior, m.thickness, m.attenuation_color, m.attenuation_distance) == (
        pytest.approx(0.8), pytest.approx(1.33), 0.5, (0.5, 0.25, 1.0), 3.0)
    assert m.transmissive and m.see_through


def horizon_step():
    """An environment bright (1 nit) above the horizon and black below."""
    texels = np.zeros((64, 128, 3), np.float32)
    texels[:32] = 1.0
    return pw.Environment(texels)


def column_seen_through(roughness, ior=1.5):
    """The middle column, top to bottom, of a view of the horizon through a thin glass sheet
    filling it."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, z=0.5, material=glass(roughness=roughness, ior=ior)))
    scene.environment = horizon_step()
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), fov_y=40.0), size=(5, 61))
    return frame.rgb[:, 2, 1]


def test_rough_transmission_blurs_the_environment_seen_through_it():
    """Cheap rung: the environment seen through a rough sheet is the prefiltered one at the
    sheet's roughness (times clamp(2 ior - 2, 0, 1)), so the sharp horizon seen through a smooth
    sheet spreads over many rows; an IOR of 1 bends nothing and leaves it sharp."""
    def blurred_rows(column):
        return int(np.sum((column > 0.05 * column.max()) & (column < 0.95 * column.max())))

    smooth, rough, index_matched = (column_seen_through(0.0), column_seen_through(0.6),
                                    column_seen_through(0.6, ior=1.0))
    # seen sharp, the horizon spans the 3 rows of one texel's bilinear ramp (2.8 degrees)
    assert blurred_rows(smooth) <= 4 and blurred_rows(index_matched) <= 4, (smooth, index_matched)
    assert blurred_rows(rough) >= 20, rough
    assert np.all(np.diff(rough) <= 1e-6)  # bright above, dark below: a blur, not noise


def test_transmission_blur_is_compiled_in_only_for_rough_transmission_under_an_environment():
    def features(roughness, background=None):
        scene = pw.Scene()
        scene.add_mesh(quad(size=4.0, z=0.5, material=glass(roughness=roughness)))
        scene.environment = horizon_step()
        return scene_features(scene, upload(scene), shadows=True, spp=1,
                              background_given=background is not None).rough_transmission
    assert features(0.5) and not features(0.0) and not features(0.5, background=(0, 0, 0))


@pytest.mark.skipif("AttenuationTest" not in BOARDS, reason="AttenuationTest needs PBRWARP_TEST_ASSETS")
def test_attenuation_board_shows_one_shade_per_column():
    """AttenuationTest, viewed face-on: each column of blue glass cubes (thickness by size, by
    node scale, or by attenuation distance) shows one shade, the one its top row's thin sample
    emulates with a base colour (its README); ray traced, the cubes also pass the light through a
    second interface, so they show 1 - F = 0.96 of the sample at normal incidence."""
    scene = load_board_quietly("AttenuationTest")
    scene.environment = pw.Environment.uniform(intensity=1.0)
    size = 600
    camera = pw.Camera.frame(scene, direction=(0.0, 0.0, 1.0), aspect=1.0)
    # bilinear: the grid seen through stays sharp, so each median is the backdrop's own colour
    # rather than a mip level's blend of its lines, which differs with where the lines fall
    frame = render_checked(scene, camera, size=(size, size), texture_filter="bilinear")
    eye, scale = np.asarray(camera.eye), size / 2 / math.tan(math.radians(camera.fov_y) / 2)

    def pixel(x, y, z):
        return (int(size / 2 + (x - eye[0]) / (eye[2] - z) * scale), int(size / 2 - (y - eye[1]) / (eye[2] - z) * scale))

    columns = {}
    for prim in scene.primitives:
        # the middle of each cube's front face (the thickness-texture row is one mesh: skipped)
        if prim.material.transmission == 0.0 or prim.material.name.startswith("R3"):
            continue
        lo, hi = prim.bounds()
        centre, half = (lo + hi) / 2, (hi - lo) / 2
        (x0, y0), (x1, y1) = (pixel(centre[0] - 0.4 * half[0], centre[1] + 0.4 * half[1], hi[2]),
                              pixel(centre[0] + 0.4 * half[0], centre[1] - 0.4 * half[1], hi[2]))
        shade = np.median(frame.rgb[y0:y1 + 1, x0:x1 + 1].reshape(-1, 3), axis=0)  # past the grid seen through
        columns.setdefault(round(float(centre[0])), []).append((prim.material.thickness == 0.0, shade))
    assert len(columns) == 5
    for cubes in columns.values():
        sample = [shade for thin, shade in cubes if thin]
        volumes = [shade for thin, shade in cubes if not thin]
        assert len(sample) == 1 and len(volumes) >= 3
        for shade in volumes:
            np.testing.assert_allclose(shade / sample[0], 0.96, atol=0.03)


# ---------------------------------------------------------------------------- shadows
E = 3.0
WHITE = dict(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=1.0, specular=0.0)


def floor_under(blocker):
    """A white Lambert floor at z = 0 lit straight down (along -z) by E lux, ``blocker`` above
    it, seen from below the blocker: the floor's radiance."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=20.0, z=0.0, material=pw.Material(**WHITE)))
    scene.add_mesh(blocker)
    scene.add_light(pw.DirectionalLight(direction=(0.0, 0.0, -1.0), intensity=E))
    camera = pw.Camera.look_at(eye=(0.0, 0.0, 0.4), target=(0.0, 0.0, 0.0), fov_y=20.0)
    return render_checked(scene, camera, size=(9, 9)).rgb


def test_a_glass_sheet_casts_a_tinted_shadow():
    """Under a smooth thin sheet, the floor gets (1 - F) base colour of the light, F = 0.04 at
    normal incidence: E / pi * 0.96 * base colour."""
    rgb = floor_under(quad(size=20.0, z=1.0, material=glass(base_color=TINT)))
    np.testing.assert_allclose(rgb.reshape(-1, 3), np.broadcast_to(E / math.pi * 0.96 * np.array(TINT), (81, 3)),
                               rtol=1e-5)


def test_a_glass_volume_casts_a_shadow_absorbed_along_its_chord():
    """Under a glass box 0.6 thick: E / pi * 0.96 * exp(-sigma 0.6) * 0.96."""
    colour, distance = np.array([0.5, 0.8, 0.95]), 1.0
    rgb = floor_under(slab(0.6, glass(thickness=1.0, attenuation_color=tuple(colour), attenuation_distance=distance),
                           z_top=2.0, size=20.0))
    expected = E / math.pi * 0.96 * np.exp(np.log(colour) / distance * 0.6) * 0.96
    np.testing.assert_allclose(rgb.reshape(-1, 3), np.broadcast_to(expected, (81, 3)), rtol=1e-4)


def test_an_opaque_sheet_still_shadows_fully_and_a_metal_one_too():
    assert np.all(floor_under(quad(size=20.0, z=1.0, material=pw.Material())) == 0.0)
    assert np.all(floor_under(quad(size=20.0, z=1.0, material=glass(metallic=1.0))) == 0.0)


# ---------------------------------------------------------------------------- rough, exact rung
MONTE_CARLO = pw.IBL(method="monte_carlo", samples=4)


def edge_row(roughness, ibl, spp=64):
    """The middle row of a view of an emitter's vertical edge (x >= 0) through a thin sheet of
    this roughness, in a black environment lit the ``ibl`` way."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, z=0.5, material=glass(roughness=roughness)))
    scene.add_mesh(Primitive(np.array([[0, -5, -1], [5, -5, -1], [5, 5, -1], [0, 5, -1]], float),
                             np.array([[0, 1, 2], [0, 2, 3]]), glowing()))
    scene.environment = pw.Environment.uniform(intensity=0.0)
    frame = render_checked(scene, head_on_camera(distance=3.0, fov=30.0), size=(41, 3), spp=spp, ibl=ibl)
    return frame.rgb[1, :, 2]


def test_the_exact_rung_blurs_what_lies_behind_a_rough_sheet():
    """Sampling the GGX transmission lobe spreads the emitter's sharp edge over many columns,
    where the cheap rung (which blurs only the environment) leaves it sharp; the light seen
    through is redistributed, not created."""
    def blurred_columns(row):
        return int(np.sum((row > 0.05 * row.max()) & (row < 0.95 * row.max())))

    sharp = edge_row(0.5, pw.IBL())
    sampled = edge_row(0.5, MONTE_CARLO)
    smooth = edge_row(0.0, MONTE_CARLO)
    assert blurred_columns(sharp) <= 2 and blurred_columns(smooth) <= 2  # the edge pixel, antialiased
    assert blurred_columns(sampled) >= 6, sampled
    assert sampled.sum() <= sharp.sum() * 1.02


def test_a_rough_white_sheet_in_a_white_furnace_returns_no_more_than_it_receives():
    """Never more than the environment; less, by the single-scattering loss of the sampled lobe
    (directions that reflect below a microfacet's horizon, and masking G1: about 18 % per surface
    at roughness 0.6 head-on, 11.5 % of it the GGX normals steeper than 45 degrees), which no
    multiple-scattering term restores."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3), glass(roughness=0.6))
    scene.environment = pw.Environment.uniform(intensity=1.0)
    frame = render_checked(scene, pw.Camera.look_at(eye=(0, 0, 3.5), target=(0, 0, 0), fov_y=40.0), size=(32, 32),
                           spp=16, ibl=pw.IBL(method="monte_carlo", samples=16))
    on = frame.alpha == 1.0
    assert 0.5 < frame.rgb[on].mean() <= 1.01 and frame.rgb[on].max() <= 1.2  # 16 noisy samples a pixel


def test_monte_carlo_environment_lighting_chooses_the_exact_rung():
    scene = pw.Scene()
    scene.add_mesh(quad(size=4.0, z=0.5, material=glass(roughness=0.5)))
    scene.environment = pw.Environment.uniform(intensity=1.0)
    gpu = upload(scene)
    assert scene_features(scene, gpu, shadows=True, spp=1, ibl=MONTE_CARLO).rough_transmission == "sampled"
    assert scene_features(scene, gpu, shadows=True, spp=1).rough_transmission == "prefiltered"
    assert "samples the GGX transmission lobe per camera sample" in pw.explain(scene, ibl=MONTE_CARLO)


def test_transmission_texture_varies_the_f0_mix_coupling_per_pixel():
    """The "f0" mix couples the diffuse lobe to a lobe whose f0 mixes in the base colour, which
    transmission scales per texel: the specialized kernel (which may keep that normalization
    from pixel to pixel where only the material sets it) renders what the all-effects kernel does."""
    rng = np.random.default_rng(5)
    material = pw.Material(base_color=(0.9, 0.5, 0.2), metallic=0.5, roughness=0.4, transmission=0.8,
                           transmission_texture=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32))
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0, material=material))
    scene.add_light(pw.PointLight(position=(0.5, 0.8, 2.0), intensity=8.0))
    cam = pw.Camera.look_at(eye=(0.3, 0.4, 3.0), target=(0, 0, 0))
    brdf = pw.BRDF(metallic_mix="f0")
    special = render_checked(scene, cam, size=(32, 32), brdf=brdf)
    general = render_checked(scene, cam, size=(32, 32), brdf=brdf, specialize=False)
    np.testing.assert_allclose(special.rgb, general.rgb, rtol=1e-6, atol=1e-30)


# ---------------------------------------------------------------------------- rough lobes' sampling
@wp.kernel(enable_backward=False)
def draw_lobes(d: wp.vec3, n: wp.vec3, eta: float, roughness: float, seed: int,
               interface: wp.array(dtype=wp.vec3), interface_weight: wp.array(dtype=float),
               interface_refracts: wp.array(dtype=int), thin: wp.array(dtype=wp.vec3),
               thin_weight: wp.array(dtype=float)):
    i = wp.tid()
    state = wp.rand_init(seed, i)
    u = wp.vec2(wp.randf(state), wp.randf(state))
    refracts, direction, weight = sample_rough_interface(d, n, n, eta, roughness, u)
    interface[i] = direction
    interface_weight[i] = weight
    interface_refracts[i] = wp.where(refracts, 1, 0)
    through, thin_w = sample_thin_lobe(d, n, n, roughness, u)
    thin[i] = through
    thin_weight[i] = thin_w


def draw_lobe_samples(v, eta, roughness, count=400_000, seed=3):
    """Both samplers' draws for a ray of direction -v meeting a surface of normal +z (shading and
    geometric), as float64 arrays: interface directions, weights and refraction flags; thin-wall
    directions and weights."""
    outs = [wp.zeros(count, dtype=t, device="cpu") for t in (wp.vec3, float, int, wp.vec3, float)]
    wp.launch(draw_lobes, dim=count, device="cpu",
              inputs=[wp.vec3(*(-np.asarray(v))), wp.vec3(0.0, 0.0, 1.0), eta, roughness, seed, *outs])
    return [o.numpy().astype(np.float64) for o in outs]


def g1_ggx(cos, alpha):
    """Smith's masking of GGX for a direction at cos theta to the normal (Walter et al. 2007, eq. 34)."""
    a2 = alpha**2
    return 2 * cos / (cos + np.sqrt(a2 + (1 - a2) * cos**2))


def visible_normals_pdf(m, v, alpha):
    """Heitz 2018's distribution of the GGX normals visible from v: G1(v) max(0, v.m) D(m) / v.z."""
    m_z = np.clip(m[..., 2], 0.0, 1.0)
    d = np.where(m[..., 2] > 0, ref.d_ggx(m_z, alpha), 0.0)
    return g1_ggx(v[2], alpha) * np.maximum(m @ v, 0.0) * d / v[2]


def rough_interface_pdfs(l, v, eta, alpha):
    """The solid-angle densities of a direction l drawn by refracting v through a visible GGX
    normal m (Walter et al. 2007, eq. 17: dw_m / dw_l = eta^2 |l.m| / (v.m + eta l.m)^2, with
    m = -(v + eta l) turned up), and of one reflected off m where m reflects totally
    (dw_m / dw_l = 1 / (4 v.m)); float64, (refracted, reflected)."""
    half = v + eta * l
    m_t = half * np.where(half[..., 2:] < 0, -1.0, 1.0) / np.linalg.norm(half, axis=-1, keepdims=True)
    v_m, l_m = m_t @ v, np.sum(l * m_t, -1)
    transmits = (v_m > 0) & (l_m < 0)
    refracted = np.where(transmits, visible_normals_pdf(m_t, v, alpha) * eta**2 * np.abs(l_m)
                         / np.maximum((v_m + eta * l_m) ** 2, 1e-300), 0.0)
    m_r = ref.normalize(v + l)
    v_m = m_r @ v
    total = (1 - v_m**2) / eta**2 >= 1.0
    reflected = np.where(total & (v_m > 0), visible_normals_pdf(m_r, v, alpha) / (4 * np.maximum(v_m, 1e-300)), 0.0)
    return refracted, reflected


def walter_lobe_cosine(l, v, eta, alpha):
    """Walter et al. 2007's rough dielectric BSDF times |n.l|, without its Fresnel factor (the
    caller's): the BTDF (eq. 21) below the surface, the BRDF under total internal reflection
    (F = 1) above it; separable Smith G = G1(v) G1(l); float64."""
    half = v + eta * l
    m_t = half * np.where(half[..., 2:] < 0, -1.0, 1.0) / np.linalg.norm(half, axis=-1, keepdims=True)
    v_m, l_m = m_t @ v, np.sum(l * m_t, -1)
    g = g1_ggx(v[2], alpha) * g1_ggx(np.abs(l[..., 2]), alpha)
    d_t = np.where(m_t[..., 2] > 0, ref.d_ggx(np.clip(m_t[..., 2], 0, 1), alpha), 0.0)
    btdf = (np.abs(v_m * l_m) / (v[2] * np.abs(l[..., 2])) * eta**2 * g * d_t
            / np.maximum((v_m + eta * l_m) ** 2, 1e-300))
    transmitted = np.where((l[..., 2] < 0) & (v_m > 0) & (l_m < 0), btdf * np.abs(l[..., 2]), 0.0)
    m_r = ref.normalize(v + l)
    v_m = m_r @ v
    total = ((1 - v_m**2) / eta**2 >= 1.0) & (v_m > 0) & (m_r[..., 2] > 0)
    brdf = g * ref.d_ggx(np.clip(m_r[..., 2], 0, 1), alpha) / (4 * v[2] * np.maximum(l[..., 2], 1e-300))
    reflected = np.where(total & (l[..., 2] > 0), brdf * l[..., 2], 0.0)
    return transmitted + reflected


SPHERE_STEPS = 600  # quadrature cells per unit of cos theta and per pi of phi
SPHERE_BINS = 16


def sphere_grid():
    """Midpoints of a (cos theta, phi) grid over the sphere, and each cell's solid angle."""
    mu = -1 + (np.arange(2 * SPHERE_STEPS) + 0.5) / SPHERE_STEPS
    phi = -np.pi + (np.arange(2 * SPHERE_STEPS) + 0.5) * np.pi / SPHERE_STEPS
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m**2)
    return np.stack([s * np.cos(p), s * np.sin(p), m], -1), (1 / SPHERE_STEPS) * (np.pi / SPHERE_STEPS)


def binned(density, cell):
    """A density on sphere_grid() integrated over SPHERE_BINS x SPHERE_BINS (cos theta, phi) bins."""
    k = 2 * SPHERE_STEPS // SPHERE_BINS
    return density.reshape(SPHERE_BINS, k, SPHERE_BINS, k).sum((1, 3)) * cell


def histogram(directions):
    counts, _, _ = np.histogram2d(directions[:, 2], np.arctan2(directions[:, 1], directions[:, 0]),
                                  bins=SPHERE_BINS, range=[[-1, 1], [-np.pi, np.pi]])
    return counts


LOBE_CASES = [  # (roughness, eta, angle of incidence): into glass, out of it (with total internal
    (0.3, 1.5, 0.3), (0.6, 1.5, 1.2), (1.0, 1.33, 0.7),  # reflection), near head-on and grazing
    (0.5, 1 / 1.5, 0.4), (0.8, 1 / 1.33, 1.0), (0.4, 1 / 1.5, 1.35)]


@pytest.mark.parametrize("roughness, eta, theta", LOBE_CASES)
def test_rough_interface_samples_follow_walters_transmission_lobe(roughness, eta, theta):
    """sample_rough_interface draws a visible GGX normal m (Heitz 2018) and refracts through it, or
    reflects where m reflects totally: its directions' density is the visible-normal density
    times the Jacobian of m -> direction (Walter et al. 2007), and its weight G1(l) is Walter's
    BSDF times |n.l| over that density (Fresnel aside). Chi-square over (cos theta, phi) bins,
    refracted and reflected samples counted apart."""
    alpha = roughness**2
    v = np.array([np.sin(theta), 0.0, np.cos(theta)])
    l, weight, refracts, _, _ = draw_lobe_samples(v, eta, roughness)
    refracts = refracts.astype(bool)
    grid, cell = sphere_grid()
    refracted, reflected = rough_interface_pdfs(grid, v, eta, alpha)
    # the reference density integrates to 1 (every visible normal makes one direction); no
    # reflection where light enters the denser side
    assert abs((refracted + reflected).sum() * cell - 1.0) < 3e-3
    assert eta < 1 or not reflected.any()
    counts = np.concatenate([histogram(l[refracts]).ravel(), histogram(l[~refracts]).ravel()])
    expected = np.concatenate([binned(refracted, cell).ravel(), binned(reflected, cell).ravel()]) * len(l)
    ok, stat, quantile = chi_square_ok(counts, expected)
    assert ok, (stat, quantile)
    # the weight: G1 of the new direction, 0 where it leaves on the wrong side of the surface
    wrong_side = np.where(refracts, l[:, 2] >= 0, l[:, 2] <= 0)
    np.testing.assert_array_equal(weight[wrong_side], 0.0)
    np.testing.assert_allclose(weight[~wrong_side], g1_ggx(np.abs(l[~wrong_side, 2]), alpha), rtol=1e-4)
    # which is Walter's lobe over the density drawn, on the side each part may leave by
    lobe = walter_lobe_cosine(grid, v, eta, alpha)
    kept = refracted * (grid[..., 2] < 0) + reflected * (grid[..., 2] > 0)
    np.testing.assert_allclose(lobe, kept * g1_ggx(np.abs(grid[..., 2]), alpha), rtol=1e-6, atol=1e-9 * lobe.max())


@pytest.mark.parametrize("roughness, theta", [(0.3, 0.3), (0.7, 1.2), (1.0, 0.6)])
def test_thin_lobe_samples_follow_the_mirrored_visible_normal_reflection(roughness, theta):
    """sample_thin_lobe reflects v off a visible GGX normal and mirrors the result through the
    surface's plane: below the surface, its density is the reflection's, G1(v) D(m) / (4 v.z)
    at the mirror image (Heitz 2018, eq. 17); reflections that would leave below the surface
    come back as d with weight 0, as often as the density says they happen."""
    alpha = roughness**2
    v = np.array([np.sin(theta), 0.0, np.cos(theta)])
    _, _, _, through, weight = draw_lobe_samples(v, 1.5, roughness)
    grid, cell = sphere_grid()
    mirrored = grid * [1.0, 1.0, -1.0]
    m = ref.normalize(v + mirrored)
    density = np.where(grid[..., 2] < 0, visible_normals_pdf(m, v, alpha) / (4 * np.maximum(m @ v, 1e-300)), 0.0)
    kept = weight > 0
    np.testing.assert_allclose(through[~kept], np.broadcast_to(-v, through[~kept].shape), atol=1e-6)
    counts = np.append(histogram(through[kept]).ravel(), (~kept).sum())
    expected_bins = binned(density, cell).ravel()
    expected = np.append(expected_bins, 1.0 - expected_bins.sum()) * len(through)
    ok, stat, quantile = chi_square_ok(counts, expected)
    assert ok, (stat, quantile)
    np.testing.assert_allclose(weight[kept], g1_ggx(-through[kept, 2], alpha), rtol=1e-4)
