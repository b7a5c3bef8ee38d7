"""Counter-based random numbers: each number is a hash of (seed, pixel, sample index, dimension),
not the next state of a generator.

A path's numbers therefore do not depend on which thread renders the pixel, on the order of
launches, or on how many samples came before in the same call: sample s of a pixel is the same
whether it is rendered in a call for samples [0, 8) or one for [s, s + 1), so a render can be
continued (pbrwarp.render's ``first_sample``) and threads=1 and threads=N give identical images.

The hash is PCG's output permutation applied to a 32-bit counter, the "pcg" hash that Jarzynski
& Olano 2020 ("Hash Functions for GPU Rendering", JCGT 9(3)) recommend for its quality at its
cost; inputs are chained as pcg(a + pcg(b)), as Warp's own ``rand_init(seed, offset)`` does.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})

# 2^-24: a hash's top 24 bits scaled into [0, 1), every value exactly representable in float32,
# so a uniform number is never rounded up to 1.
_TO_UNIT = wp.constant(1.0 / 16777216.0)


@wp.func_native("""
wp::uint32 state = x * 747796405u + 2891336453u;
wp::uint32 word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
return (word >> 22u) ^ word;
""")
def pcg_hash(x: wp.uint32) -> wp.uint32:
    """PCG's RXS-M-XS permutation of one LCG step of x (O'Neill 2014; Jarzynski & Olano 2020)."""
    ...


@wp.func
def hash_combine(a: wp.uint32, b: int) -> wp.uint32:
    """pcg(a + pcg(b)): a new key from key ``a`` and counter ``b``."""
    return pcg_hash(a + pcg_hash(wp.uint32(b)))


@wp.func
def sample_key(seed: int, pixel: int, sample: int) -> wp.uint32:
    """The key of sample ``sample`` of pixel ``pixel`` (row-major index) under ``seed``."""
    return hash_combine(hash_combine(pcg_hash(wp.uint32(seed)), pixel), sample)


@wp.func
def uniform(key: wp.uint32, dimension: int) -> float:
    """A number uniform in [0, 1), the ``dimension``-th of the sample with ``key``."""
    return float(hash_combine(key, dimension) >> wp.uint32(8)) * _TO_UNIT


@wp.func
def uniform2(key: wp.uint32, dimension: int) -> wp.vec2:
    """Two independent numbers uniform in [0, 1): dimensions ``dimension`` and ``dimension + 1``."""
    return wp.vec2(uniform(key, dimension), uniform(key, dimension + 1))
