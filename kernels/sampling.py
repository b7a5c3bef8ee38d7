"""Stratified sub-pixel sample positions: multi-jittered sampling with correlated shuffles.

N = m x n samples are stratified both on the m x n grid and on N strips in x and in y
(multi-jittered sampling, Chiu, Shirley and Wang 1994); the canonical arrangement is shuffled by
one permutation of columns and one of rows per pixel, as in Kensler's correlated multi-jittered
sampling (Pixar 2013). The permutations here are affine maps i -> (a i + b) mod l with a coprime
to l, seeded from Warp's per-pixel random state, so every pixel gets its own pattern and the
image does not depend on how the frame is split into tiles. sample_positions lays every sample's
image position out for the rasterizer, computed as the ray caster computes its rays'.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func
def gcd(a: int, b: int) -> int:
    x = a
    y = b
    while y != 0:
        t = x % y
        x = y
        y = t
    return x


@wp.func
def affine_permutation(i: int, length: int, a: int, b: int) -> int:
    """i -> (a i + b) mod length, a permutation of [0, length) when gcd(a, length) = 1."""
    return (a * i + b) % length


@wp.func
def coprime_multiplier(length: int, r: int) -> int:
    a = 1 + r % length
    while gcd(a, length) != 1:
        a = a + 1
    return a


@wp.func
def multi_jittered_sample(s: int, m: int, n: int, seed: int) -> wp.vec2:
    """Position in [0, 1)^2 of sample s of m x n for the pixel whose random seed is ``seed``."""
    state = wp.rand_init(seed)
    col_a = coprime_multiplier(m, wp.abs(wp.randi(state)))
    col_b = wp.abs(wp.randi(state)) % m
    row_a = coprime_multiplier(n, wp.abs(wp.randi(state)))
    row_b = wp.abs(wp.randi(state)) % n
    state = wp.rand_init(seed, s)
    jx = wp.randf(state)
    jy = wp.randf(state)
    col = s % m
    row = s / m
    sub_x = affine_permutation(row, n, row_a, row_b)
    sub_y = affine_permutation(col, m, col_a, col_b)
    x = (float(col) + (float(sub_x) + jx) / float(n)) / float(m)
    y = (float(row) + (float(sub_y) + jy) / float(m)) / float(n)
    return wp.vec2(wp.min(x, 0.99999994), wp.min(y, 0.99999994))


@wp.kernel
def sample_positions(spp: int, grid_m: int, grid_n: int, seed: int, width: int, first_row: int,
                     out: wp.array2d(dtype=wp.vec2)):
    """Image position (pixels, (0, 0) the top-left corner) of every sample of rows first_row...,
    computed exactly as the ray caster's render_tile computes its rays' (x, y)."""
    i = wp.tid()
    s = i % spp
    px = (i / spp) % width
    py = first_row + i / (spp * width)
    offset = wp.vec2(0.5, 0.5)
    if spp > 1:
        offset = multi_jittered_sample(s, grid_m, grid_n, seed + py * width + px)
    out[py, px * spp + s] = wp.vec2(float(px) + offset[0], float(py) + offset[1])
