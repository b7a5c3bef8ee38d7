"""Ray casting rates: Warp's ``mesh_query_ray`` with each BVH leaf size, and a traversal of our own,
on the CPU. An experiment for the path tracer's speed (docs/integrators.md, "Speed").

    python bench/traversal.py [--rays 300000] [--repeats 5]

Builds a binned-SAH BVH (12 bins, leaves of at most 2 triangles; Wald 2007) in NumPy, flattened
depth first, and traverses it in a Warp function written as a renderer would: nearer child first,
a fixed stack, Möller & Trumbore's ray-triangle test on precomputed edges (not watertight, so a
lower bound on a robust version's cost). The same random rays (from random points of a box, in
uniformly random directions, one thread) go through it and through ``wp.mesh_query_ray`` on
Warp's own SAH BVH of the same triangles, built with leaves of at most 1, 2, 4 (Warp's default)
and 8 triangles. All must find the same nearest hits (the sums of their distances are compared). Scenes: the Cornell box seen from inside (pbrwarp.meshes.cornell_box();
large triangles whose boxes all contain the ray origins), the decimated bunny installed with
pbrwarp, and the 69k-triangle scan when the shared assets are beside the clone, from around them.

Writes bench/results/traversal.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, interleaved_medians, write_results  # noqa: E402

from pbrwarp import meshes  # noqa: E402

BINS = 12
LEAF = 2
WARP_LEAF_SIZES = (1, 2, 4, 8)


def _surface_area(lower, upper):
    d = np.maximum(upper - lower, 0.0)
    return 2.0 * (d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0])


def _best_split(lower, upper, centres):
    """(cost, axis, bin, bins of each triangle) of the cheapest binned SAH split, or None."""
    best = None
    c_lo, c_hi = centres.min(0), centres.max(0)
    n = len(centres)
    for axis in range(3):
        extent = c_hi[axis] - c_lo[axis]
        if extent <= 0.0:
            continue
        bins = np.minimum(((centres[:, axis] - c_lo[axis]) / extent * BINS).astype(int), BINS - 1)
        counts = np.bincount(bins, minlength=BINS)
        b_lo = np.full((BINS, 3), np.inf)
        b_hi = np.full((BINS, 3), -np.inf)
        np.minimum.at(b_lo, bins, lower)
        np.maximum.at(b_hi, bins, upper)
        left_lo, left_hi = np.minimum.accumulate(b_lo, 0), np.maximum.accumulate(b_hi, 0)
        right_lo = np.minimum.accumulate(b_lo[::-1], 0)[::-1]
        right_hi = np.maximum.accumulate(b_hi[::-1], 0)[::-1]
        left_n = np.cumsum(counts)
        right_n = n - left_n
        cost = _surface_area(left_lo[:-1], left_hi[:-1]) * left_n[:-1] + _surface_area(right_lo[1:], right_hi[1:]) * right_n[1:]
        cost = np.where((left_n[:-1] > 0) & (right_n[1:] > 0), cost, np.inf)
        k = int(np.argmin(cost))
        if np.isfinite(cost[k]) and (best is None or cost[k] < best[0]):
            best = (cost[k], axis, k, bins)
    return best


def build_bvh(positions, faces):
    """Flattened BVH, depth first (a node's left child follows it): lower, upper, right child
    index, (first triangle, count) for leaves ((0, 0) for inner nodes), and the triangles'
    corners in leaf order."""
    corners = positions[faces]
    lower, upper = corners.min(1), corners.max(1)
    centres = 0.5 * (lower + upper)
    node_lower, node_upper, right, leaf, order = [], [], [], [], []
    stack = [(np.arange(len(faces)), None)]
    while stack:
        members, parent = stack.pop()
        me = len(node_lower)
        if parent is not None:
            right[parent] = me
        lo, hi = lower[members].min(0), upper[members].max(0)
        node_lower.append(lo), node_upper.append(hi), right.append(-1), leaf.append((0, 0))
        split = _best_split(lower[members], upper[members], centres[members]) if len(members) > LEAF else None
        if split is None and len(members) > LEAF:  # coincident centres: halve in any order
            stack += [(members[len(members) // 2:], me), (members[: len(members) // 2], None)]
            continue
        if split is None:
            leaf[me] = (len(order), len(members))
            order.extend(members.tolist())
            continue
        _, _, k, bins = split
        stack += [(members[bins > k], me), (members[bins <= k], None)]
    tri = corners[np.asarray(order)].astype(np.float32)
    return (np.asarray(node_lower, np.float32), np.asarray(node_upper, np.float32), np.asarray(right, np.int32),
            np.asarray(leaf, np.int32), tri)


@wp.struct
class Bvh:
    lower: wp.array(dtype=wp.vec3)
    upper: wp.array(dtype=wp.vec3)
    right: wp.array(dtype=wp.int32)
    leaf: wp.array(dtype=wp.vec2i)
    v0: wp.array(dtype=wp.vec3)
    e1: wp.array(dtype=wp.vec3)
    e2: wp.array(dtype=wp.vec3)


@wp.func
def box_entry(o: wp.vec3, inv_d: wp.vec3, lo: wp.vec3, hi: wp.vec3, t_max: float) -> float:
    """Where the ray enters the box (0 from inside), or -1 if it misses it before t_max."""
    t0 = wp.cw_mul(lo - o, inv_d)
    t1 = wp.cw_mul(hi - o, inv_d)
    near = wp.max(wp.max(wp.min(t0[0], t1[0]), wp.min(t0[1], t1[1])), wp.max(wp.min(t0[2], t1[2]), 0.0))
    far = wp.min(wp.min(wp.max(t0[0], t1[0]), wp.max(t0[1], t1[1])), wp.min(wp.max(t0[2], t1[2]), t_max))
    if near <= far * 1.00000024:
        return near
    return -1.0


@wp.func
def nearest_hit(b: Bvh, o: wp.vec3, d: wp.vec3, t_max: float) -> float:
    inv_d = wp.vec3(1.0 / d[0], 1.0 / d[1], 1.0 / d[2])
    stack = wp.vector(dtype=wp.int32, length=64)
    depth = int(0)
    node = int(0)
    best = t_max
    while True:
        span = b.leaf[node]
        if span[1] > 0:
            for k in range(span[0], span[0] + span[1]):
                e1 = b.e1[k]
                e2 = b.e2[k]
                pv = wp.cross(d, e2)
                inv_det = 1.0 / wp.dot(e1, pv)
                tv = o - b.v0[k]
                u = wp.dot(tv, pv) * inv_det
                qv = wp.cross(tv, e1)
                v = wp.dot(d, qv) * inv_det
                t = wp.dot(e2, qv) * inv_det
                if u >= 0.0 and v >= 0.0 and u + v <= 1.0 and t > 0.0 and t < best:
                    best = t
            if depth == 0:
                break
            depth -= 1
            node = stack[depth]
            continue
        left = node + 1
        right = b.right[node]
        t_left = box_entry(o, inv_d, b.lower[left], b.upper[left], best)
        t_right = box_entry(o, inv_d, b.lower[right], b.upper[right], best)
        if t_left >= 0.0 and t_right >= 0.0:
            if t_left <= t_right:
                stack[depth] = right
                node = left
            else:
                stack[depth] = left
                node = right
            depth += 1
        elif t_left >= 0.0:
            node = left
        elif t_right >= 0.0:
            node = right
        else:
            if depth == 0:
                break
            depth -= 1
            node = stack[depth]
    return best


@wp.func
def random_ray(i: int, lo: wp.vec3, hi: wp.vec3):
    """Ray i: an origin uniform in the box [lo, hi], a direction uniform on the sphere. Its own
    generator per ray: a wp.func gets the state by value, so a state passed in would not advance."""
    state = wp.rand_init(7, i)
    o = wp.vec3(wp.randf(state, lo[0], hi[0]), wp.randf(state, lo[1], hi[1]), wp.randf(state, lo[2], hi[2]))
    return o, wp.sample_unit_sphere_surface(state)


@wp.kernel(enable_backward=False, module="unique")
def cast_own(b: Bvh, lo: wp.vec3, hi: wp.vec3, rays: int, out: wp.array(dtype=float)):
    total = float(0.0)
    for i in range(rays):
        o, d = random_ray(i, lo, hi)
        t = nearest_hit(b, o, d, 1.0e6)
        if t < 1.0e6:
            total += t
    out[0] = total


@wp.kernel(enable_backward=False, module="unique")
def cast_warp(mesh: wp.uint64, lo: wp.vec3, hi: wp.vec3, rays: int, out: wp.array(dtype=float)):
    total = float(0.0)
    for i in range(rays):
        o, d = random_ray(i, lo, hi)
        q = wp.mesh_query_ray(mesh, o, d, 1.0e6)
        if q.result:
            total += q.t
    out[0] = total


def measure(positions, faces, ray_box, rays, repeats):
    t0 = time.perf_counter()
    lower, upper, right, leaf, tri = build_bvh(positions, faces)
    build_s = time.perf_counter() - t0
    b = Bvh()
    b.lower, b.upper = wp.array(lower, dtype=wp.vec3), wp.array(upper, dtype=wp.vec3)
    b.right, b.leaf = wp.array(right, dtype=wp.int32), wp.array(leaf, dtype=wp.vec2i)
    b.v0 = wp.array(tri[:, 0], dtype=wp.vec3)
    b.e1, b.e2 = wp.array(tri[:, 1] - tri[:, 0], dtype=wp.vec3), wp.array(tri[:, 2] - tri[:, 0], dtype=wp.vec3)
    points = wp.array(positions.astype(np.float32), dtype=wp.vec3)
    indices = wp.array(faces.astype(np.int32).ravel(), dtype=wp.int32)
    warp_meshes = {leaf: wp.Mesh(points=points, indices=indices, bvh_leaf_size=leaf) for leaf in WARP_LEAF_SIZES}
    lo, hi = (wp.vec3(*v) for v in ray_box)
    runs = {"own": (cast_own, b), **{f"warp leaf {leaf}": (cast_warp, m.id) for leaf, m in warp_meshes.items()}}
    outs = {name: wp.zeros(1, dtype=float) for name in runs}

    def run(name):
        kernel, first = runs[name]
        wp.launch(kernel, 1, [first, lo, hi, rays, outs[name]], device="cpu")
        wp.synchronize_device("cpu")

    seconds = interleaved_medians({name: (lambda name=name: run(name)) for name in runs}, repeats)
    sums = [float(out.numpy()[0]) for out in outs.values()]
    return {"triangles": len(faces), "nodes": len(lower), "build_s": build_s,
            "mrays_s": {name: rays / t / 1e6 for name, t in seconds.items()},
            "same_hits": bool(np.allclose(sums, sums[0], rtol=1e-5))}


def scenes():
    scene, _ = meshes.cornell_box()
    positions = np.concatenate([p.positions for p in scene.primitives])
    offsets = np.cumsum([0] + [len(p.positions) for p in scene.primitives[:-1]])
    faces = np.concatenate([p.faces + o for p, o in zip(scene.primitives, offsets)])
    lo, hi = positions.min(0), positions.max(0)
    yield "Cornell box, rays from inside", positions, faces, (lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
    bunnies = [("decimated bunny", True)]
    if (meshes.ASSETS / "meshes/stanford-bunny.obj").is_file():
        bunnies.append(("bunny scan", False))
    for name, decimated in bunnies:
        m = meshes.bunny(decimated=decimated)
        lo, hi = m.bounds
        yield f"{name}, rays from around it", np.asarray(m.vertices, np.float64), np.asarray(m.faces), (
            lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo))


def main(argv=None):
    ap = argparse.ArgumentParser(prog="traversal.py", description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=300_000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    rows = []
    for name, positions, faces, box in scenes():
        rows.append({"scene": name, **measure(positions, faces, box, args.rays, args.repeats)})
    names = list(rows[0]["mrays_s"])
    lines = ["| scene | triangles | " + " | ".join(f"{n}, M rays/s" for n in names)
             + " | own build (NumPy), s | same hits |", "|---|---|" + "---|" * (len(names) + 2)]
    for r in rows:
        rates = " | ".join(f"{r['mrays_s'][n]:.2f}" for n in names)
        lines.append(f"| {r['scene']} | {r['triangles']} | {rates} | {r['build_s']:.2f} | {r['same_hits']} |")
    lines += ["", f"{args.rays} closest-hit rays per run on one thread, medians of {args.repeats} runs after a warm-up, "
              "the traversals timed in turn. 'warp leaf 4' is what wp.Mesh builds by default."]
    write_results("traversal", command_line(ap, args), {"rows": rows}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
