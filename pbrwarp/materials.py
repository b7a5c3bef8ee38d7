"""Metallic-roughness materials, as glTF 2.0 defines them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from . import validate
from .errors import InputError, InputTypeError
from .textures import Texture

# Texture slots: (attribute, whether the texels are sRGB-encoded colour by default).
TEXTURE_SLOTS = (
    ("base_color_texture", True),
    ("metallic_roughness_texture", False),
    ("normal_texture", False),
    ("occlusion_texture", False),
    ("emissive_texture", True),
    ("specular_texture", False),
    ("specular_color_texture", True),
    ("anisotropy_texture", False),
    ("iridescence_texture", False),
    ("iridescence_thickness_texture", False),
    ("clearcoat_texture", False),
    ("clearcoat_roughness_texture", False),
    ("clearcoat_normal_texture", False),
    ("sheen_color_texture", True),
    ("sheen_roughness_texture", False),
    ("transmission_texture", False),
)


@dataclass(eq=False)
class Material(validate.Checked):
    """A glTF metallic-roughness material.

    Factors are linear (as in glTF) and multiply the matching texture, if any. Every field is
    checked whenever it is set, by the constructor or later (``material.roughness = 7`` raises
    InputError as ``Material(roughness=7)`` does; a value of the wrong type raises
    InputTypeError). Out-of-range values are rejected, not clamped: they nearly always mean a bug
    upstream (a percentage, a wrong channel).

    - ``base_color``: linear RGB or RGBA, components >= 0, alpha <= 1 (default (0.8, 0.8, 0.8),
      stored as RGBA); the diffuse albedo of dielectrics, f0 of metals.
    - ``metallic`` (default 0), ``roughness`` (perceptual, GGX alpha = roughness^2; default 0.5):
      in [0, 1]. ``metallic_roughness_texture`` holds roughness in G and metallic in B (glTF).
    - ``ior``: the dielectric's index of refraction (KHR_materials_ior), >= 1 or exactly 0
      (default 1.5). Its reflectance at normal incidence is ((ior - 1) / (ior + 1))^2, 0.04 for
      1.5; 0 means an infinite IOR (reflectance 1 at every angle), as the extension specifies for
      materials converted from specular-glossiness. Metals are unaffected.
    - ``specular``: KHR_materials_specular's strength of the dielectric specular lobe, in [0, 1]:
      1 (the default) leaves it as the IOR gives it, 0 removes it entirely (a pure Lambert
      surface). It scales both f0 and f90 of dielectric Fresnel; metals are unaffected.
      ``specular_texture`` (linear) multiplies it by its alpha channel.
    - ``specular_color``: KHR_materials_specular's tint of the dielectric's f0, linear RGB >= 0,
      components may exceed 1 (default (1, 1, 1)); ``specular_color_texture`` (sRGB-encoded
      unless the :class:`Texture` says otherwise) multiplies it. The dielectric's
      f0 = min(((ior - 1) / (ior + 1))^2 specular_color, 1) specular, and its f90 = specular.
    - ``emissive``: emitted radiance in cd/m^2 (nits; W/(sr m^2) in radiometric terms), linear RGB
      >= 0 (default black), times ``emissive_texture``.
    - Textures (default None): ``base_color_texture``, ``emissive_texture`` and
      ``specular_color_texture`` (sRGB-encoded unless the :class:`Texture` says otherwise),
      ``metallic_roughness_texture``, ``specular_texture``,
      ``normal_texture`` (tangent-space, +Y green up) with ``normal_scale`` (any finite number,
      default 1, scaling the map's x and y), ``occlusion_texture`` with ``occlusion_strength``
      (in [0, 1], default 1; occlusion only scales environment light, so it has no effect under
      punctual lights alone, as glTF specifies). A bare array or Pillow image is wrapped in a
      :class:`Texture` with default sampling.
    - ``double_sided``: back faces are shaded with flipped normals (True, the default here, so a
      lone plane is visible from both sides); when False, back faces are culled for camera rays,
      as glTF specifies (glTF files set it per material; glTF's own default is False). Shadows
      are cast by every face either way.
    - ``alpha_mode``: "OPAQUE" (default), "MASK" (cut out where base-colour alpha, times vertex and
      texture alpha, is below ``alpha_cutoff``, in [0, 1], default 0.5) or "BLEND" (that alpha is
      the surface's coverage: a camera ray takes alpha of its shading and passes 1 - alpha on to
      what lies behind, front to back along the ray, and the frame's alpha is the coverage so
      composited; shadow rays and shadowed environment rays treat the surface as opaque).
    - ``unlit``: KHR_materials_unlit's constant shading (default False). When True the surface's
      radiance towards the eye is its base colour, times the base-colour texture and vertex
      colour, in cd/m^2 (a white unlit surface is 1 nit, whatever lights the scene); lights,
      environment, emission, normal and occlusion maps do not change it. It still casts shadows,
      and ``alpha_mode`` and ``double_sided`` apply.
    - ``anisotropy_strength``: KHR_materials_anisotropy's strength, in [0, 1] (default 0, an
      isotropic highlight): GGX's alpha along the anisotropy direction becomes
      mix(alpha, 1, strength^2), so the highlight stretches along it, most on smooth materials
      and not at all at roughness 1. The direction is the mesh's tangent (its TANGENT attribute,
      or tangents generated from its uvs) turned by ``anisotropy_rotation`` radians
      counter-clockwise towards the bitangent (any finite number, default 0).
      ``anisotropy_texture`` (linear) gives a direction per texel in red and green ([0, 1] mapped
      to [-1, 1], x along the tangent, y along the bitangent; turned by the rotation too) and
      multiplies the strength by blue. A mesh with neither tangents nor uvs has no tangent frame
      and is shaded isotropically.
    - ``iridescence``: KHR_materials_iridescence's strength of a thin dielectric film over the
      surface, in [0, 1] (default 0, no film), times the red channel of ``iridescence_texture``
      (linear): each specular lobe's Fresnel term becomes mix(F, F_film, iridescence), F_film the
      film's interference colours (Belcour & Barla 2017). The film's index of refraction
      ``iridescence_ior`` (>= 1, default 1.3) and thickness in nanometres:
      ``iridescence_thickness_max`` (>= 0, default 400), or, with
      ``iridescence_thickness_texture``, mix(``iridescence_thickness_min`` (>= 0, default 100),
      max, its green channel (linear)).
    - ``clearcoat``: KHR_materials_clearcoat's intensity of a clear coat (IOR 1.5) over the
      whole material, in [0, 1] (default 0, no coat), times ``clearcoat_texture``'s red channel;
      ``clearcoat_roughness``: its perceptual roughness, in [0, 1] (default 0), times
      ``clearcoat_roughness_texture``'s green channel; ``clearcoat_normal_texture`` (tangent-space,
      as ``normal_texture``) with ``clearcoat_normal_scale`` (finite, default 1): the coat's
      normal map; without one the coat follows the interpolated normal, not ``normal_texture``.
      The coat reflects clearcoat F(Nc.v) of the light, F the Fresnel of f0 = 0.04; the material
      below it, emission included, keeps 1 - clearcoat F(Nc.v) (docs/materials.md). All three
      textures are linear.
    - ``sheen_color``: KHR_materials_sheen's colour of a layer of fibres over the material,
      linear RGB in [0, 1] (default black, no sheen), times ``sheen_color_texture``'s RGB
      (sRGB-encoded unless the :class:`Texture` says otherwise); ``sheen_roughness``, in [0, 1]
      (default 0), times ``sheen_roughness_texture``'s alpha (linear): the Charlie sheen of
      Estevez & Kulla 2017 over the material, which is scaled by 1 - max(sheen_color) E_sheen so
      that no energy is gained (docs/materials.md).
    - ``transmission``: KHR_materials_transmission's share of the light entering the surface (not
      reflected by its specular layer) that passes through it rather than being diffused, in
      [0, 1] (default 0, opaque); ``transmission_texture`` (linear) multiplies it by its R
      channel. Transmitted light is tinted by the base colour; metals transmit nothing (the share
      is scaled by 1 - metallic). Ray traced for smooth surfaces (docs/materials.md).
    - ``thickness``: KHR_materials_volume's thicknessFactor, >= 0 (default 0). 0 makes a
      transmissive surface thin-walled: rays pass straight through it. Above 0 the mesh bounds a
      volume: rays refract by ``ior`` entering and leaving it, whatever ``double_sided`` says, and
      the distances they travel inside are measured from the geometry (the value itself only
      chooses the volume).
    - ``attenuation_color`` (linear RGB in [0, 1], default white) and ``attenuation_distance``
      (> 0, scene units, default infinity: no absorption): KHR_materials_volume's absorption, the
      colour white light turns into after that distance inside the volume.
    - ``name``: for messages (default "").
    - ``complex_ior``: optional ``(n, k)``, the complex index of refraction n + ik of a metal,
      each an RGB triple (n > 0, k >= 0), e.g. from refractiveindex.info at 650, 550 and 450 nm.
      The exact Fresnel rung (``pw.BRDF(fresnel="exact")``, ``quality="reference"``) then uses
      the conductor Fresnel equations for the metallic part; the approximate rungs use
      ``base_color`` as f0, so :meth:`conductor` sets both consistently.
    """

    base_color: tuple = (0.8, 0.8, 0.8)
    metallic: float = 0.0
    roughness: float = 0.5
    specular: float = 1.0
    ior: float = 1.5
    specular_color: tuple = (1.0, 1.0, 1.0)
    emissive: tuple = (0.0, 0.0, 0.0)
    base_color_texture: Texture | None = None
    metallic_roughness_texture: Texture | None = None
    normal_texture: Texture | None = None
    normal_scale: float = 1.0
    occlusion_texture: Texture | None = None
    occlusion_strength: float = 1.0
    emissive_texture: Texture | None = None
    specular_texture: Texture | None = None
    specular_color_texture: Texture | None = None
    double_sided: bool = True
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    unlit: bool = False
    anisotropy_strength: float = 0.0
    anisotropy_rotation: float = 0.0
    anisotropy_texture: Texture | None = None
    iridescence: float = 0.0
    iridescence_ior: float = 1.3
    iridescence_thickness_min: float = 100.0
    iridescence_thickness_max: float = 400.0
    iridescence_texture: Texture | None = None
    iridescence_thickness_texture: Texture | None = None
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.0
    clearcoat_texture: Texture | None = None
    clearcoat_roughness_texture: Texture | None = None
    clearcoat_normal_texture: Texture | None = None
    clearcoat_normal_scale: float = 1.0
    sheen_color: tuple = (0.0, 0.0, 0.0)
    sheen_roughness: float = 0.0
    sheen_color_texture: Texture | None = None
    sheen_roughness_texture: Texture | None = None
    transmission: float = 0.0
    transmission_texture: Texture | None = None
    thickness: float = 0.0
    attenuation_color: tuple = (1.0, 1.0, 1.0)
    attenuation_distance: float = math.inf
    name: str = field(default="")
    complex_ior: tuple | None = None

    _checks = {
        "base_color": lambda material, value: _base_color(value),
        "metallic": lambda material, value: validate.unit_interval(value, "Material.metallic"),
        "roughness": lambda material, value: validate.unit_interval(value, "Material.roughness"),
        "specular": lambda material, value: validate.unit_interval(value, "Material.specular"),
        "ior": lambda material, value: _ior(value),
        "specular_color": lambda material, value: validate.colour(value, "Material.specular_color"),
        "emissive": lambda material, value: validate.colour(value, "Material.emissive"),
        "normal_scale": lambda material, value: validate.finite_scalar(value, "Material.normal_scale"),
        "occlusion_strength": lambda material, value: validate.unit_interval(value, "Material.occlusion_strength"),
        "alpha_cutoff": lambda material, value: validate.unit_interval(value, "Material.alpha_cutoff"),
        "alpha_mode": lambda material, value: _alpha_mode(value),
        "double_sided": lambda material, value: bool(value),
        "unlit": lambda material, value: bool(value),
        "anisotropy_strength": lambda material, value: validate.unit_interval(value, "Material.anisotropy_strength"),
        "anisotropy_rotation": lambda material, value: validate.finite_scalar(value, "Material.anisotropy_rotation"),
        "iridescence": lambda material, value: validate.unit_interval(value, "Material.iridescence"),
        "iridescence_ior": lambda material, value: _film_ior(value),
        "iridescence_thickness_min": lambda material, value: _thickness(value, "Material.iridescence_thickness_min"),
        "iridescence_thickness_max": lambda material, value: _thickness(value, "Material.iridescence_thickness_max"),
        "clearcoat": lambda material, value: validate.unit_interval(value, "Material.clearcoat"),
        "clearcoat_roughness": lambda material, value: validate.unit_interval(value, "Material.clearcoat_roughness"),
        "clearcoat_normal_scale": lambda material, value: validate.finite_scalar(value,
                                                                                 "Material.clearcoat_normal_scale"),
        "sheen_color": lambda material, value: _unit_colour(value, "Material.sheen_color"),
        "sheen_roughness": lambda material, value: validate.unit_interval(value, "Material.sheen_roughness"),
        "transmission": lambda material, value: validate.unit_interval(value, "Material.transmission"),
        "thickness": lambda material, value: validate.non_negative(value, "Material.thickness"),
        "attenuation_color": lambda material, value: _unit_colour(value, "Material.attenuation_color"),
        "attenuation_distance": lambda material, value: _distance(value),
        "complex_ior": lambda material, value: None if value is None else _complex_ior(value),
        **{slot: (lambda material, value, slot=slot: Texture.wrap(value, f"Material.{slot}"))
           for slot, _ in TEXTURE_SLOTS},
    }

    @classmethod
    def conductor(cls, n, k, roughness: float = 0.5, **kwargs) -> "Material":
        """A metal given by its complex IOR n + ik (RGB triples, n > 0, k >= 0): metallic = 1,
        base_color = the normal-incidence reflectance ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2)
        (Born & Wolf) that the approximate Fresnel rungs use, and ``complex_ior`` for the exact
        one; ``roughness`` (default 0.5) and any other field as keywords."""
        n_rgb, k_rgb = _complex_ior((n, k))
        f0 = tuple(((a - 1) ** 2 + b**2) / ((a + 1) ** 2 + b**2) for a, b in zip(n_rgb, k_rgb))
        return cls(base_color=f0, metallic=1.0, roughness=roughness, complex_ior=(n_rgb, k_rgb), **kwargs)

    @property
    def see_through(self) -> bool:
        """Whether camera rays may see what lies behind the surface: it is alpha-masked,
        alpha-blended or transmissive (its back faces and what a closed mesh of it holds may then
        show)."""
        return self.alpha_mode != "OPAQUE" or self.transmissive

    @property
    def transmissive(self) -> bool:
        """Whether light may pass through the surface (KHR_materials_transmission)."""
        return self.transmission > 0.0

    @property
    def attenuation_coefficient(self) -> tuple:
        """sigma = -ln(attenuation_color) / attenuation_distance per channel, per scene unit
        (KHR_materials_volume): 0 without absorption, infinite for a black channel."""
        return tuple(0.0 if c == 1.0 or math.isinf(self.attenuation_distance)
                     else (math.inf if c == 0.0 else -math.log(c) / self.attenuation_distance)
                     for c in self.attenuation_color)

    @property
    def f0_dielectric(self) -> tuple:
        """((ior - 1) / (ior + 1))^2 times ``specular_color`` per channel: the dielectric's f0
        before its clamp to 1 and the ``specular`` factor (KHR_materials_ior, _specular)."""
        reflectance = ((self.ior - 1.0) / (self.ior + 1.0)) ** 2
        return tuple(reflectance * c for c in self.specular_color)

    def textures(self):
        """(slot, texture, srgb) for every texture this material uses."""
        for slot, colour_slot in TEXTURE_SLOTS:
            tex = getattr(self, slot)
            if tex is not None:
                yield slot, tex, colour_slot if tex.srgb is None else tex.srgb


def _base_color(value) -> tuple:
    """Linear RGB or RGBA, stored as RGBA (alpha 1 if not given)."""
    rgba = validate.colour(value, "Material.base_color", allow_alpha=True)
    if len(rgba) == 4 and rgba[3] > 1.0:
        raise InputError(f"Material.base_color alpha must lie in [0, 1], got {rgba[3]}")
    return rgba if len(rgba) == 4 else (*rgba, 1.0)


def _unit_colour(value, what: str) -> tuple:
    """Linear RGB with every component in [0, 1]."""
    rgb = validate.colour(value, what)
    if max(rgb) > 1.0:
        raise InputError(f"{what} components must lie in [0, 1], got {rgb}")
    return rgb


def _ior(value) -> float:
    """An index of refraction >= 1, or 0 (KHR_materials_ior's infinite IOR)."""
    x = validate.finite_scalar(value, "Material.ior")
    if x != 0.0 and x < 1.0:
        raise InputError(f"Material.ior must be >= 1 (or 0, meaning infinite, as KHR_materials_ior allows), got {x}")
    return x


def _film_ior(value) -> float:
    x = validate.finite_scalar(value, "Material.iridescence_ior")
    if x < 1.0:
        raise InputError(f"Material.iridescence_ior must be >= 1 (a dielectric film), got {x}")
    return x


def _thickness(value, what: str) -> float:
    """A film thickness in nanometres: finite, >= 0, and within float32's range."""
    x = validate.non_negative(value, what)
    if x > 1.0e6:
        raise InputError(f"{what} is in nanometres and must be at most 1e6 (1 mm: no longer a thin film), got {x}")
    return x


def _distance(value) -> float:
    """A distance > 0, infinity allowed (KHR_materials_volume's attenuationDistance)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"Material.attenuation_distance must be a number, got {value!r}") from None
    if not x > 0.0:
        raise InputError(f"Material.attenuation_distance must be > 0 (infinity: no absorption), got {value!r}")
    return x


def _alpha_mode(value) -> str:
    if value not in ("OPAQUE", "MASK", "BLEND"):
        raise InputError(f"Material.alpha_mode must be OPAQUE, MASK or BLEND, got {value!r}")
    return value


def _complex_ior(value) -> tuple:
    """(n, k) as two RGB triples with n > 0 and k >= 0."""
    try:
        n, k = value
    except (TypeError, ValueError):
        raise InputError(f"Material.complex_ior must be (n, k), two RGB triples, got {value!r}") from None
    n = validate.finite_vector(n, 3, "Material.complex_ior n")
    k = validate.finite_vector(k, 3, "Material.complex_ior k")
    if min(n) <= 0.0 or min(k) < 0.0:
        raise InputError(f"Material.complex_ior needs n > 0 and k >= 0 in every channel, got n={n}, k={k}")
    return n, k
