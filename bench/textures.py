"""Texture sampling: pbrwarp's own bilinear sampler over one flat texel array vs wp.Texture2D.

    python bench/textures.py [--repeats 5]

Both sample the same float32 RGBA texture with bilinear filtering and repeat wrapping at the
same random UVs (one kernel launch of N lookups on one thread); the result also checks that the
two agree. The own sampler is also timed on the 8-bit sRGB texels pbrwarp keeps for 8-bit images
(decoded in the kernel), against wp.Texture2D over the same texels decoded to float32. Writes
bench/results/textures.{md,json}.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, median_time, write_results  # noqa: E402

from pbrwarp.kernels.textures import TEXELS_FLOAT, TEXELS_SRGB8, WRAP_REPEAT, Texels, TextureData, sample_texture, texel_store  # noqa: E402
from pbrwarp.textures import UNORM8_DECODE  # noqa: E402

LOOKUPS = 1_000_000


@wp.kernel(enable_backward=False)
def sample_own(tex: TextureData, texels: Texels, uv: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = sample_texture(tex, texels, uv[i])


@wp.kernel(enable_backward=False)
def sample_warp(tex: wp.Texture2D, uv: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = wp.texture_sample(tex, uv[i], dtype=wp.vec4)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    rng = np.random.default_rng(0)
    rows = []
    for size, texel_format in ((256, TEXELS_FLOAT), (2048, TEXELS_FLOAT), (256, TEXELS_SRGB8), (2048, TEXELS_SRGB8)):
        if texel_format == TEXELS_FLOAT:
            image = rng.uniform(0, 1, (size, size, 4)).astype(np.float32)
            texels = texel_store([image.reshape(-1, 4)])
        else:
            stored = rng.integers(0, 256, (size, size, 4), dtype=np.uint8)
            image = UNORM8_DECODE[stored + np.array([256, 256, 256, 0])]
            texels = texel_store(unorm8=[stored.reshape(-1, 4)], decode=UNORM8_DECODE)
        for pattern in ("coherent", "random"):
            if pattern == "random":
                uv = rng.uniform(-2, 3, (LOOKUPS, 2)).astype(np.float32)
            else:  # a sweep along rows, as neighbouring pixels of a textured surface
                t = np.arange(LOOKUPS, dtype=np.float64)
                uv = np.stack([(t % 1000) / 1000.0, (t // 1000) / 1000.0], -1).astype(np.float32)
            uv_wp = wp.array(uv, dtype=wp.vec2, device="cpu")
            row = TextureData()
            row.offset, row.width, row.height, row.wrap_s, row.wrap_t = 0, size, size, WRAP_REPEAT, WRAP_REPEAT
            row.texel_format = texel_format
            row.uv_row0, row.uv_row1 = wp.vec3(1, 0, 0), wp.vec3(0, 1, 0)
            tex = wp.Texture2D(image, address_mode=wp.TextureAddressMode.WRAP, device="cpu")
            out_own = wp.empty(LOOKUPS, dtype=wp.vec4, device="cpu")
            out_warp = wp.empty(LOOKUPS, dtype=wp.vec4, device="cpu")

            def own():
                wp.launch(sample_own, dim=LOOKUPS, inputs=[row, texels, uv_wp, out_own], device="cpu")

            def warp_tex():
                wp.launch(sample_warp, dim=LOOKUPS, inputs=[tex, uv_wp, out_warp], device="cpu")

            t_own = median_time(own, args.repeats)
            t_warp = median_time(warp_tex, args.repeats)
            diff = float(np.max(np.abs(out_own.numpy() - out_warp.numpy())))
            texels_name = "float32" if texel_format == TEXELS_FLOAT else "8-bit sRGB"
            rows.append({"size": size, "texels": texels_name, "pattern": pattern, "own_ns": 1e9 * t_own / LOOKUPS,
                         "texture2d_ns": 1e9 * t_warp / LOOKUPS, "ratio": t_warp / t_own, "max_abs_diff": diff})
            print(rows[-1], file=sys.stderr)
    lines = ["| texture | UVs | own sampler ns/lookup | wp.Texture2D ns/lookup | Texture2D / own | max abs difference |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['size']}² RGBA {r['texels']} | {r['pattern']} | {r['own_ns']:.1f} | {r['texture2d_ns']:.1f} | "
                     f"{r['ratio']:.2f} | {r['max_abs_diff']:.1e} |")
    lines.append("")
    lines.append(f"{LOOKUPS:,} bilinear lookups with repeat wrapping per launch, one thread, median of {args.repeats} after a warm-up.")
    command = command_line(ap, args)
    write_results("textures", command, {"rows": rows}, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
