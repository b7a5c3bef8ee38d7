"""Lights as the path tracer samples them: one table over the area lights and the emissive
triangles, beside the environment (punctual lights are not in it: next-event estimation visits
every one of them at every vertex); a light chosen by a discrete distribution, and a
point drawn uniformly on a chosen triangle, with the solid-angle pdf multiple importance sampling
needs.

pbrwarp/emitters.py builds the table (which triangles emit, each entry's probability).
"""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.struct
class LightTable:
    # cumulative probabilities of the entries: the area lights (scene.area_lights, in order), then
    # the emissive triangles; the last is exactly 1
    cdf: wp.array(dtype=float)
    pmf: wp.array(dtype=float)
    # the triangle of each entry past the area lights
    face: wp.array(dtype=wp.int32)
    # per triangle of the scene, the probability its entry is chosen (0 for triangles that emit
    # nothing): the light-sampling pdf of a point a BSDF-sampled ray hits
    face_pmf: wp.array(dtype=float)
    count: int
    area: int
    # the probability of choosing the environment rather than an entry (whose probabilities are
    # then scaled by 1 - environment): 0 where the environment lights nothing
    environment: float


@wp.func
def choose_light(table: LightTable, u: float) -> int:
    """The entry i with cdf[i - 1] <= u < cdf[i] (u in [0, 1)): chosen with probability pmf[i];
    entries of probability 0 never are. Binary search."""
    low = int(0)
    high = table.count - 1
    while low < high:
        middle = (low + high) / 2
        if u < table.cdf[middle]:
            high = middle
        else:
            low = middle + 1
    return low


@wp.func
def choose_light_or_environment(table: LightTable, u: float):
    """(entry, probability of the choice): -1 for the environment, chosen with probability
    table.environment, else choose_light on u rescaled to [0, 1); entry -2 (probability 0) where
    there is nothing to choose."""
    if u < table.environment:
        return -1, table.environment
    if table.count == 0:
        return -2, 0.0
    rest = 1.0 - table.environment
    i = choose_light(table, wp.min((u - table.environment) / rest, 0.99999994))
    return i, table.pmf[i] * rest


@wp.func
def sample_triangle(u: wp.vec2) -> wp.vec2:
    """Barycentric weights (b0, b1) of p0 and p1 (p2's is 1 - b0 - b1) of a point uniform over a
    triangle's area: b0 = 1 - sqrt(u0), b1 = u1 sqrt(u0) (Turk 1990; Shirley & Chiu's square-root
    warp, pbrt-v4's SampleUniformTriangle in another parameterization)."""
    root = wp.sqrt(u[0])
    return wp.vec2(1.0 - root, u[1] * root)


@wp.func
def triangle_area(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3) -> float:
    return 0.5 * wp.length(wp.cross(p1 - p0, p2 - p0))


@wp.func
def area_to_solid_angle(pdf_area: float, distance_sq: float, cos_at_light: float) -> float:
    """A pdf per unit area at a light point turned into one per unit solid angle at the shading
    point: pdf_A d^2 / |cos theta_light| (pbrt-v4, section 4.2.3); 0 where it is 0 or the light is
    seen exactly edge-on (an infinite density that contributes nothing)."""
    c = wp.abs(cos_at_light)
    if pdf_area <= 0.0 or c <= 0.0:
        return 0.0
    return pdf_area * distance_sq / c
