"""glTF's KHR_materials_ior and KHR_materials_specular read into Materials, and their textures
compiled into the render kernel only where a scene's materials use them."""

import numpy as np
import pytest

from pbrwarp.errors import AssetFormatError
from pbrwarp.gltf import load_gltf

from test_gltf import Builder


def specular_material(b: Builder, **extensions) -> None:
    b.json["materials"] = [{"pbrMetallicRoughness": {"metallicFactor": 0.0}, "extensions": extensions}]
    b.node(mesh=b.quad(material=0))


def test_ior_and_every_specular_property_are_read(tmp_path):
    b = Builder()
    image = b.image()
    b.json["textures"] = [{"source": image}, {"source": image, "sampler": 0}]
    b.json["samplers"] = [{"wrapS": 33071}]
    specular_material(b, KHR_materials_ior={"ior": 1.33},
                      KHR_materials_specular={"specularFactor": 0.5, "specularColorFactor": [2.0, 1.0, 0.25],
                                              "specularTexture": {"index": 0},
                                              "specularColorTexture": {"index": 1}})
    b.json["extensionsRequired"] = b.json["extensionsUsed"] = ["KHR_materials_ior", "KHR_materials_specular"]
    prim, = load_gltf(b.glb(tmp_path / "specular.glb")).primitives
    m = prim.material
    assert m.ior == pytest.approx(1.33) and m.specular == 0.5 and m.specular_color == (2.0, 1.0, 0.25)
    assert m.specular_texture is not None and m.specular_color_texture is not None
    assert m.specular_color_texture.wrap_s == "clamp" and m.specular_texture.wrap_s == "repeat"
    # the colour texture is sRGB-encoded (KHR_materials_specular), the strength's alpha linear
    slots = {slot: srgb for slot, _, srgb in m.textures()}
    assert slots == {"specular_texture": False, "specular_color_texture": True}
    # f0 of the dielectric before the clamp: ((ior - 1) / (ior + 1))^2 specularColorFactor
    np.testing.assert_allclose(m.f0_dielectric, (0.33 / 2.33) ** 2 * np.array([2.0, 1.0, 0.25]), rtol=1e-12)


def test_defaults_without_the_extensions(tmp_path):
    b = Builder()
    specular_material(b)
    m = load_gltf(b.glb(tmp_path / "plain.glb")).primitives[0].material
    assert m.ior == 1.5 and m.specular == 1.0 and m.specular_color == (1.0, 1.0, 1.0)
    assert m.specular_texture is None and m.specular_color_texture is None
    np.testing.assert_allclose(m.f0_dielectric, 0.04, rtol=1e-12)


def test_ior_zero_means_infinite_and_below_one_is_refused(tmp_path):
    """KHR_materials_ior: ior >= 1, or 0 for the specular-glossiness conversion (f0 = 1)."""
    b = Builder()
    specular_material(b, KHR_materials_ior={"ior": 0})
    m = load_gltf(b.glb(tmp_path / "zero.glb")).primitives[0].material
    assert m.f0_dielectric == (1.0, 1.0, 1.0)
    b = Builder()
    specular_material(b, KHR_materials_ior={"ior": 0.5})
    with pytest.raises(AssetFormatError, match="ior"):
        load_gltf(b.glb(tmp_path / "half.glb"))
    b = Builder()
    specular_material(b, KHR_materials_specular={"specularColorFactor": [1.0, -1.0, 1.0]})
    with pytest.raises(AssetFormatError, match="specular_color"):
        load_gltf(b.glb(tmp_path / "negative.glb"))
