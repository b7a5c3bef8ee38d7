"""Auxiliary outputs beside the radiance: what each sample's first surface records for the
frame's ``albedo`` (a guide for denoising; pbrwarp.denoise)."""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func
def denoiser_albedo(base_color: wp.vec3) -> wp.vec3:
    """The albedo Open Image Denoise's guide buffer asks for (its documentation, "Albedo"): the
    surface's colour independent of light and view, in [0, 1]. In glTF's metallic-roughness model
    one base colour is both the diffuse colour of a dielectric and the normal-incidence
    reflectance (F0) of a metal, the two choices OIDN recommends for each; any metallic mix of
    them is that same colour."""
    return wp.vec3(wp.clamp(base_color[0], 0.0, 1.0), wp.clamp(base_color[1], 0.0, 1.0),
                   wp.clamp(base_color[2], 0.0, 1.0))
