"""Procedural scenes for the demo, the tests and the benchmarks.

>>> from pbrwarp.meshes import demo_scene
>>> scene, camera = demo_scene()
>>> pw.render(scene, camera, 960, 540, spp=4).save("demo.png")

- :func:`sphere_grid`: the metallic x roughness sphere sweep of LearnOpenGL's PBR chapter.
- :func:`brick_textures`: a tileable brick base-colour texture and its tangent-space normal map.
- :func:`normal_mapped_torus` / :func:`normal_mapped_tile`: textured, normal-mapped primitives
  with analytic normals and tangents.
- :func:`demo_scene`: both of the above, lit and framed.
- :func:`icosphere`, :func:`bunny`, :func:`mesh_scene`: meshes of known size for benchmarks.
- :func:`cornell_box`: the measured Cornell box, lit by an emissive quad, for the path tracer.

Conventions are pbrwarp's (glTF's): +Y up, UV (0, 0) at the top-left of the image, normal maps
with +X right and +Y (green) *up* in the image, bitangent = cross(normal, tangent.xyz) * w.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

import pbrwarp as pw

__all__ = [
    "ASSETS", "CORNELL_GREEN", "CORNELL_LIGHT", "CORNELL_RED", "CORNELL_WHITE", "DEMO_BACKGROUND", "SAMPLES",
    "brick_textures", "bunny", "cornell_box", "demo_scene", "height_to_normal_map",
    "icosphere", "mesh_scene", "normal_mapped_tile", "normal_mapped_torus", "sphere_grid",
]

# Sample assets installed with pbrwarp (SOURCES.md in this folder says where each comes from).
SAMPLES = Path(__file__).resolve().parent
# The larger public assets the benchmarks read (the full-size scanned meshes, the 1k HDRs, the
# Khronos glTF samples) are not part of pbrwarp: they live beside a clone, in ../shared/assets.
ASSETS = Path(__file__).resolve().parents[1].parent / "shared" / "assets"

# Background radiance the demo is meant to be rendered over (``pbrwarp demo`` uses it): a
# near-black blue-grey, so the smooth metals (black but for their highlights) keep a silhouette.
DEMO_BACKGROUND = (0.012, 0.014, 0.02)

# LearnOpenGL clamps the smoothest column to roughness 0.05: a perfectly smooth sphere under
# punctual lights reflects each light into a sub-pixel point, so its column would look empty.
MIN_GRID_ROUGHNESS = 0.05


# ---------------------------------------------------------------------- sphere grid
def icosphere(subdivisions: int = 4, radius: float = 1.0):
    """A ``trimesh.Trimesh`` icosphere of 20 * 4^``subdivisions`` triangles (default 4: 5,120)
    and ``radius`` world units (default 1), centred at the origin. InputError unless
    ``subdivisions`` is a whole number >= 0."""
    import trimesh

    if isinstance(subdivisions, bool) or not isinstance(subdivisions, (int, np.integer)) or subdivisions < 0:
        raise pw.InputError(f"icosphere subdivisions must be a whole number >= 0, got {subdivisions!r}")
    return trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=float(radius))


def sphere_grid(rows: int = 7, cols: int = 7, base_color=(0.9, 0.9, 0.9), subdivisions: int = 4,
                spacing: float = 2.5, radius: float = 1.0, min_roughness: float = MIN_GRID_ROUGHNESS) -> pw.Scene:
    """A scene of spheres (:func:`icosphere` of ``subdivisions`` and ``radius``) on a ``rows`` x
    ``cols`` grid (default 7 x 7), ``spacing`` world units apart (default 2.5), in the z = 0 plane,
    centred at the origin and facing +z, one :class:`pw.Material` of linear RGB ``base_color``
    each: metallic grows from 0 (bottom row) to 1 (top row), roughness from 0 (left column,
    clamped to ``min_roughness``, default 0.05) to 1 (right column), as in LearnOpenGL's
    "PBR / Lighting" chapter. No lights: callers add their own. InputError for ``rows`` or
    ``cols`` below 1 or a ``spacing`` not > 0.
    """
    for name, value in (("rows", rows), ("cols", cols)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise pw.InputError(f"sphere_grid {name} must be a whole number >= 1, got {value!r}")
    spacing = float(spacing)
    if not math.isfinite(spacing) or spacing <= 0.0:
        raise pw.InputError(f"sphere_grid spacing must be > 0, got {spacing}")
    sphere = icosphere(subdivisions, radius)
    # Shared geometry: normals straight from the sphere (exact), no crease splitting needed.
    normals = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    scene = pw.Scene()
    for row in range(rows):
        metallic = row / (rows - 1) if rows > 1 else 0.0
        for col in range(cols):
            roughness = max(col / (cols - 1) if cols > 1 else 0.5, min_roughness)
            material = pw.Material(base_color=base_color, metallic=metallic, roughness=roughness,
                                   name=f"metallic {metallic:.2f} roughness {roughness:.2f}")
            offset = np.array([(col - (cols - 1) / 2) * spacing, (row - (rows - 1) / 2) * spacing, 0.0])
            scene.add_mesh(pw.Primitive(sphere.vertices + offset, sphere.faces, material, normals,
                                        name=f"sphere r{row} c{col}"))
    return scene


# ---------------------------------------------------------------------- textures
def _box_blur(a: np.ndarray, radius: int) -> np.ndarray:
    """Separable periodic box blur (the textures tile, so their filters wrap around too)."""
    if radius <= 0:
        return a
    for axis in (0, 1):
        acc = np.zeros_like(a)
        for k in range(-radius, radius + 1):
            acc += np.roll(a, k, axis=axis)
        a = acc / (2 * radius + 1)
    return a


def height_to_normal_map(height: np.ndarray, strength: float = 1.0) -> np.ndarray:
    """A tangent-space normal map, an (H, W, 3) uint8 RGB array (glTF/OpenGL convention: +X
    right, +Y up in the image, i.e. green grows where the surface faces the top of the image),
    from ``height``, an (H, W) height field in texel units, by periodic central differences.

    ``strength`` (default 1) scales the heights: a slope of one height unit per texel tilts the
    normal by ``atan(strength)``. InputError unless ``height`` is 2-D.
    """
    h = np.asarray(height, dtype=np.float64)
    if h.ndim != 2:
        raise pw.InputError(f"height field must be 2-D, got shape {h.shape}")
    dh_dx = 0.5 * (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1))  # along +u (right)
    dh_drow = 0.5 * (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0))  # along +v (down the image)
    # Image "up" is -row, so dh/dup = -dh/drow; the normal of z = h(x, up) is (-dh/dx, -dh/dup, 1).
    n = np.stack([-strength * dh_dx, strength * dh_drow, np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n * 0.5 + 0.5) * 255.0).astype(np.uint8)


def brick_textures(size: int = 512, courses: int = 8, bricks_per_course: int = 4, seed: int = 7,
                   strength: float = 1.0):
    """A seamlessly tiling running-bond brick wall: ``(base_color, normal_map, height)`` with
    ``base_color`` an sRGB uint8 (size, size, 3) array, ``normal_map`` uint8 RGB from
    :func:`height_to_normal_map` and ``height`` float32 in [0, 1] (1 = brick face, 0 = mortar).
    ``size`` texels a side (default 512), ``courses`` rows of bricks (default 8) of
    ``bricks_per_course`` bricks (default 4); ``seed`` (default 7) picks the bricks' random tints
    and grain. ``strength`` is the steepness of the rounded brick edges: 1 (the default) tilts
    their normals by 45 degrees on average (56 at the steepest). InputError unless ``size`` >= 16
    is divisible by ``courses`` and by 2 ``bricks_per_course``.
    """
    if size < 16 or size % courses or size % (2 * bricks_per_course):
        raise pw.InputError("brick_textures size must be >= 16 and divisible by courses and 2 * bricks_per_course")
    rng = np.random.default_rng(seed)
    brick_h = size // courses
    brick_w = size // bricks_per_course
    mortar = max(2.0, size / 128.0)  # half-width of a mortar joint, in texels
    bevel = max(2.0, size / 64.0)    # width of the rounded brick edge

    y, x = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
    course = (y // brick_h).astype(int)
    xs = (x + (course % 2) * (brick_w / 2)) % size  # every other course shifted half a brick
    brick = (xs // brick_w).astype(int)
    brick_id = course * bricks_per_course + brick
    lx, ly = xs % brick_w, y % brick_h
    edge = np.minimum(np.minimum(lx, brick_w - lx), np.minimum(ly, brick_h - ly))  # to the joint centre
    t = np.clip((edge - mortar) / bevel, 0.0, 1.0)
    bump = t * t * (3.0 - 2.0 * t)  # smoothstep: rounded brick edges

    # per-brick tilt and surface grain, so the faces are not perfectly flat
    n_bricks = courses * bricks_per_course
    tilt = rng.normal(0.0, 0.015, size=(n_bricks, 2))
    grain = _box_blur(rng.normal(0.0, 1.0, size=(size, size)), 2)
    grain /= grain.std()
    height = bump * (0.9 + tilt[brick_id, 0] * (lx - brick_w / 2) / 8 + tilt[brick_id, 1] * (ly - brick_h / 2) / 8)
    height += 0.04 * grain * np.where(bump > 0.5, 1.0, 2.0)  # mortar is rougher than brick
    height = _box_blur(height, 1)
    height = (height - height.min()) / (height.max() - height.min())

    # colours (sRGB): red-brown bricks varying brick to brick, light grey mortar
    hue = rng.uniform(-1.0, 1.0, size=(n_bricks, 3)) * np.array([22.0, 12.0, 8.0])
    brick_rgb = np.array([150.0, 62.0, 44.0]) + hue[brick_id] * rng.uniform(0.6, 1.0)
    brick_rgb *= (0.82 + 0.18 * bump)[..., None]  # darker, worn edges
    mortar_rgb = np.array([160.0, 155.0, 145.0])
    speckle = _box_blur(rng.normal(0.0, 1.0, size=(size, size)), 1)
    colour = mortar_rgb + (brick_rgb - mortar_rgb) * bump[..., None]
    colour *= (1.0 + 0.06 * speckle)[..., None]
    base_color = np.clip(np.round(colour), 0, 255).astype(np.uint8)

    normal_map = height_to_normal_map(height * bevel, strength=strength)  # heights in texels
    return base_color, normal_map, height.astype(np.float32)


def brick_material(size: int = 512, roughness: float = 0.75, normal_scale: float = 1.0) -> pw.Material:
    """A dielectric :class:`pw.Material` of ``roughness`` (default 0.75) with :func:`brick_textures`
    of ``size`` (default 512) as base colour and normal map, the map scaled by ``normal_scale``."""
    base_color, normal_map, _ = brick_textures(size)
    return pw.Material(base_color=(1.0, 1.0, 1.0), metallic=0.0, roughness=roughness,
                       base_color_texture=pw.Texture(base_color), normal_texture=pw.Texture(normal_map),
                       normal_scale=normal_scale, name="bricks")


# ---------------------------------------------------------------------- normal-mapped models
def _grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """Two triangles per cell of an (n_v + 1) x (n_u + 1) vertex grid (row-major, u fastest)."""
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v))
    a = (j * (n_u + 1) + i).ravel()
    b, c, d = a + 1, a + (n_u + 1), a + (n_u + 2)
    return np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])


def _glTF_tangents(normals, dp_du, dp_dv) -> np.ndarray:
    """Tangents (V, 4): xyz = dP/du made unit and perpendicular to the normal, w chosen so that
    cross(n, t) w points along -dP/dv (towards the top of the image, glTF)."""
    t = dp_du - normals * np.sum(dp_du * normals, axis=1, keepdims=True)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.sign(np.sum(np.cross(normals, t) * -dp_dv, axis=1))
    w[w == 0] = 1.0
    return np.column_stack([t, w])


def _orient_faces(positions, faces, normals) -> np.ndarray:
    """``faces`` wound counter-clockwise seen from the side the vertex normals point to."""
    p0, p1, p2 = (positions[faces[:, k]] for k in range(3))
    geometric = np.cross(p1 - p0, p2 - p0)
    mean_n = normals[faces].sum(axis=1)
    flip = np.sum(geometric * mean_n, axis=1) < 0
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out


def normal_mapped_torus(major_radius: float = 2.0, minor_radius: float = 0.85, segments: int = 160,
                        rings: int = 64, repeats=(3, 1), material: pw.Material | None = None) -> pw.Primitive:
    """A :class:`pw.Primitive` torus around the +Y axis, centred at the origin, with radii
    ``major_radius`` (default 2) and ``minor_radius`` (default 0.85) in world units,
    ``segments`` x ``rings`` quads (default 160 x 64), UVs, analytic normals and tangents, and
    ``material`` (default: :func:`brick_material`'s). ``repeats``: (around the ring, around the
    tube) texture repetitions, default (3, 1); whole numbers keep the seams invisible."""
    phi = np.linspace(0.0, 2.0 * math.pi, segments + 1)   # around the Y axis -> u
    theta = np.linspace(0.0, 2.0 * math.pi, rings + 1)    # around the tube -> v
    ph, th = np.meshgrid(phi, theta)                       # shape (rings + 1, segments + 1)
    ph, th = ph.ravel(), th.ravel()
    radial = np.column_stack([np.cos(ph), np.zeros_like(ph), -np.sin(ph)])
    d_radial = np.column_stack([-np.sin(ph), np.zeros_like(ph), -np.cos(ph)])
    up = np.array([0.0, 1.0, 0.0])
    ring = major_radius + minor_radius * np.cos(th)
    positions = radial * ring[:, None] + up * (minor_radius * np.sin(th))[:, None]
    normals = radial * np.cos(th)[:, None] + up * np.sin(th)[:, None]
    ru, rv = repeats
    uvs = np.column_stack([ph / (2 * math.pi) * ru, th / (2 * math.pi) * rv])
    dp_du = d_radial * ring[:, None]                                              # * dphi/du > 0
    dp_dv = -radial * (minor_radius * np.sin(th))[:, None] + up * (minor_radius * np.cos(th))[:, None]
    tangents = _glTF_tangents(normals, dp_du, dp_dv)
    faces = _orient_faces(positions, _grid_faces(segments, rings), normals)
    return pw.Primitive(positions, faces, material or brick_material(), normals, uvs, tangents,
                        name="brick torus")


def normal_mapped_tile(size: float = 4.0, repeats: float = 1.0, material: pw.Material | None = None) -> pw.Primitive:
    """A :class:`pw.Primitive` square of ``size`` x ``size`` world units (default 4) centred in
    the z = 0 plane, facing +z, the texture upright as seen from +z (UV (0, 0) at the top-left
    corner) and repeated ``repeats`` times across (default 1), tangent +x and bitangent +y
    (w = +1); ``material`` defaults to :func:`brick_material`'s."""
    h = size / 2.0
    positions = np.array([[-h, h, 0.0], [h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]) * repeats
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    faces = np.array([[0, 2, 1], [1, 2, 3]])
    return pw.Primitive(positions, faces, material or brick_material(), normals, uvs, tangents, name="brick tile")


# ---------------------------------------------------------------------- demo
def _rotation(axis, angle):
    axis = np.asarray(axis, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                  [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                  [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]])
    m = np.eye(4)
    m[:3, :3] = r
    return m


def _translation(offset):
    m = np.eye(4)
    m[:3, 3] = offset
    return m


def demo_scene() -> tuple[pw.Scene, pw.Camera]:
    """``(scene, camera)``: the 7 x 7 sphere grid (gold-coloured, so metals are told apart from
    dielectrics by their tinted highlights), a brick torus standing to its right, a warm
    directional key light (3 lux) and two point lights in front (180 and 120 cd); the camera
    frames them for a 16:9 image. Meant to be rendered over :data:`DEMO_BACKGROUND` with the
    default ACES tone map."""
    scene = sphere_grid(base_color=(0.9, 0.6, 0.2))
    torus = normal_mapped_torus(major_radius=2.3, minor_radius=1.0)
    # stand the torus up (its hole facing the camera, turned 35 degrees to show its depth)
    transform = _translation((12.4, -0.5, 1.5)) @ _rotation((0, 1, 0), math.radians(-35.0)) @ _rotation((1, 0, 0), math.radians(80.0))
    scene.add_mesh(torus, transform=transform)
    scene.add_light(pw.DirectionalLight(direction=(-0.35, -0.45, -1.0), color=(1.0, 0.95, 0.88), intensity=3.0))
    scene.add_light(pw.PointLight(position=(-10.0, 9.0, 10.0), color=(0.85, 0.9, 1.0), intensity=180.0))
    scene.add_light(pw.PointLight(position=(14.0, -6.0, 9.0), intensity=120.0))

    camera = pw.Camera.look_at(eye=(2.9, 0.0, 30.0), target=(2.9, 0.0, 0.0), fov_y=36.0)
    return scene, camera


# ---------------------------------------------------------------------- Cornell box
# The Cornell box as measured (Cornell University Program of Computer Graphics, "Cornell Box
# Data"): corners in millimetres, x to the camera's left, y up, z away from the camera.
_CORNELL_WALLS = {
    "floor": [(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2)],
    "back wall": [(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2)],
    "right wall": [(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2)],
    "left wall": [(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0)],
}
# the opening in the ceiling the light fills, x and z ranges at the ceiling's height
_CORNELL_CEILING_Y, _CORNELL_CEILING_X, _CORNELL_CEILING_Z = 548.8, (0.0, 556.0), (0.0, 559.2)
_CORNELL_LIGHT_X, _CORNELL_LIGHT_Z = (213.0, 343.0), (227.0, 332.0)
_CORNELL_BLOCKS = {
    "short block": [(130.0, 65.0), (82.0, 225.0), (240.0, 272.0), (290.0, 114.0), 165.0],
    "tall block": [(423.0, 247.0), (265.0, 296.0), (314.0, 456.0), (472.0, 406.0), 330.0],
}
# Linear RGB reflectances of the measured white, red and green paints and the light's radiance
# (cd/m^2), the RGB values renderers commonly use for the measured spectra (Mitsuba 3's
# cornell_box(), for one).
CORNELL_WHITE = (0.885809, 0.698859, 0.666422)
CORNELL_RED = (0.570068, 0.0430135, 0.0443706)
CORNELL_GREEN = (0.105421, 0.37798, 0.076425)
CORNELL_LIGHT = (18.387, 13.9873, 6.75357)


def _quads(corners: list) -> tuple[np.ndarray, np.ndarray]:
    """(positions in metres, faces) of quads given as lists of 4 corners in millimetres."""
    positions = np.array([c for quad in corners for c in quad], dtype=np.float64) / 1000.0
    faces = np.array([[4 * i, 4 * i + 1, 4 * i + 2, 4 * i, 4 * i + 2, 4 * i + 3] for i in range(len(corners))])
    return positions, faces.reshape(-1, 3)


def _rectangle(x: tuple, z: tuple, y: float, down: bool) -> list:
    """The corners of an axis-aligned rectangle at height y, wound to face down (-y) or up."""
    corners = [(x[0], y, z[0]), (x[1], y, z[0]), (x[1], y, z[1]), (x[0], y, z[1])]
    return corners if down else corners[::-1]


def cornell_box() -> tuple[pw.Scene, pw.Camera]:
    """``(scene, camera)``: the Cornell box, as measured at Cornell (their "Cornell Box Data"
    page): a 0.556 x 0.549 x 0.559 m room with a white floor, ceiling and back wall, a red wall on
    the left and a green one on the right, two white blocks (0.165 and 0.330 m tall), and a
    0.130 x 0.105 m light in an opening of the ceiling. Every surface is Lambertian (metallic 0,
    specular 0, double-sided), coloured as :data:`CORNELL_WHITE`, :data:`CORNELL_RED` and
    :data:`CORNELL_GREEN`; the light is a quad of emissive material :data:`CORNELL_LIGHT`
    (cd/m^2), facing down, and the scene has no other light, so only the path tracer
    (``integrator="path"``) lights it. Units are metres, +Y up; the camera is the measured one,
    at (0.278, 0.273, -0.800) looking along +Z with a vertical field of view of 39.31 degrees
    (a 35 mm lens over a 25 mm square film), for a square image."""
    def paint(colour, name):
        return pw.Material(base_color=colour, metallic=0.0, specular=0.0, name=name)

    white, red, green = paint(CORNELL_WHITE, "white"), paint(CORNELL_RED, "red"), paint(CORNELL_GREEN, "green")
    scene = pw.Scene()

    def add(name, corners, material):
        positions, faces = _quads(corners)
        scene.add_mesh(pw.Primitive(positions, faces, material, name=name))

    for name, material in (("floor", white), ("back wall", white), ("left wall", red), ("right wall", green)):
        add(name, [_CORNELL_WALLS[name]], material)
    (x0, x1), (z0, z1) = _CORNELL_CEILING_X, _CORNELL_CEILING_Z
    (lx0, lx1), (lz0, lz1) = _CORNELL_LIGHT_X, _CORNELL_LIGHT_Z
    y = _CORNELL_CEILING_Y
    ceiling = [_rectangle((x0, x1), (z0, lz0), y, True), _rectangle((x0, x1), (lz1, z1), y, True),
               _rectangle((x0, lx0), (lz0, lz1), y, True), _rectangle((lx1, x1), (lz0, lz1), y, True)]
    add("ceiling", ceiling, white)
    for name, (*top, height) in _CORNELL_BLOCKS.items():
        sides = [[(top[i][0], 0.0, top[i][1]), (top[i][0], height, top[i][1]),
                  (top[(i + 1) % 4][0], height, top[(i + 1) % 4][1]), (top[(i + 1) % 4][0], 0.0, top[(i + 1) % 4][1])]
                 for i in range(4)]
        add(name, [[(x, height, z) for x, z in top]] + sides, white)
    light = pw.Material(base_color=(0.78, 0.78, 0.78), metallic=0.0, specular=0.0, emissive=CORNELL_LIGHT,
                        name="light")
    add("light", [_rectangle((lx0, lx1), (lz0, lz1), y, True)], light)
    fov = math.degrees(2.0 * math.atan(12.5 / 35.0))
    camera = pw.Camera.look_at(eye=(0.278, 0.273, -0.800), target=(0.278, 0.273, 0.0), fov_y=fov)
    return scene, camera


# ---------------------------------------------------------------------- benchmark meshes
def asset(relative: str) -> Path:
    """The path of a shared asset (``meshes/stanford-bunny.obj`` etc.) under :data:`ASSETS`;
    :class:`pw.AssetNotFoundError` if it is missing."""
    path = ASSETS / relative
    if not path.is_file():
        raise pw.AssetNotFoundError(f"shared asset not found: {path} (the larger assets are not installed "
                                    f"with pbrwarp: they are read from {ASSETS}, beside the clone)")
    return path


def bunny(decimated: bool = True):
    """The Stanford bunny as a ``trimesh.Trimesh``: the decimated one installed with pbrwarp (6,966
    triangles, watertight), or with ``decimated=False`` the full 69,451-triangle scan from the shared
    assets (:class:`pw.AssetNotFoundError` when they are not beside the clone)."""
    import trimesh

    path = SAMPLES / "bunny-decimated.off" if decimated else asset("meshes/stanford-bunny.obj")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as err:  # trimesh raises many types for corrupt files
        raise pw.AssetFormatError(f"cannot read {path}: {type(err).__name__}: {err}") from None
    return mesh


def mesh_scene(mesh, material: pw.Material | None = None, fov_y: float = 40.0) -> tuple[pw.Scene, pw.Camera]:
    """``(scene, camera)``: one mesh (a ``trimesh.Trimesh`` or :class:`pw.Primitive`) with
    ``material`` (default: grey, roughness 0.4), a camera framing it (:meth:`pw.Camera.frame`
    with ``fov_y`` degrees, default 40) and a 3 lux key light from over the camera's shoulder: a
    ready-made benchmark scene."""
    scene = pw.Scene()
    scene.add_mesh(mesh, material or pw.Material(base_color=(0.8, 0.8, 0.8), roughness=0.4))
    camera = pw.Camera.frame(scene, fov_y=fov_y)
    forward, up, right = (np.asarray(v) for v in (camera.forward, camera.up, camera.right))
    scene.add_light(pw.DirectionalLight(direction=tuple(forward - 0.7 * up - 0.4 * right), intensity=3.0))
    return scene, camera
