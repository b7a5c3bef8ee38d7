"""Shadow maps, the fast shadow rung: a depth map per light rendered by the rasterizer, looked up
with percentage-closer filtering instead of tracing a shadow ray (kernels/shadow_map.py)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import validate
from .errors import InputError
from .lights import DIRECTIONAL, SPOT
from .parallel import run_all, thread_count
from .raster import decode, reused_buffer, visibility_buffer
from pbrwarp.kernels.camera import CameraData
from pbrwarp.kernels.loading import load_for_cpu
from pbrwarp.kernels.shadow_map import ShadowMaps, ShadowView, cut_out_pass

# A directional light's map is a parallel projection from a plane this many scene radii behind
# the scene's centre, so that every triangle lies in front of it.
DIRECTIONAL_VIEW_DISTANCE_RADII = 2.0
# Spot lights whose cone fits a view this wide get one map; wider ones get a cube of six.
MAX_SPOT_VIEW_HALF_ANGLE = math.radians(60.0)
# Launches per thread of the pass that ray casts texels showing alpha-masked triangles.
ROW_BLOCKS_PER_THREAD = 4
CUBE_DIRECTIONS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))


@dataclass(frozen=True)
class ShadowMap:
    """Shadow-map settings, passed as ``pw.render(..., shadows=pw.ShadowMap(...))``
    (``shadows="map"`` uses the defaults).

    - ``resolution``: texels per side of each map, 16 to 8192 (default 1024); point lights and
      spot lights wider than 60 degrees (half-angle) use six maps.
    - ``bias``: the receiver is moved this many texels (at its own depth) off its surface along
      its normal and may lie as many texels behind the stored depth, >= 0 (default 1.5): larger
      removes acne on steep slopes, smaller keeps contact shadows (peter-panning).
    - ``pcf``: side of the square of texels averaged by percentage-closer filtering, 1 to 9
      (default 3); 1 gives hard, aliased edges.

    A value out of range raises InputError, one of the wrong type InputTypeError.
    """

    resolution: int = 1024
    bias: float = 1.5
    pcf: int = 3

    def __post_init__(self):
        resolution = validate.positive_int(self.resolution, "ShadowMap.resolution")
        if not 16 <= resolution <= 8192:
            raise InputError(f"ShadowMap.resolution must lie in [16, 8192] texels, got {resolution}")
        bias = validate.non_negative(self.bias, "ShadowMap.bias")
        pcf = validate.positive_int(self.pcf, "ShadowMap.pcf")
        if pcf > 9:
            raise InputError(f"ShadowMap.pcf must be at most 9 (a 9 x 9 filter), got {pcf}")
        object.__setattr__(self, "resolution", resolution)
        object.__setattr__(self, "bias", bias)
        object.__setattr__(self, "pcf", pcf)


def _frame(forward) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, up), orthonormal, for a view along ``forward``."""
    f = np.asarray(forward, dtype=np.float64)
    f = f / np.linalg.norm(f)
    helper = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(f, helper)
    right /= np.linalg.norm(right)
    return f, right, np.cross(right, f)


def _view(eye, forward, half_extent: float, resolution: int, orthographic: bool = False):
    """(CameraData, ShadowView) of a square view along ``forward``: half_extent is tan(fov/2) for
    a pinhole view, the half-width in world units for a parallel one."""
    f, right, up = _frame(forward)
    cam = CameraData()
    cam.eye = wp.vec3(*eye)
    cam.forward = wp.vec3(*f)
    cam.right = wp.vec3(*(right * half_extent))
    cam.up = wp.vec3(*(up * half_extent))
    cam.width = cam.height = resolution
    view = ShadowView()
    view.eye = cam.eye
    view.to_camera = wp.mat33(*np.linalg.inv(np.column_stack([right * half_extent, up * half_extent, f])).reshape(-1))
    view.resolution = resolution
    view.orthographic = int(orthographic)
    view.texel_size = 2.0 * half_extent / resolution
    return cam, view


def _has_one_view(light) -> bool:
    """Whether light_views gives ``light`` one view (a directional light, a narrow spot) rather
    than a cube of six."""
    return light.kind == DIRECTIONAL or (light.kind == SPOT and light.outer_cone <= MAX_SPOT_VIEW_HALF_ANGLE)


def view_count(light) -> int:
    """How many views light_views gives ``light``, without making them."""
    return 1 if _has_one_view(light) else len(CUBE_DIRECTIONS)


def light_views(light, center, radius: float, res: int, margin_texels: int):
    """The (CameraData, ShadowView) pairs of the views of one light (shadow maps, light buffers):
    a cube of six for point lights and spot lights wider than MAX_SPOT_VIEW_HALF_ANGLE, one
    pinhole view for narrower spots, a parallel view behind the scene (centre, radius) for
    directional lights; ``res`` texels a side, of which ``margin_texels`` on each lie beyond the
    light's reach (the cube's faces, the spot's cone, the scene)."""
    margin = 1.0 + 2.0 * margin_texels / res
    if light.kind == DIRECTIONAL:
        eye = center - np.asarray(light.direction) * (DIRECTIONAL_VIEW_DISTANCE_RADII * radius)
        return [_view(eye, light.direction, radius * margin, res, orthographic=True)]
    position = np.asarray(light.position, dtype=np.float64)
    if _has_one_view(light):
        return [_view(position, light.direction, math.tan(light.outer_cone) * margin, res)]
    return [_view(position, d, margin, res) for d in CUBE_DIRECTIONS]


def light_geometry(light) -> tuple:
    """What a light's maps depend on (not its colour or intensity)."""
    return (light.kind, tuple(getattr(light, "position", ())), tuple(getattr(light, "direction", ())),
            getattr(light, "outer_cone", None))


def build(scene, gpu, settings: ShadowMap, threads: int | None) -> ShadowMaps:
    """Every light's depth maps, rendered with the rasterizer and packed for the render kernel.

    Kept in the scene cache and reused while its geometry, the lights' placement, the settings and
    the alpha-masked materials' cut-outs stay the same: moving the camera or changing colours and
    intensities renders no new maps."""
    masked = [p.material for p in scene.primitives if p.material.alpha_mode == "MASK"]
    # what decides the cut-outs the maps see through (a texture by identity, kept alive by the key)
    # a cut-out's texture by identity and revision: an image set anew gives other cut-outs
    masks = tuple((m.alpha_cutoff, m.base_color[3], None if m.base_color_texture is None
                   else validate.revision(m.base_color_texture)) for m in masked)
    key = (gpu.geometry, tuple(light_geometry(light) for light in scene.punctual_lights), settings, masks)
    return scene.cache.get("shadow maps", key, lambda: _render_maps(scene, gpu, settings, masked, threads))


def _render_maps(scene, gpu, settings: ShadowMap, masked: list, threads: int | None) -> ShadowMaps:
    """build's maps, rendered anew (``masked``: the alpha-masked materials)."""
    lo, hi = scene.bounds()
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-30)
    depths, views, spans = [], [], []
    for light in scene.punctual_lights:
        # a texel of margin per PCF tap, so that filtering at the edge of a view stays inside the map
        pairs = light_views(light, center, radius, settings.resolution, settings.pcf)
        spans.append((len(views), len(pairs)))
        for cam, view in pairs:
            buffer = visibility_buffer(gpu.data.positions, gpu.data.indices, cam, threads=threads,
                                       out=reused_buffer("shadow map", cam.height, cam.width),
                                       orthographic=bool(view.orthographic), clusters=gpu.clusters)
            if masked:
                _see_through_cut_outs(gpu, cam, view, buffer, threads)
            depths.append(decode(buffer)[1])
            views.append(view)
    maps = ShadowMaps()
    maps.depth = wp.array(np.stack(depths) if depths else np.full((1, 1, 1), np.inf, np.float32), dtype=float,
                          device="cpu")
    maps.views = wp.array(views if views else [ShadowView()], dtype=ShadowView, device="cpu")
    maps.light_views = wp.array(spans if spans else [(0, 0)], dtype=wp.vec2i, device="cpu")
    maps.bias = settings.bias
    maps.pcf = settings.pcf
    return maps


def _see_through_cut_outs(gpu, cam, view, buffer, threads):
    """Texels of a rasterized map showing an alpha-masked triangle ray cast past its cut-outs
    (kernels/shadow_map.cut_out_pass), in blocks of rows on every thread."""
    kernel = cut_out_pass()
    load_for_cpu(kernel)
    workers = thread_count(threads)
    rows = -(-cam.height // (ROW_BLOCKS_PER_THREAD * workers))

    def launch(first_row):
        wp.launch(kernel, dim=min(rows, cam.height - first_row), device="cpu",
                  inputs=[gpu.data, cam, int(view.orthographic), first_row, buffer])

    run_all(launch, range(0, cam.height, rows), workers)


def shadow_mode(shadows) -> tuple[object, ShadowMap | None]:
    """render's ``shadows`` option as (mode, settings): mode "rays", "map" or False."""
    if shadows is True or shadows == "rays":
        return "rays", None
    if shadows is False or shadows is None:
        return False, None
    if shadows == "map":
        return "map", ShadowMap()
    if isinstance(shadows, ShadowMap):
        return "map", shadows
    raise InputError(f'shadows must be "rays" (or True), "map", a pbrwarp.ShadowMap or False, got {shadows!r}')


@functools.cache
def no_shadow_maps() -> ShadowMaps:
    """The render kernel's argument when shadows are ray traced or off."""
    maps = ShadowMaps()
    maps.depth = wp.full((1, 1, 1), np.inf, dtype=float, device="cpu")
    maps.views = wp.array([ShadowView()], dtype=ShadowView, device="cpu")
    maps.light_views = wp.array([(0, 0)], dtype=wp.vec2i, device="cpu")
    maps.bias, maps.pcf = 0.0, 1
    return maps
