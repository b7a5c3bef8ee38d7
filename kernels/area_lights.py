"""Area lights (pbrwarp.SphereLight, pbrwarp.RectLight): sampling them from a shading point, the
densities of those samples, and the closed forms of the direct integrator's cheap rung.

Each light emits radiance ``radiance`` (colour times luminance in nits) from one side of its
surface: a sphere outwards, a rectangle along its normal, edge_u x edge_v. Samplers take two
uniform numbers u in [0, 1)^2 (as kernels/direction_sampling.py does) and return
(direction, distance, pdf): the unit direction from the shading point to a point of the light,
the distance to that point, and the density of the direction per unit solid angle, 0 where the
point receives no light (inside a sphere, behind a rectangle, a light too small for float32 to
resolve from there). ``pdf_*`` evaluates that density for any direction, 0 off the light, for
multiple importance sampling.
"""

import functools

import warp as wp

from .direction_sampling import orthonormal_basis
from .microfacet import PI
from .robust import FLOAT32_MAX, safe_normalize

wp.set_module_options({"enable_backward": False})

AREA_SPHERE = wp.constant(0)
AREA_RECT = wp.constant(1)
# The random streams of the render kernel's area-light samples, one per camera sample (the
# environment's are from 2^24, rough transmission's from 2^25).
AREA_LIGHT_STREAM = wp.constant(1 << 26)


@wp.struct
class AreaLightData:
    kind: int
    # the sphere's or the rectangle's centre
    position: wp.vec3
    # the sphere's radius
    radius: float
    # the rectangle's edges (full lengths) and unit normal edge_u x edge_v, the side it lights
    edge_u: wp.vec3
    edge_v: wp.vec3
    normal: wp.vec3
    # the emitting area: 4 pi r^2, |edge_u| |edge_v|
    area: float
    # colour times luminance (nits): the radiance leaving the surface
    radiance: wp.vec3


@wp.func
def robust_length(v: wp.vec3) -> float:
    """|v| without overflow or underflow of the squares, for any finite float32 vector."""
    m = wp.max(wp.abs(v[0]), wp.max(wp.abs(v[1]), wp.abs(v[2])))
    if m == 0.0:
        return 0.0
    return m * wp.length(v / m)


@wp.func
def one_minus_cos_from_sin_sq(sin_sq: float) -> float:
    """1 - cos(theta) for theta in [0, pi/2] given sin^2(theta), without the cancellation of
    1 - sqrt(1 - sin^2) at small angles: sin^2 / (1 + cos)."""
    return sin_sq / (1.0 + wp.sqrt(wp.max(1.0 - sin_sq, 0.0)))


# ---------------------------------------------------------------------------------- sphere


@wp.func
def sphere_cone(light: AreaLightData, p: wp.vec3):
    """(unit direction w to the centre, distance d to it, sin^2 of the cone's half-angle alpha,
    1 - cos(alpha)) of the cone of directions a sphere subtends from p; 1 - cos(alpha) is 0 where
    p is inside or on the sphere, or where the cone is too narrow for float32."""
    to_centre = light.position - p
    d = robust_length(to_centre)
    if not (d > light.radius and d < FLOAT32_MAX):
        # inside or on the sphere, or beyond float32's reach (an overflowed difference)
        return wp.vec3(0.0, 0.0, 1.0), 0.0, 1.0, 0.0
    w = to_centre / d
    ratio = light.radius / d
    sin_sq = ratio * ratio
    return w, d, sin_sq, one_minus_cos_from_sin_sq(sin_sq)


@wp.func
def sample_sphere_light(light: AreaLightData, p: wp.vec3, u: wp.vec2):
    """(direction, distance, solid-angle pdf) of a direction drawn uniformly from the cone a
    sphere light subtends from p (Shirley, Wang & Zimmerman 1996, "Monte Carlo Techniques for
    Direct Lighting Calculations"; pbrt-v4's Sphere::Sample): pdf 1 / (2 pi (1 - cos(alpha))),
    sin(alpha) = radius / distance to the centre. The distance is to the near side of the sphere.
    Points inside or on the sphere receive nothing from it (it emits outwards): pdf 0."""
    w, d, sin_sq_max, one_minus_cos_max = sphere_cone(light, p)
    if one_minus_cos_max <= 0.0:
        return wp.vec3(0.0), 0.0, 0.0
    # cos(theta) uniform in [cos(alpha), 1], kept as 1 - cos(theta) for small cones
    one_minus_cos = u[0] * one_minus_cos_max
    cos_theta = 1.0 - one_minus_cos
    sin_theta = wp.sqrt(wp.max(one_minus_cos * (2.0 - one_minus_cos), 0.0))
    phi = 2.0 * PI * u[1]
    direction = orthonormal_basis(w) * wp.vec3(sin_theta * wp.cos(phi), sin_theta * wp.sin(phi), cos_theta)
    direction = safe_normalize(direction, w)
    # the near root of |p + t direction - centre| = r, rationalized so that it neither cancels
    # near the sphere nor squares distances that overflow float32:
    # t = (d - r)(d + r) / (d cos + sqrt(r^2 - d^2 sin^2))
    r = light.radius
    d_sin = d * sin_theta
    root = wp.sqrt(wp.max((r - d_sin) * (r + d_sin), 0.0))
    distance = (d - r) * ((d + r) / (d * cos_theta + root))
    return direction, distance, 1.0 / (2.0 * PI * one_minus_cos_max)


@wp.func
def pdf_sphere_light(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
    """The solid-angle density of sample_sphere_light from p at the unit ``direction``: constant
    inside the cone the sphere subtends, 0 outside it, and 0 from inside the sphere. The test is
    on sin^2 (a cross product), exact for narrow cones where cosines round to 1."""
    w, d, sin_sq_max, one_minus_cos_max = sphere_cone(light, p)
    if one_minus_cos_max <= 0.0:
        return 0.0
    if wp.dot(direction, w) <= 0.0:
        return 0.0
    c = wp.cross(direction, w)
    if wp.dot(c, c) > sin_sq_max:
        return 0.0
    return 1.0 / (2.0 * PI * one_minus_cos_max)


@wp.func
def ray_sphere(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
    """The distance t > 0 at which the ray p + t direction (unit direction) meets the sphere's
    outside, -1 where it misses it, runs away from it, or starts inside or on it (the sphere emits
    outwards only). Robust as pbrt-v4's sphere test (section 6.8.1): the squared distance of the
    ray from the centre as (r - l)(r + l) of the perpendicular length l, and the near root in the
    form t = (d - r)(d + r) / (-b + sqrt(disc)), neither cancelling at grazing rays nor squaring
    distances that would overflow float32."""
    to_p = p - light.position
    d = robust_length(to_p)
    r = light.radius
    if not (d > r and d < FLOAT32_MAX):
        return -1.0
    b = wp.dot(to_p, direction)  # -(distance along the ray to the point nearest the centre)
    if not (b < 0.0):
        return -1.0
    l = robust_length(to_p - direction * b)  # the ray's distance from the centre
    if not (l <= r):
        return -1.0
    q = -b + wp.sqrt(wp.max((r - l) * (r + l), 0.0))
    t = (d - r) * ((d + r) / q)
    if not (t > 0.0 and t < FLOAT32_MAX):
        return -1.0
    return t


@wp.func
def sphere_projected_solid_angle(cos_theta: float, sin_sq: float) -> float:
    """The projected solid angle, over a surface, of a sphere subtending a cone of half-angle
    alpha (sin^2(alpha) = sin_sq < 1) whose axis makes angle theta with the surface's normal:
    pi sin^2(alpha) cos(theta) while the sphere is wholly above the horizon, 0 wholly below, and
    across the horizon Snyder's closed form (Snyder 1996, "Area Light Sources for Real-Time
    Graphics"; as Lagarde & de Rousiers 2014 use it): with x = cot(alpha) and
    y = -x cot(theta), (cos(theta) acos(y) - x sin(theta) sqrt(1 - y^2)) sin^2(alpha)
    + atan(sin(theta) sqrt(1 - y^2) / x)."""
    if cos_theta * cos_theta > sin_sq:
        return PI * sin_sq * wp.max(cos_theta, 0.0)
    sin_theta = wp.sqrt(wp.max(1.0 - cos_theta * cos_theta, 0.0))
    if sin_theta <= 0.0:
        return PI * sin_sq * wp.max(cos_theta, 0.0)
    x = wp.sqrt(wp.max(1.0 / sin_sq - 1.0, 0.0))
    y = wp.clamp(-x * cos_theta / sin_theta, -1.0, 1.0)
    s = sin_theta * wp.sqrt(wp.max(1.0 - y * y, 0.0))
    return wp.max((cos_theta * wp.acos(y) - x * s) * sin_sq + wp.atan2(s, x), 0.0)


@wp.func
def sphere_irradiance(light: AreaLightData, p: wp.vec3, n: wp.vec3):
    """(unit direction to the centre, the projected solid angle of the sphere over the surface
    with unit normal n at p, the projected solid angle on a surface facing it, pi sin^2(alpha)):
    the irradiance of a uniform sphere of radiance L is L times the former, exact for any
    placement of the sphere above, across or below the horizon (sphere_projected_solid_angle);
    0 inside the sphere."""
    w, d, sin_sq, one_minus_cos = sphere_cone(light, p)
    if one_minus_cos <= 0.0:
        return w, 0.0, 0.0
    return w, sphere_projected_solid_angle(wp.dot(n, w), sin_sq), PI * sin_sq


@wp.func
def sphere_representative_point(light: AreaLightData, p: wp.vec3, r: wp.vec3) -> wp.vec3:
    """The point of the sphere nearest the reflection ray p + t r (unit r), relative to p (Karis
    2013, "Real Shading in Unreal Engine 4", eq. 11): the centre moved towards the ray by at most
    the radius."""
    to_centre = light.position - p
    centre_to_ray = wp.dot(to_centre, r) * r - to_centre
    gap = robust_length(centre_to_ray)
    step = float(1.0)
    if gap > light.radius:
        step = light.radius / gap
    return to_centre + centre_to_ray * step


@wp.func
def representative_point_normalization(alpha: float, radius: float, distance: float) -> float:
    """Karis 2013's energy normalization of a specular lobe shaded from a representative point:
    (alpha / alpha')^2 with alpha' = saturate(alpha + radius / (2 distance)) (eq. 14), the GGX
    lobe widened by the source's angular size so that its peak does not add energy."""
    if distance <= 0.0:
        return 0.0
    widened = wp.min(alpha + radius / (2.0 * distance), 1.0)
    ratio = alpha / widened
    return ratio * ratio


# ---------------------------------------------------------------------------------- rectangle


@wp.func
def rect_corner(light: AreaLightData, i: int) -> wp.vec3:
    """Corner i (0..3) of the rectangle, counterclockwise about its normal."""
    su = float(-0.5)
    sv = float(-0.5)
    if i == 1 or i == 2:
        su = 0.5
    if i >= 2:
        sv = 0.5
    return light.position + light.edge_u * su + light.edge_v * sv


@wp.struct
class SphericalRectangle:
    """A rectangle as seen from a point o in front of it (Urena, Fajardo & King 2013, "An
    Area-Preserving Parametrization for Spherical Rectangles"): the local frame (x, y along the
    edges, z the emission normal), the corner's local coordinates x0, y0, z0 (z0 < 0) and the far
    ones x1, y1, the z of two edge planes' normals b0, b1, the constant k and the solid angle."""

    x: wp.vec3
    y: wp.vec3
    z: wp.vec3
    x0: float
    y0: float
    z0: float
    x1: float
    y1: float
    b0: float
    b1: float
    k: float
    solid_angle: float


# The spherical-rectangle sampler serves rectangles subtending between these solid angles (sr):
# below, float32's sum of four angles less 2 pi loses the solid angle's digits (and area
# sampling is as good, the rectangle being nearly flat to the point); above, the point all but
# lies in the rectangle's plane and the angles near pi lose theirs (as pbrt-v4 bounds it).
MIN_SPHERICAL_RECT_SOLID_ANGLE = wp.constant(1.0e-3)
MAX_SPHERICAL_RECT_SOLID_ANGLE = wp.constant(6.2)


@wp.func
def spherical_rectangle(light: AreaLightData, o: wp.vec3) -> SphericalRectangle:
    """Urena et al. 2013's set-up of the rectangle seen from o (o in front of it), section 3."""
    q = SphericalRectangle()
    length_u = wp.length(light.edge_u)
    length_v = wp.length(light.edge_v)
    q.x = light.edge_u / length_u
    q.y = light.edge_v / length_v
    q.z = light.normal
    d = light.position - light.edge_u * 0.5 - light.edge_v * 0.5 - o
    q.x0 = wp.dot(d, q.x)
    q.y0 = wp.dot(d, q.y)
    q.z0 = wp.dot(d, q.z)
    q.x1 = q.x0 + length_u
    q.y1 = q.y0 + length_v
    # the normals of the planes through o and each edge, and the rectangle's inner angles
    n0 = wp.normalize(wp.vec3(0.0, q.z0, -q.y0))
    n1 = wp.normalize(wp.vec3(-q.z0, 0.0, q.x1))
    n2 = wp.normalize(wp.vec3(0.0, -q.z0, q.y1))
    n3 = wp.normalize(wp.vec3(q.z0, 0.0, -q.x0))
    g0 = wp.acos(wp.clamp(-wp.dot(n0, n1), -1.0, 1.0))
    g1 = wp.acos(wp.clamp(-wp.dot(n1, n2), -1.0, 1.0))
    g2 = wp.acos(wp.clamp(-wp.dot(n2, n3), -1.0, 1.0))
    g3 = wp.acos(wp.clamp(-wp.dot(n3, n0), -1.0, 1.0))
    q.b0 = n0[2]
    q.b1 = n2[2]
    q.k = 2.0 * PI - g2 - g3
    q.solid_angle = g0 + g1 - q.k
    return q


@wp.func
def spherical_rectangle_point(q: SphericalRectangle, u: wp.vec2) -> wp.vec3:
    """The point, relative to o, that Urena et al. 2013's area-preserving map (section 4) takes
    u to: uniform in the rectangle's solid angle."""
    au = u[0] * q.solid_angle + q.k
    fu = (wp.cos(au) * q.b0 - q.b1) / wp.sin(au)
    cu = wp.clamp(wp.where(fu > 0.0, 1.0, -1.0) / wp.sqrt(fu * fu + q.b0 * q.b0), -1.0, 1.0)
    xu = wp.clamp(-(cu * q.z0) / wp.sqrt(wp.max(1.0 - cu * cu, 1.0e-12)), q.x0, q.x1)
    d = wp.sqrt(xu * xu + q.z0 * q.z0)
    h0 = q.y0 / wp.sqrt(d * d + q.y0 * q.y0)
    h1 = q.y1 / wp.sqrt(d * d + q.y1 * q.y1)
    hv = h0 + u[1] * (h1 - h0)
    yv = q.y1
    if hv * hv < 1.0 - 1.0e-6:
        yv = wp.clamp(hv * d / wp.sqrt(1.0 - hv * hv), q.y0, q.y1)
    return q.x * xu + q.y * yv + q.z * q.z0


@wp.func
def spherical_sampling_serves(q: SphericalRectangle) -> bool:
    return q.solid_angle >= MIN_SPHERICAL_RECT_SOLID_ANGLE and q.solid_angle <= MAX_SPHERICAL_RECT_SOLID_ANGLE


@wp.func
def sample_rect_light(light: AreaLightData, p: wp.vec3, u: wp.vec2):
    """(direction, distance, solid-angle pdf) of a point of the rectangle: uniform in the solid
    angle it subtends from p (Urena, Fajardo & King 2013), pdf 1 / solid angle; or, where the
    rectangle subtends less than MIN_SPHERICAL_RECT_SOLID_ANGLE or more than
    MAX_SPHERICAL_RECT_SOLID_ANGLE, uniform over its area converted to solid angle,
    pdf = distance^2 / (area cos(theta_l)) (theta_l between the normal and the way back to p).
    pdf 0 where p is behind the rectangle or in its plane."""
    height = wp.dot(p - light.position, light.normal)
    if not (height > 0.0 and height < FLOAT32_MAX):
        return wp.vec3(0.0), 0.0, 0.0
    q = spherical_rectangle(light, p)
    to_q = wp.vec3(0.0)
    if spherical_sampling_serves(q):
        to_q = spherical_rectangle_point(q, u)
    else:
        to_q = light.position + light.edge_u * (u[0] - 0.5) + light.edge_v * (u[1] - 0.5) - p
    distance = robust_length(to_q)
    if not (distance > 0.0 and distance < FLOAT32_MAX):
        return wp.vec3(0.0), 0.0, 0.0
    direction = to_q / distance
    cos_light = -wp.dot(direction, light.normal)
    if not (cos_light > 0.0):
        return wp.vec3(0.0), 0.0, 0.0
    if spherical_sampling_serves(q):
        return direction, distance, 1.0 / q.solid_angle
    pdf = wp.min((distance / light.area) * (distance / cos_light), FLOAT32_MAX)
    return direction, distance, pdf


@wp.func
def rect_hit(light: AreaLightData, p: wp.vec3, direction: wp.vec3):
    """(whether the ray p + t direction, t > 0, meets the rectangle's lit face, t, the cosine at
    the light)."""
    cos_light = -wp.dot(direction, light.normal)
    height = wp.dot(p - light.position, light.normal)  # p's distance in front of the plane
    if not (cos_light > 0.0 and height > 0.0 and height < FLOAT32_MAX):
        return False, 0.0, 0.0
    t = height / cos_light
    local = p + direction * t - light.position
    su = wp.dot(local, light.edge_u) / wp.dot(light.edge_u, light.edge_u)
    sv = wp.dot(local, light.edge_v) / wp.dot(light.edge_v, light.edge_v)
    if not (wp.abs(su) <= 0.5 and wp.abs(sv) <= 0.5):
        return False, 0.0, 0.0
    return True, t, cos_light


@wp.func
def ray_rect(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
    """The distance t > 0 at which the ray p + t direction (unit direction) meets the rectangle's
    lit face, -1 where it does not (behind it, parallel to it, past its edges)."""
    hit, t, cos_light = rect_hit(light, p, direction)
    if not hit:
        return -1.0
    return t


@wp.func
def pdf_rect_light(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
    """The solid-angle density of sample_rect_light from p at the unit ``direction``: where the
    ray meets the rectangle's lit face, 1 / its solid angle, or t^2 / (area cos(theta_l)) at
    distance t where sample_rect_light samples the area; else 0."""
    hit, t, cos_light = rect_hit(light, p, direction)
    if not hit:
        return 0.0
    q = spherical_rectangle(light, p)
    if spherical_sampling_serves(q):
        return 1.0 / q.solid_angle
    return wp.min((t / light.area) * (t / cos_light), FLOAT32_MAX)


@wp.func
def edge_vector(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    """One edge's term of Lambert's polygon formula (Lambert 1760; Arvo 1995, "Applications of
    Irradiance Tensors"), as a vector: the angle the edge a -> b (directions from the shading
    point) subtends times the unit normal of the plane through it, oriented so that a polygon
    counterclockwise about its normal, seen from its front, sums to a vector whose dot product
    with a surface normal n is twice its projected solid angle over that surface. The angle in
    atan2 form, exact at small angles."""
    c = wp.cross(b, a)
    s = wp.length(c)
    if s <= 0.0:
        return wp.vec3(0.0)
    return c * (wp.atan2(s, wp.dot(a, b)) / s)


@wp.func
def rect_irradiance(light: AreaLightData, p: wp.vec3, n: wp.vec3):
    """(unit mean direction of the light over the horizon, the projected solid angle of the
    rectangle over the surface with unit normal n at p, the length of its vector form factor
    unclipped: the projected solid angle on a surface facing it).

    Lambert's formula: the projected solid angle of a polygon is 1/2 sum over its edges of the
    angle each subtends times the cosine between n and its plane's normal, for the polygon
    clipped to the surface's horizon (Sutherland-Hodgman against n.x = 0, summed edge by edge):
    exact for any placement; 0 behind the light. Irradiance = radiance times it."""
    height = wp.dot(p - light.position, light.normal)
    if not (height > 0.0 and height < FLOAT32_MAX):
        return n, 0.0, 0.0
    vector = wp.vec3(0.0)  # twice the vector form factor, unclipped and clipped
    clipped = wp.vec3(0.0)
    exit_point = wp.vec3(0.0)
    entry_point = wp.vec3(0.0)
    crossed = int(0)
    for i in range(4):
        a = wp.normalize(rect_corner(light, i) - p)
        b = wp.normalize(rect_corner(light, (i + 1) % 4) - p)
        vector = vector + edge_vector(a, b)
        ha = wp.dot(n, a)
        hb = wp.dot(n, b)
        if ha >= 0.0 and hb >= 0.0:
            clipped = clipped + edge_vector(a, b)
        elif ha >= 0.0:
            exit_point = a + (b - a) * (ha / (ha - hb))
            clipped = clipped + edge_vector(a, exit_point)
            crossed = crossed + 1
        elif hb >= 0.0:
            entry_point = a + (b - a) * (ha / (ha - hb))
            clipped = clipped + edge_vector(entry_point, b)
            crossed = crossed + 1
    if crossed == 2:
        # the horizon closes the clipped polygon, from where it left to where it came back
        clipped = clipped + edge_vector(exit_point, entry_point)
    projected = wp.max(0.5 * wp.dot(n, clipped), 0.0)
    mean = safe_normalize(clipped, safe_normalize(light.position - p, n))
    return mean, projected, 0.5 * wp.length(vector)


@wp.func
def rect_representative_point(light: AreaLightData, p: wp.vec3, r: wp.vec3) -> wp.vec3:
    """The point of the rectangle nearest the reflection ray p + t r, relative to p: where the ray
    meets the rectangle's plane (or, where it runs away from the lit face, the ray's point at the
    centre's distance projected onto it), clamped to the rectangle (the representative point of
    Karis 2013, for rectangles as Drobot 2014, "Physically Based Area Lights", GPU Pro 5)."""
    to_centre = light.position - p
    height = -wp.dot(to_centre, light.normal)
    toward = -wp.dot(r, light.normal)
    q = p + r * robust_length(to_centre)
    if toward > 0.0 and height > 0.0:
        q = p + r * (height / toward)
    local = q - light.position
    su = wp.clamp(wp.dot(local, light.edge_u) / wp.dot(light.edge_u, light.edge_u), -0.5, 0.5)
    sv = wp.clamp(wp.dot(local, light.edge_v) / wp.dot(light.edge_v, light.edge_v), -0.5, 0.5)
    return to_centre + light.edge_u * su + light.edge_v * sv


# ---------------------------------------------------------------------------------- by kind


@functools.cache
def area_light_kinds(spheres: bool, rects: bool):
    """(sample, pdf, intersect): sample_*_light, pdf_*_light and ray_* dispatched on a light's
    kind, for kernels holding sphere lights, rectangle lights or both (at least one); the code of
    an absent kind is not generated."""

    @wp.func
    def sample(light: AreaLightData, p: wp.vec3, u: wp.vec2):
        if wp.static(spheres and rects):
            if light.kind == AREA_RECT:
                return sample_rect_light(light, p, u)
            return sample_sphere_light(light, p, u)
        elif wp.static(spheres):
            return sample_sphere_light(light, p, u)
        else:
            return sample_rect_light(light, p, u)

    @wp.func
    def pdf(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
        if wp.static(spheres and rects):
            if light.kind == AREA_RECT:
                return pdf_rect_light(light, p, direction)
            return pdf_sphere_light(light, p, direction)
        elif wp.static(spheres):
            return pdf_sphere_light(light, p, direction)
        else:
            return pdf_rect_light(light, p, direction)

    @wp.func
    def intersect(light: AreaLightData, p: wp.vec3, direction: wp.vec3) -> float:
        if wp.static(spheres and rects):
            if light.kind == AREA_RECT:
                return ray_rect(light, p, direction)
            return ray_sphere(light, p, direction)
        elif wp.static(spheres):
            return ray_sphere(light, p, direction)
        else:
            return ray_rect(light, p, direction)

    return sample, pdf, intersect
