"""The Khronos test boards (tests/assets/gltf-ext/): per board, the property its README describes."""

import numpy as np
import pytest

import pbrwarp as pw

from assets import board

EMISSIVE = np.array([0.1, 0.5, 0.9])  # every cube's emissiveFactor in EmissiveStrengthTest


@pytest.mark.parametrize("cube, x, strength", [("Cube1", -6.0, 1.0), ("Cube2", -3.0, 2.0), ("Cube4", 0.0, 4.0),
                                               ("Cube8", 3.0, 8.0), ("Cube16", 6.0, 16.0)])
def test_emissive_strength_board_cubes_double_left_to_right(cube, x, strength):
    """EmissiveStrengthTest: five black cubes emitting (0.1, 0.5, 0.9) times 1, 2, 4, 8 and 16
    (KHR_materials_emissive_strength; the leftmost has no extension). Unlit by any light, a
    cube's face seen head-on has exactly that radiance, in nits."""
    scene = pw.Scene.load(board("EmissiveStrengthTest"))
    camera = pw.Camera.look_at(eye=(x, 0.0, 10.0), target=(x, 0.0, 0.0), fov_y=5.0)
    frame = pw.render(scene, camera, width=8, height=8, shadows=False, progress=False)
    np.testing.assert_allclose(frame.rgb[2:6, 2:6], np.broadcast_to(EMISSIVE * strength, (4, 4, 3)), rtol=1e-5)


def test_draco_board_is_refused_naming_the_extension():
    """Box/glTF-Draco requires KHR_draco_mesh_compression, which pbrwarp cannot decode: a clear
    error naming it, before any geometry is read."""
    with pytest.raises(pw.AssetFormatError, match="KHR_draco_mesh_compression"):
        pw.Scene.load(board("Box"))
