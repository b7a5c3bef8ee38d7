"""Choosing the BRDF's model term by term: the rungs of the accuracy ladder."""

from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError
from pbrwarp.kernels.brdf import (COUPLING_MODELS, DIFFUSE_MODELS, ENERGY_MODELS, FRESNEL_MODELS, METALLIC_MIXES,
                                  MODELS)
from pbrwarp.kernels.microfacet import DISTRIBUTIONS, GEOMETRY_MODELS


@dataclass(frozen=True)
class BRDF:
    """Which model each BRDF term uses; each choice is compiled in, not branched on per pixel.

    The defaults are glTF 2.0's material model (its Appendix B) with the terms of the common
    real-time model (Karis 2013): Lambert diffuse, GGX distribution, Smith with Schlick-GGX
    (k = (roughness + 1)^2 / 8), Schlick Fresnel, single scattering, with the energy-conserving
    albedo coupling of the diffuse lobe rather than the common 1 - F(v.h), which makes smooth
    white dielectrics at grazing views reflect more light than they receive (tests/test_energy.py).
    Each field takes one of the names below, the first its default; any other raises InputError.

    - ``diffuse``: "lambert" | "burley" (Burley 2012)
    - ``distribution``: "ggx" | "blinn_phong" (normalized, exponent 2/alpha^2 - 2)
    - ``geometry``: "schlick_ggx" | "implicit" (G = n.l n.v) | "smith_separable" (Walter et al.
      2007) | "smith_correlated" (Heitz 2014) | "smith_correlated_fast" (Hammon 2017)
    - ``fresnel``: "schlick" | "none" (F = f0) | "spherical_gaussian" (Lagarde 2012) | "exact"
      (dielectric Fresnel with the IOR f0 implies; conductor Fresnel for materials with a
      ``complex_ior``)
    - ``energy``: "single" | "multiscatter" (energy compensation of the specular lobe with its
      single-scattering albedo, integrated by a Warp kernel: Kulla & Conty 2017, Fdez-Agüera 2019)
    - ``coupling``, the diffuse lobe's share of light: "albedo" ((1 - E(v))(1 - E(l)) / (1 - E_avg)
      with E the albedo of the specular lobe above it; Kelemen & Szirmay-Kalos 2001) | "fresnel"
      (1 - F(v.h), as LearnOpenGL's PBR tutorial and glTF's Appendix B weight it) | "none"
      (diffuse + specular, as Filament)
    - ``metallic_mix``, how ``metallic`` combines a dielectric and a metal: "gltf"
      (mix(dielectric BRDF, metal BRDF, metallic), glTF 2.0 Appendix B: the dielectric is Lambert
      under a specular layer with an achromatic Fresnel from the material's ``ior``, scaled by its
      ``specular`` and ``specular_color`` (KHR_materials_ior, KHR_materials_specular); the metal a
      specular lobe with f0 = base colour) | "f0" (one specular lobe with f0 = mix(dielectric f0,
      base colour, metallic) over (1 - metallic) of the diffuse lobe, as Karis 2013). Both have
      the same specular lobes for Schlick's Fresnel; they differ in the diffuse lobe's share. In
      "gltf" it is the dielectric layer's, achromatic (its largest channel, as
      KHR_materials_specular's max_value); in "f0" the mixed lobe's, which for a partly metallic
      coloured material is chromatic and tints the diffuse light with the complement of the
      base colour. Multiple-scattering compensation applies to each lobe with its own f0.
    - ``model``: "microfacet" (Cook-Torrance with the terms above) | "phong" | "blinn_phong": the
      legacy non-PBR baselines, Lambert plus a normalized (Blinn-)Phong lobe (Lafortune & Willems
      1994; Lagarde 2011), which ignore the other terms
    """

    diffuse: str = "lambert"
    distribution: str = "ggx"
    geometry: str = "schlick_ggx"
    fresnel: str = "schlick"
    energy: str = "single"
    coupling: str = "albedo"
    model: str = "microfacet"
    metallic_mix: str = "gltf"

    def __post_init__(self):
        for name, allowed in (("diffuse", DIFFUSE_MODELS), ("distribution", DISTRIBUTIONS),
                              ("geometry", GEOMETRY_MODELS), ("fresnel", FRESNEL_MODELS), ("energy", ENERGY_MODELS),
                              ("coupling", COUPLING_MODELS), ("model", MODELS), ("metallic_mix", METALLIC_MIXES)):
            value = getattr(self, name)
            if value not in allowed:
                raise InputError(f"BRDF {name} must be one of {', '.join(allowed)}, got {value!r}")

    def describe(self) -> str:
        if self.model != "microfacet":
            return f"legacy {self.model} model: Lambert plus a normalized {self.model} lobe (not physically based)"
        mix = ("glTF's mix of a dielectric and a metal BRDF" if self.metallic_mix == "gltf"
               else "one specular lobe with f0 mixed by metallic")
        return (f"{mix}: {self.diffuse} diffuse, {self.distribution} distribution, {self.geometry} geometry, "
                f"{self.fresnel} Fresnel, {self.energy} scattering, {self.coupling} coupling")


# Quality presets: the rungs each selects. "balanced" is the default because it is the model
# tutorials teach and real-time engines ship (Karis 2013): GGX with Schlick's Fresnel and the
# Schlick-GGX geometry term, whose cost is a few multiply-adds over the cheapest rungs.
PRESETS = {
    # the cheapest rung of every term: Blinn-Phong NDF, G = n.l n.v, exp2 Fresnel, and the
    # 1 - F coupling (no table lookups; "none" would be cheaper still but adds the lobes' energies)
    "fast": BRDF(distribution="blinn_phong", geometry="implicit", fresnel="spherical_gaussian", coupling="fresnel"),
    # the real-time model (Karis 2013)
    "balanced": BRDF(),
    # the exact Smith term (Heitz 2014) and Disney diffuse, with Schlick's Fresnel
    "accurate": BRDF(diffuse="burley", geometry="smith_correlated"),
    # the most exact rung of every term (bench/accuracy.py's reference)
    "reference": BRDF(diffuse="burley", geometry="smith_correlated", fresnel="exact", energy="multiscatter"),
}


def brdf_for_quality(quality: str | None, brdf: BRDF | None) -> BRDF:
    """The BRDF a render uses: ``brdf`` when given (per-term overrides win), else the preset."""
    if brdf is not None:
        if not isinstance(brdf, BRDF):
            from .errors import InputTypeError

            raise InputTypeError(f"brdf must be a pbrwarp.BRDF, got {type(brdf).__name__}")
        return brdf
    if quality is None:
        return PRESETS["balanced"]
    if quality not in PRESETS:
        raise InputError(f"quality must be one of {', '.join(PRESETS)}, got {quality!r}")
    return PRESETS[quality]
