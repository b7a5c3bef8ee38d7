"""Which effects a render needs: one immutable, hashable value per (scene, render options).

The render kernel is compiled per Features value (kernels/render.py), so an effect that a scene
does not call for is absent from the generated code rather than skipped at run time.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Features:
    textures: bool
    normal_mapping: bool
    shadows: bool
    supersampling: bool
    # some surface can be passed through by camera rays: a single-sided back face or an alpha mask
    pass_through: bool


def scene_features(gpu_scene, shadows: bool, spp: int) -> Features:
    """The Features a compiled scene needs under the given render options."""
    return Features(
        textures=gpu_scene.has_textures,
        normal_mapping=gpu_scene.has_normal_maps,
        shadows=bool(shadows) and gpu_scene.num_lights > 0,
        supersampling=spp > 1,
        pass_through=gpu_scene.has_pass_through,
    )
