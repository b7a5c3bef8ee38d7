"""Stand-alone pipeline stages (primary rays, closest hit, any hit) for benchmarks and for
comparing ray throughput with other ray casters on exactly the same rays."""

import functools

import warp as wp

from .brdf import brdf_for

from .camera import CameraData, camera_ray_direction
from .robust import RAY_FAR, offset_ray_origin, triangle_hit_error, safe_normalize

wp.set_module_options({"enable_backward": False})


@wp.kernel(enable_backward=False)
def primary_ray_directions(cam: CameraData, out_dir: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out_dir[i] = camera_ray_direction(cam, float(i % cam.width) + 0.5, float(i / cam.width) + 0.5)


@wp.kernel(enable_backward=False)
def closest_hits(mesh: wp.uint64, origin: wp.vec3, dirs: wp.array(dtype=wp.vec3),
                 out_t: wp.array(dtype=float), out_face: wp.array(dtype=int)):
    i = wp.tid()
    q = wp.mesh_query_ray(mesh, origin, dirs[i], RAY_FAR)
    if q.result:
        out_t[i] = q.t
        out_face[i] = q.face
    else:
        out_t[i] = wp.inf
        out_face[i] = -1


@wp.kernel(enable_backward=False)
def shadow_origins(positions: wp.array(dtype=wp.vec3), indices: wp.array(dtype=wp.int32), origin: wp.vec3,
                   dirs: wp.array(dtype=wp.vec3), t: wp.array(dtype=float), face: wp.array(dtype=int),
                   to_light: wp.vec3, out_origin: wp.array(dtype=wp.vec3)):
    """Offset hit points towards the light, the origins of the shadow rays any_hits traces."""
    i = wp.tid()
    f = face[i]
    if f < 0:
        out_origin[i] = wp.vec3(RAY_FAR)
        return
    p0 = positions[indices[3 * f]]
    p1 = positions[indices[3 * f + 1]]
    p2 = positions[indices[3 * f + 2]]
    ng = safe_normalize(wp.cross(p1 - p0, p2 - p0), -dirs[i])
    if wp.dot(ng, dirs[i]) > 0.0:
        ng = -ng
    out_origin[i] = offset_ray_origin(origin + dirs[i] * t[i], triangle_hit_error(p0, p1, p2), ng, to_light)


@wp.kernel(enable_backward=False)
def any_hits(mesh: wp.uint64, origins: wp.array(dtype=wp.vec3), to_light: wp.vec3, out_hit: wp.array(dtype=int)):
    i = wp.tid()
    o = origins[i]
    if o[0] >= RAY_FAR:
        out_hit[i] = 0
        return
    out_hit[i] = wp.where(wp.mesh_query_ray_anyhit(mesh, o, to_light, RAY_FAR), 1, 0)


@functools.cache
def brdf_throughput_kernel(**rungs):
    """A kernel evaluating the BRDF ``evals`` times per thread on inputs that vary with every call
    (the sum is written so that nothing is optimized away): time per evaluation of the rungs
    (brdf_for's keyword names)."""
    brdf = brdf_for(True, True, **rungs)

    @wp.kernel(enable_backward=False, module="unique")
    def evaluate(evals: int, out: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        state = wp.rand_init(1234, i)
        total = wp.vec3(0.0)
        n = wp.vec3(0.0, 0.0, 1.0)
        for _ in range(evals):
            v = wp.normalize(wp.vec3(wp.randf(state) - 0.5, wp.randf(state) - 0.5, wp.randf(state) + 0.05))
            l = wp.normalize(wp.vec3(wp.randf(state) - 0.5, wp.randf(state) - 0.5, wp.randf(state) + 0.05))
            total = total + brdf(n, v, l, wp.vec3(0.8, 0.6, 0.4), wp.randf(state), wp.randf(state), 1.0)
        out[i] = total

    return evaluate


@wp.kernel(enable_backward=False)
def random_inputs_only(evals: int, out: wp.array(dtype=wp.vec3)):
    """The input generation of brdf_throughput_kernel alone, to subtract its cost."""
    i = wp.tid()
    state = wp.rand_init(1234, i)
    total = wp.vec3(0.0)
    for _ in range(evals):
        v = wp.normalize(wp.vec3(wp.randf(state) - 0.5, wp.randf(state) - 0.5, wp.randf(state) + 0.05))
        l = wp.normalize(wp.vec3(wp.randf(state) - 0.5, wp.randf(state) - 0.5, wp.randf(state) + 0.05))
        total = total + v + l + wp.vec3(wp.randf(state), wp.randf(state), 0.0)
    out[i] = total
