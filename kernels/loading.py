"""Loading compiled kernels for CPU launches, and reading back the code Warp generated."""

import os

import warp as wp


# Warp launches CPU kernels with block_dim 1, which is part of the module's hash: loading with
# any other block_dim would compile a second module that launches never use.
CPU_BLOCK_DIM = 1


def load_for_cpu(kernel):
    """Compile (or load from Warp's disk cache) ``kernel`` exactly as a CPU launch will use it."""
    return kernel.module.load(wp.get_device("cpu"), CPU_BLOCK_DIM)


def generated_source(kernel) -> str:
    """The C++ Warp generated for ``kernel`` (from its on-disk kernel cache), to prove what a
    specialized kernel does and does not contain."""
    load_for_cpu(kernel)
    name = kernel.module.get_module_identifier(CPU_BLOCK_DIM)
    with open(os.path.join(wp.config.kernel_cache_dir, name, name + ".cpp"), encoding="utf-8") as f:
        return f.read()
