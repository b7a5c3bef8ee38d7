"""How environment light is integrated: the rungs of image-based lighting."""

from __future__ import annotations

from dataclasses import dataclass

from . import validate
from .errors import InputError

IBL_METHODS = ("split_sum", "monte_carlo")
IBL_FRESNEL = ("dfg", "lagarde")


@dataclass(frozen=True)
class IBL:
    """Image-based lighting rungs, passed as ``pw.render(..., ibl=pw.IBL(...))`` (the ``quality``
    presets pick one otherwise); they matter only when the scene has an ``environment``.

    - ``method`` (default "split_sum"): "split_sum" (the real-time model: diffuse from 9 spherical-harmonic
      coefficients of the environment (Ramamoorthi & Hanrahan 2001), specular from a GGX-prefiltered
      mip chain times a DFG table, Karis 2013) | "monte_carlo" (the reference: ``samples`` directions
      per hit, cosine-weighted, from GGX visible normals (Heitz 2018) and from the environment's
      radiance in turn, combined by the balance heuristic, through the very BRDF direct light uses).
    - ``fresnel`` (split sum; default "dfg"): "dfg", the lobe's albedo f0 A + f90 B from the table, and the diffuse
      lobe gets the rest | "lagarde", Lagarde's roughness-aware Schlick F(n.v) in place of f0 and
      1 - F for the diffuse lobe (Lagarde 2011; LearnOpenGL).
    - ``samples``: directions per hit for "monte_carlo", a whole number >= 1 (default 64).
    - ``shadowed`` ("monte_carlo" only; default False): trace each direction against the scene,
      so geometry occludes the environment; otherwise (and for the split sum) the material's
      occlusion texture scales ambient light, as glTF specifies.
    - ``environment_sampling`` ("monte_carlo" only; default True): a third of the directions are
      drawn in proportion to the environment's luminance (kernels/environment_sampling.py), the
      rest from the BRDF; False draws them all from the BRDF. Environments with a sun or small
      bright sources need it (about 10x less error at equal samples); smooth ones (a uniform
      colour, the procedural sky) converge 1.25-1.9x slower with it (docs/lighting.md).

    An unknown name, ``samples`` < 1 or ``shadowed`` with the split sum raises InputError.
    """

    method: str = "split_sum"
    fresnel: str = "dfg"
    samples: int = 64
    shadowed: bool = False
    environment_sampling: bool = True

    def __post_init__(self):
        if self.method not in IBL_METHODS:
            raise InputError(f"IBL method must be one of {', '.join(IBL_METHODS)}, got {self.method!r}")
        if self.fresnel not in IBL_FRESNEL:
            raise InputError(f"IBL fresnel must be one of {', '.join(IBL_FRESNEL)}, got {self.fresnel!r}")
        object.__setattr__(self, "samples", validate.positive_int(self.samples, "IBL.samples"))
        object.__setattr__(self, "shadowed", bool(self.shadowed))
        object.__setattr__(self, "environment_sampling", bool(self.environment_sampling))
        if self.shadowed and self.method != "monte_carlo":
            raise InputError("IBL shadowed=True traces the Monte Carlo directions: use method=\"monte_carlo\"")

    def describe(self) -> str:
        if self.method == "split_sum":
            return f"SH irradiance and split-sum specular ({self.fresnel} Fresnel)"
        strategies = "cosine + GGX VNDF + environment" if self.environment_sampling else "cosine + GGX VNDF"
        return (f"Monte Carlo, {self.samples} directions per hit ({strategies}, balance heuristic), "
                + ("shadowed by the scene" if self.shadowed else "unshadowed, occlusion texture"))


def ibl_for_quality(quality: str | None, ibl: IBL | None) -> IBL:
    """The IBL rungs a render uses: ``ibl`` when given, else the quality preset's: the split sum for
    every preset but "reference", which integrates by Monte Carlo with 256 shadowed directions."""
    if ibl is not None:
        if not isinstance(ibl, IBL):
            from .errors import InputTypeError

            raise InputTypeError(f"ibl must be a pbrwarp.IBL, got {type(ibl).__name__}")
        return ibl
    return IBL(method="monte_carlo", samples=256, shadowed=True) if quality == "reference" else IBL()
