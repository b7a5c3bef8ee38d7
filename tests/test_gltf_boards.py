"""The Khronos test boards (tests/assets/gltf-ext/): per board, the property its README describes."""

import json
import struct

import numpy as np
import pytest

import pbrwarp as pw

from assets import board

def board_json(name):
    """The JSON chunk of the test board ``name``'s .glb."""
    raw = board(name).read_bytes()
    length, = struct.unpack_from("<I", raw, 12)
    return json.loads(raw[20:20 + length])


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


SPECULAR_BOARD_ROOT = np.array([0.325, 0.0, 0.0])  # SampleRoot's translation; the spheres are its children


@pytest.mark.parametrize("node, f0", [
    ("1.1_specularFactor", (0.0, 0.0, 0.0)),                 # specular 0: perfectly black
    ("1.4_specularFactor", (0.04 * 0.520996,) * 3),         # f0 = 0.04 specularFactor
    ("1.5_specularFactor", (0.04,) * 3),
    ("3.3_whiteColorFactor", (0.04 * 0.212231,) * 3),       # f0 = 0.04 specularColorFactor
    ("5.4_yellowColorFactor", (0.04 * 0.520996, 0.04 * 0.520996, 0.0)),  # tinted yellow
    ("7.4_HDR_colorFactor", (0.04 * 13.276,) * 3),          # colour factor above 1: f0 = 0.531
    ("7.5_HDR_colorFactor", (1.0, 1.0, 1.0)),               # 0.04 x 25 clamped to 1: a mirror
])
def test_specular_board_spheres_reflect_their_f0_head_on(node, f0):
    """SpecularTest: black, smooth dielectric spheres whose KHR_materials_specular factor or colour
    sets f0 = min(0.04 specularColorFactor, 1) specularFactor (ior 1.5). In a uniform white
    environment of radiance 1 nit a sphere's centre, seen head-on, reflects the environment by
    Fresnel at normal incidence: radiance f0."""
    scene = pw.Scene.load(board("SpecularTest"))
    scene.environment = pw.Environment.uniform()
    nodes = {n["name"]: n for n in board_json("SpecularTest")["nodes"]}
    centre = SPECULAR_BOARD_ROOT + np.array(nodes[node]["translation"])
    camera = pw.Camera.look_at(eye=tuple(centre + (0.0, 0.0, 1.0)), target=tuple(centre), fov_y=0.5)
    frame = pw.render(scene, camera, width=4, height=4, shadows=False, progress=False)
    np.testing.assert_allclose(frame.rgb[1:3, 1:3], np.broadcast_to(f0, (2, 2, 3)), rtol=0.02, atol=2e-4)
