"""Texture filtering in the renderer: trilinear lookups over each sample's footprint against an
analytic head-on expectation and a supersampled reference; the bilinear rung; hard cases."""

import numpy as np
import pytest

import pbrwarp as pw
from pbrwarp import gpu_scene, textures
from pbrwarp.errors import InputError

from scenes import quad, render_checked
from test_mipmaps import trilinear_reference


def unlit(texture):
    """A material whose radiance is its base colour texture's texel (linear, no lights needed)."""
    return pw.Material(base_color=(1.0, 1.0, 1.0), base_color_texture=texture, unlit=True)


def random_texture(n, seed=0):
    return pw.Texture(np.random.default_rng(seed).random((n, n, 3)).astype(np.float32), srgb=False)


@pytest.mark.parametrize("visibility", ["raycast", "raster"])
@pytest.mark.parametrize("texels_per_pixel", [0.5, 2 ** 0.5, 2.0, 2 ** 2.3])
def test_head_on_plane_reads_the_level_of_its_footprint(texels_per_pixel, visibility):
    head_on_plane_check(texels_per_pixel, visibility)


@pytest.mark.parametrize("visibility", ["raycast", "raster"])
def test_footprint_of_a_surface_seen_through_a_culled_one(visibility):
    """The same plane behind a single-sided square turned away from the camera (culled, passed
    through): the footprint is that of the plane, not of the square's distance."""
    head_on_plane_check(2 ** 1.6, visibility, blocker=True)


# the head-on view: a square of HEAD_ON_SIDE carrying a HEAD_ON_TEXELS² texture, seen from
# HEAD_ON_DISTANCE in a HEAD_ON_SIZE (width, height) image
HEAD_ON_TEXELS, HEAD_ON_SIDE, HEAD_ON_SIZE, HEAD_ON_DISTANCE = 256, 2.0, (32, 24), 3.0


def head_on_camera(texels_per_pixel):
    """(camera, half the height it sees on the plane) for the head-on view at ``texels_per_pixel``,
    looking along -z at (0.1, -0.05, 0)."""
    pixel = HEAD_ON_SIDE / HEAD_ON_TEXELS * texels_per_pixel  # world units a pixel spans on the plane
    half_height = pixel * HEAD_ON_SIZE[1] / 2
    fov = 2 * np.degrees(np.arctan(half_height / HEAD_ON_DISTANCE))
    return pw.Camera.look_at(eye=(0.1, -0.05, HEAD_ON_DISTANCE), target=(0.1, -0.05, 0), fov_y=fov), half_height


@pytest.mark.parametrize("integrator", ["direct", "path"])
def test_a_sample_reads_textures_over_its_stratum_of_the_pixel(integrator):
    """With spp samples a sample's footprint is one stratum, 1/sqrt(spp) of a pixel a side: at 2
    texels per pixel, from 16 spp on (half a texel) trilinear lookups read level 0, exactly what
    the bilinear rung reads at the same samples; at 1 spp the footprint is two texels (level 1)."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=HEAD_ON_SIDE, material=pw.Material(base_color_texture=random_texture(HEAD_ON_TEXELS))))
    scene.add_light(pw.DirectionalLight(direction=(0.0, 0.0, -1.0), intensity=3.0))
    cam, _ = head_on_camera(2.0)
    for spp in (1, 16):
        trilinear, bilinear = (render_checked(scene, cam, size=HEAD_ON_SIZE, spp=spp, integrator=integrator,
                                              max_bounces=1 if integrator == "path" else None, texture_filter=f)
                               for f in ("trilinear", "bilinear"))
        difference = np.abs(trilinear.rgb - bilinear.rgb).max()
        if spp == 1:
            assert difference > 0.05  # level 1 against level 0
        else:
            assert difference < 1e-6


def head_on_plane_check(texels_per_pixel, visibility, uv_set=0, blocker=False):
    """A square of side L facing a camera at distance D: a pixel spans s = 2 D tan(fov/2) / H on
    it, so du/dx = s / L exactly and the level is log2(N s / L) for an N-texel texture (0 when
    magnified). Every pixel equals the trilinear blend of the two levels of the (tested) mip
    chain at its centre's uv, computed in float64. With ``uv_set`` 1 the texture reads uvs1,
    and uvs span a thousandth of it (their footprint would be level 0); with ``blocker`` a
    single-sided square facing away from the camera, halfway to it, covers the view."""
    n, side, (width, height), distance = HEAD_ON_TEXELS, HEAD_ON_SIDE, HEAD_ON_SIZE, HEAD_ON_DISTANCE
    texture = random_texture(n)
    texture.texcoord = uv_set
    cam, half_height = head_on_camera(texels_per_pixel)
    prim = quad(size=side, material=unlit(texture))
    if uv_set == 1:
        prim.uvs1, prim.uvs = prim.uvs, prim.uvs * 1e-3 + 0.5
    scene = pw.Scene()
    scene.add_mesh(prim)
    if blocker:
        away = quad(size=4 * side, z=distance / 2, material=pw.Material(double_sided=False))
        away.faces = away.faces[:, ::-1]
        scene.add_mesh(away)
    frame = render_checked(scene, cam, size=(width, height), visibility=visibility)
    # pixel centres on the plane, and their uv (u = (x + 1) / 2, v = (1 - y) / 2 on scenes.quad)
    px, py = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    x = 0.1 + (px * 2 / width - 1) * half_height * width / height
    y = -0.05 + (1 - py * 2 / height) * half_height
    u, v = (x + 1) / 2, (1 - y) / 2
    inside = (np.abs(x) < 0.98) & (np.abs(y) < 0.98)
    assert inside.mean() > 0.2
    level = max(np.log2(texels_per_pixel), 0.0)
    chain = textures.mip_chain(texture.texels(False))
    expected = trilinear_reference([lv.astype(np.float64) for lv in chain], u[inside], v[inside],
                                   np.full(inside.sum(), level))
    np.testing.assert_allclose(frame.rgb[inside], expected[:, :3], atol=2e-4)


def tilted_checker_scene(texels=512):
    """A large plane seen at 60 degrees from its normal, far away, carrying a texture of
    ``texels`` a side repeated 4 times: half a one-texel checker (many texels to a pixel over
    most of the plane) plus half a checker of 128-texel cells (several pixels wide)."""
    i, j = np.indices((texels, texels))
    pattern = (0.5 * ((i + j) % 2) + 0.5 * ((i // 128 + j // 128) % 2)).astype(np.float32)
    texture = pw.Texture(np.dstack([pattern] * 3), srgb=False, scale=(4.0, 4.0))
    scene = pw.Scene()
    scene.add_mesh(quad(size=40.0, material=unlit(texture)))
    tilt = np.radians(60.0)
    target = np.array([0.0, 2.0, 0.0])
    eye = target + 25.0 * np.array([0.0, -np.sin(tilt), np.cos(tilt)])
    return scene, pw.Camera.look_at(eye=tuple(eye), target=tuple(target), fov_y=30)


def test_trilinear_at_one_sample_is_close_to_a_supersampled_reference():
    """At 1 spp, bilinear lookups of a checker far finer than the pixels alias to noise;
    trilinear ones keep the coarse checker and average the fine one, as the pixel averages of
    the supersampled (256 spp) bilinear reference do: its error is a fraction of bilinear's, and
    below that of bilinear at 4 spp."""
    scene, cam = tilted_checker_scene()
    size = (48, 36)
    reference = render_checked(scene, cam, size=size, spp=256, texture_filter="bilinear")
    covered = reference.alpha == 1.0
    assert covered.mean() > 0.8

    def rms(**options):
        frame = render_checked(scene, cam, size=size, **options)
        return float(np.sqrt(np.mean((frame.rgb[covered] - reference.rgb[covered]) ** 2)))

    # the analytic mean of the texture, 0.5, is what the reference's pixels average to; its
    # coarse checker stays (a contrast of 0.5 where resolved)
    assert abs(reference.rgb[covered].mean() - 0.5) < 0.01 and reference.rgb[covered].std() > 0.15
    trilinear, bilinear = rms(), rms(texture_filter="bilinear")
    assert bilinear > 0.09
    assert trilinear < 0.06
    assert trilinear < 0.4 * bilinear
    assert trilinear < rms(texture_filter="bilinear", spp=4)


def test_bilinear_rung_reads_level_zero():
    """texture_filter="bilinear" is the full-resolution image whatever the footprint: a head-on
    plane at 4 texels a pixel shows level 0's texels at the pixel centres."""
    n, side, width, height, distance = 64, 2.0, 16, 16, 3.0
    texture = random_texture(n, seed=5)
    half = side / n * 4 * height / 2
    scene = pw.Scene()
    scene.add_mesh(quad(size=side, material=unlit(texture)))
    cam = pw.Camera.look_at(eye=(0, 0, distance), target=(0, 0, 0), fov_y=2 * np.degrees(np.arctan(half / distance)))
    frame = render_checked(scene, cam, size=(width, height), texture_filter="bilinear")
    px, py = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    u = ((px * 2 / width - 1) * half + 1) / 2
    v = (1 - (1 - py * 2 / height) * half) / 2
    level0 = [texture.texels(False).astype(np.float64)]
    expected = trilinear_reference(level0, u.ravel(), v.ravel(), np.zeros(u.size))
    np.testing.assert_allclose(frame.rgb.reshape(-1, 3), expected[:, :3], atol=2e-4)


def test_grazing_views_and_degenerate_uvs_stay_finite():
    """Planes seen edge-on and from just above, triangles whose UVs are all equal, collinear or
    huge, and 1 x 1 and odd-sized textures: finite images (render_checked), trilinear or not."""
    scene = pw.Scene()
    rng = np.random.default_rng(2)
    for k, (uvs, n) in enumerate([(None, 7), (np.full((4, 2), 0.3), 5), (np.array([[0, 0], [1, 1], [2, 2], [3, 3.0]]), 1),
                                  (np.array([[0, 0], [1e7, 0], [1e7, 1e7], [0, 1e7]]), 9)]):
        texture = pw.Texture(rng.random((n, n + 2, 4)).astype(np.float32), srgb=False)
        prim = quad(size=2.0, material=unlit(texture))
        if uvs is not None:
            prim.uvs = uvs
        shift = np.eye(4)
        shift[0, 3] = 2.1 * k
        scene.add_mesh(prim, transform=shift)
    for eye in ((3.0, -10.0, 1e-4), (3.0, -10.0, 0.0), (3.0, -30.0, 0.01), (3.0, -0.5, 0.5)):
        cam = pw.Camera.look_at(eye=eye, target=(3.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov_y=60)
        for texture_filter in ("trilinear", "bilinear"):
            render_checked(scene, cam, size=(24, 16), texture_filter=texture_filter)


def test_texture_filter_is_validated():
    scene = pw.Scene()
    scene.add_mesh(quad(material=unlit(random_texture(4))))
    for bad in ("nearest", "Trilinear", None, 3):
        with pytest.raises(InputError, match="texture_filter must be one of 'trilinear', 'bilinear'"):
            pw.render(scene, width=4, height=4, texture_filter=bad)
        with pytest.raises(InputError, match="texture_filter"):
            pw.explain(scene, texture_filter=bad)
    assert "textures filtered trilinearly" in pw.explain(scene)
    assert "textures filtered bilinearly" in pw.explain(scene, texture_filter="bilinear")
    bare = pw.Scene()
    bare.add_mesh(quad())
    assert "no texture filtering: no textures read" in pw.explain(bare)


def test_texel_limit_counts_the_mip_levels(monkeypatch):
    """An 8 x 8 texture holds 64 texels and 85 with its levels: a limit between them refuses it,
    with an error naming the levels, before anything reaches Warp."""
    scene = pw.Scene()
    scene.add_mesh(quad(material=unlit(random_texture(8))))
    assert textures.mip_texel_count(8, 8) == (4, 85)
    assert textures.mip_texel_count(5, 3) == (3, 15 + 2 + 1)
    monkeypatch.setattr(gpu_scene, "MAX_ELEMENTS", 80)
    with pytest.raises(InputError, match="mip levels"):
        gpu_scene.upload(scene)
    monkeypatch.setattr(gpu_scene, "MAX_ELEMENTS", 85)
    gpu_scene.upload(scene)


def test_cli_texture_filter(tmp_path):
    from pbrwarp.cli import main

    import trimesh

    mesh = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=1).export(mesh)
    out = tmp_path / "out.png"
    assert main(["render", str(mesh), "-o", str(out), "--size", "8x8", "--texture-filter", "bilinear"]) == 0
    assert out.exists()
    assert main(["render", str(mesh), "-o", str(out), "--size", "8x8", "--texture-filter", "nearest"]) == 2


def test_footprint_behind_a_refracting_slab_is_the_pencils_not_the_shift():
    """A magnified texture (about 0.7 texels a pixel: level 0) seen obliquely through a smooth
    glass slab 2 units thick. Refraction shifts each ray sideways by several texels, but a pencil
    of rays a pixel wide stays about as wide: the footprint is still below a texel, so trilinear
    lookups read level 0 and equal bilinear ones."""
    scene = pw.Scene()
    scene.add_mesh(quad(size=2.0, material=unlit(random_texture(32))))
    slab = quad(size=8.0, z=2.5, material=pw.Material(transmission=1.0, thickness=2.0, roughness=0.0))
    back = quad(size=8.0, z=0.5, material=pw.Material(transmission=1.0, thickness=2.0, roughness=0.0))
    back.faces = back.faces[:, ::-1]
    back.normals = -back.normals
    scene.add_mesh(slab)
    scene.add_mesh(back)
    cam = pw.Camera.look_at(eye=(1.2, 0.6, 4.5), target=(0.0, 0.0, 0.0), fov_y=20.0)
    trilinear = render_checked(scene, cam, size=(48, 32), background=(0.0, 0.0, 0.0))
    bilinear = render_checked(scene, cam, size=(48, 32), background=(0.0, 0.0, 0.0), texture_filter="bilinear")
    seen = bilinear.rgb.max(axis=2) > 0.05
    assert seen.mean() > 0.3
    np.testing.assert_allclose(trilinear.rgb[seen], bilinear.rgb[seen], atol=1e-4)
