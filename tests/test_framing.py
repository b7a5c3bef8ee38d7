"""Camera.frame fills the view: every vertex projects inside the image, the projection is
centred, and along the tighter axis it spans 1/margin of the image, for any aspect ratio and
view direction. Projections are computed here in float64 from the pinhole model."""

import math

import numpy as np
import pytest
import trimesh

import pbrwarp as pw
from assets import GLTF

ASPECTS = [0.25, 1.0, 4.0 / 3.0, 16.0 / 9.0, 4.0]
DIRECTIONS = [(0.6, 0.45, 1.0), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1), (1, 1, 1),
              (-0.2, 0.9, -0.4), (1e-12, 1.0, 0.0)]


def ndc(camera: pw.Camera, points: np.ndarray, aspect: float) -> np.ndarray:
    """(N, 2) normalized image coordinates of ``points``: -1..1 across the image's width and
    height, +y up, as the render kernel casts its rays (kernels/camera.py)."""
    forward, up = np.asarray(camera.forward), np.asarray(camera.up)
    right = np.cross(forward, up)
    rel = points - np.asarray(camera.eye)
    depth = rel @ forward
    assert np.all(depth > 0), "a vertex behind the eye"
    tan_half = math.tan(math.radians(camera.fov_y) / 2.0)
    return np.stack([rel @ right / (depth * tan_half * aspect), rel @ up / (depth * tan_half)], axis=1)


def vertices(scene) -> np.ndarray:
    return np.concatenate([p.positions for p in scene.primitives])


def assert_fills_the_view(scene, camera, aspect, margin=1.1, tolerance=1e-9):
    xy = ndc(camera, vertices(scene), aspect)
    low, high = xy.min(axis=0), xy.max(axis=0)
    reach = 1.0 / margin
    assert np.all(high <= reach + tolerance) and np.all(low >= -reach - tolerance), (low, high)
    np.testing.assert_allclose(high + low, 0.0, atol=tolerance)  # centred along both axes
    assert np.max(high) >= reach - tolerance, (low, high)  # the tighter axis is filled


def mesh_scene(*meshes):
    scene = pw.Scene()
    for mesh in meshes:
        scene.add_mesh(mesh)
    return scene


def random_scene(seed):
    """A box of random proportions, turned and moved at random, with an icosphere beside it."""
    rng = np.random.default_rng(seed)
    box = trimesh.creation.box(extents=rng.uniform(0.05, 3.0, 3))
    box.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
    box.apply_translation(rng.normal(0.0, 5.0, 3))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=rng.uniform(0.1, 2.0))
    ball.apply_translation(box.centroid + rng.normal(0.0, 2.0, 3))
    return mesh_scene(box, ball)


@pytest.mark.parametrize("aspect", ASPECTS)
@pytest.mark.parametrize("direction", DIRECTIONS)
def test_random_scenes_fill_the_view(aspect, direction):
    for seed in range(3):
        scene = random_scene(seed)
        assert_fills_the_view(scene, pw.Camera.frame(scene, direction=direction, aspect=aspect), aspect)


@pytest.mark.parametrize("aspect", ASPECTS)
@pytest.mark.parametrize("margin", [1.0, 1.05, 1.5])
def test_margin_and_field_of_view(aspect, margin):
    scene = random_scene(7)
    for fov in (10.0, 45.0, 120.0):
        camera = pw.Camera.frame(scene, aspect=aspect, margin=margin, fov_y=fov)
        assert camera.fov_y == fov
        assert_fills_the_view(scene, camera, aspect, margin)


@pytest.mark.parametrize("shape", ["flat", "rod", "far", "tiny", "huge"])
def test_awkward_shapes(shape):
    """A plane seen edge-on and face-on, a thin rod seen end-on, a scene far from the origin,
    tiny and huge scenes."""
    if shape == "flat":
        mesh = trimesh.Trimesh([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], [[0, 1, 2], [0, 2, 3]])
    elif shape == "rod":
        mesh = trimesh.creation.cylinder(radius=1e-3, height=10.0)
    else:
        mesh = trimesh.creation.icosphere(subdivisions=2)
        mesh.apply_scale({"far": 1.0, "tiny": 1e-6, "huge": 1e6}[shape])
        if shape == "far":
            mesh.apply_translation((1e6, -2e6, 5e5))
    scene = mesh_scene(mesh)
    for direction in ((0, 1, 0), (1, 0, 0), (0, 0, 1), (0.3, 0.2, 1.0)):
        for aspect in (0.5, 16 / 9):
            camera = pw.Camera.frame(scene, direction=direction, aspect=aspect)
            tolerance = 1e-6 if shape == "far" else 1e-9
            assert_fills_the_view(scene, camera, aspect, tolerance=tolerance)


def test_the_up_vector_is_kept_or_replaced_where_degenerate():
    scene = random_scene(3)
    cam = pw.Camera.frame(scene, direction=(1.0, 0.2, 0.5), up=(0, 0, 1))
    forward = -np.array([1.0, 0.2, 0.5]) / np.linalg.norm([1.0, 0.2, 0.5])
    upright = np.array([0.0, 0.0, 1.0]) - forward[2] * forward  # a Z-up scene stays upright
    np.testing.assert_allclose(cam.up, upright / np.linalg.norm(upright), atol=1e-15)
    top = pw.Camera.frame(scene, direction=(0, 1, 0))  # from straight above, +Y up: -Z at the top
    np.testing.assert_allclose(top.forward, (0, -1, 0), atol=1e-15)
    np.testing.assert_allclose(top.up, (0, 0, -1), atol=1e-15)
    along_z = pw.Camera.frame(scene, direction=(0, 0, 1), up=(0, 0, 1))
    np.testing.assert_allclose(along_z.up, (0, 1, 0), atol=1e-15)


@pytest.mark.parametrize("kw,match", [
    (dict(direction=(0, 0, 0)), "direction"), (dict(direction=(math.nan, 0, 1)), "direction"),
    (dict(up=(0, 0, 0)), "up"), (dict(aspect=0.0), "aspect"), (dict(aspect=math.inf), "aspect"),
    (dict(margin=-1.0), "margin"), (dict(fov_y=180.0), "fov_y"),
])
def test_bad_framing_arguments(kw, match):
    with pytest.raises(pw.InputError, match=match):
        pw.Camera.frame(random_scene(0), **kw)


@pytest.mark.parametrize("size", [(64, 48), (48, 64), (80, 20)])
def test_the_rendered_silhouette_spans_the_view(size):
    """Rendered (not only projected): the sphere's coverage reaches 1/margin of the image along
    the tighter axis, centred, and no pixel at the border is covered. ``render`` without a camera
    frames the scene for its own size."""
    width, height = size
    scene = mesh_scene(trimesh.creation.icosphere(subdivisions=4))
    for camera in (pw.Camera.frame(scene, aspect=width / height), None):
        frame = pw.render(scene, camera, width=width, height=height, progress=False)
        covered = frame.alpha > 0
        columns, rows = np.flatnonzero(covered.any(axis=0)), np.flatnonzero(covered.any(axis=1))
        spans = (columns[-1] - columns[0] + 1) / width, (rows[-1] - rows[0] + 1) / height
        assert max(spans) == pytest.approx(1 / 1.1, abs=2.5 / min(size)), spans
        assert abs(columns[0] - (width - 1 - columns[-1])) <= 1 and abs(rows[0] - (height - 1 - rows[-1])) <= 1
        assert not (covered[0].any() or covered[-1].any() or covered[:, 0].any() or covered[:, -1].any())


def test_real_models_fill_the_view():
    """Every glTF model: projected for several aspects and directions, and rendered at 640 x 480
    scaled down to 64 x 48, where it spans ~1/1.1 of the view (the DamagedHelmet spanned about a
    fifth of the frame's area when the bounding sphere was fitted to the vertical field of view)."""
    for path in GLTF:
        scene = pw.Scene.load(path)
        for aspect in (0.5, 1.0, 4 / 3, 16 / 9):
            for direction in ((0.6, 0.45, 1.0), (0, 1, 0), (-1, 0.2, -0.3)):
                assert_fills_the_view(scene, pw.Camera.frame(scene, direction=direction, aspect=aspect), aspect,
                                      tolerance=1e-7)
        frame = pw.render(scene, pw.Camera.frame(scene, aspect=64 / 48), width=64, height=48, aovs=False,
                          shadows=False, progress=False)
        covered = frame.alpha > 0
        columns, rows = np.flatnonzero(covered.any(axis=0)), np.flatnonzero(covered.any(axis=1))
        spans = (columns[-1] - columns[0] + 1) / 64, (rows[-1] - rows[0] + 1) / 48
        assert max(spans) > 1 / 1.1 - 3 / 48, (path.name, spans)


def test_a_scene_too_large_to_frame_in_float32_is_refused():
    mesh = trimesh.creation.box(extents=(3e38, 3e38, 3e38))  # within float32, but seen from 5e38 away
    with pytest.raises(pw.InputError, match="float32"):
        pw.Camera.frame(mesh_scene(mesh))


def test_a_scene_collapsed_to_a_point_gets_a_usable_camera():
    scene = mesh_scene(trimesh.Trimesh([[1.0, 2.0, 3.0]] * 3, [[0, 1, 2]], process=False))
    camera = pw.Camera.frame(scene)
    assert np.all(np.isfinite(camera.eye))
    assert np.dot(np.subtract((1.0, 2.0, 3.0), camera.eye), camera.forward) > 0  # in front of the eye
    assert pw.check(pw.render(scene, camera, width=8, height=8, progress=False)).ok
