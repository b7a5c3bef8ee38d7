"""The raster's visibility timings of two revisions of pbrwarp, measured in one run, in turn.

    python bench/revisions.py BASE [--rounds 3] [--repeats 15] [--case icosphere:5:1024 ...]

Checks BASE (any git revision) out into a temporary worktree beside this checkout and, round after round, times each
case in a fresh Python process of BASE and then of this checkout, alternately, so that a burst of
load on this shared machine falls on both alike. Each process runs bench/visibility.py's
``bench_case`` of *its own* revision (rasterization on 1 and all threads, and Embree's ray cast
as a yardstick; medians of --repeats after a warm-up) with the camera fitted to the mesh's
bounding sphere (``--framing sphere``), which is how both revisions can frame it. Cases:
``icosphere:SUBDIVISIONS:SIZE`` or ``bunny:SIZE``. Reports per case the median over rounds of
each revision's times, and of the per-round ratio this / BASE.
Writes bench/results/revisions.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, write_results  # noqa: E402

HERE = Path(__file__).resolve().parents[1]
FIELDS = ("raster_ms_1t", "raster_ms_2t", "embree_ms")

# Run inside the checkout being timed (its root the working directory, first on sys.path).
CHILD = """
import inspect, json, os, sys
sys.path.insert(0, os.getcwd())
sys.path.insert(0, os.path.join(os.getcwd(), "bench"))
import visibility
from pbrwarp.meshes import bunny, icosphere
kind, *numbers = sys.argv[1].split(":")
mesh = icosphere(int(numbers[0])) if kind == "icosphere" else bunny(decimated=False)
size = int(numbers[-1])
options = {"framing": "sphere"} if "framing" in inspect.signature(visibility.bench_case).parameters else {}
row = visibility.bench_case(kind, mesh, size, int(sys.argv[2]), os.cpu_count() or 1, **options)
print(json.dumps(row))
"""


def time_case(tree: Path, case: str, repeats: int) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, case, str(repeats)], cwd=tree, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"timing {case} in {tree} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(prog="revisions.py", description=__doc__.splitlines()[0])
    ap.add_argument("base", help="the git revision to compare this checkout with")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--case", nargs="*", default=["icosphere:5:1024", "icosphere:6:1024", "bunny:1024"])
    args = ap.parse_args(argv)
    base_commit = subprocess.run(["git", "rev-parse", "--short", args.base], cwd=HERE, capture_output=True,
                                 text=True, check=True).stdout.strip()
    rows = []
    # beside this checkout, so that both find the shared assets (../shared) the same way
    base_tree = Path(tempfile.mkdtemp(prefix=".pbrwarp-base-", dir=HERE.parent))
    subprocess.run(["git", "worktree", "add", "--detach", "--quiet", str(base_tree), args.base], cwd=HERE, check=True)
    try:
        for case in args.case:
            runs = {"base": [], "this": []}
            for _ in range(args.rounds):
                runs["base"].append(time_case(base_tree, case, args.repeats))
                runs["this"].append(time_case(HERE, case, args.repeats))
            row = {"case": case, "coverage": runs["this"][0]["coverage"]}
            for field in FIELDS:
                for side in ("base", "this"):
                    row[f"{side}_{field}"] = statistics.median(r[field] for r in runs[side])
                row[f"ratio_{field}"] = statistics.median(t[field] / b[field]
                                                         for b, t in zip(runs["base"], runs["this"]))
            rows.append(row)
            print(row, file=sys.stderr)
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base_tree)], cwd=HERE, check=False)
        shutil.rmtree(base_tree, ignore_errors=True)
    write_results("revisions", command_line(ap, args), {"base": base_commit, "rows": rows},
                  markdown(rows, base_commit, args))


def markdown(rows, base_commit, args) -> str:
    lines = [f"| case (sphere framing) | coverage | raster 1t ms: {base_commit} / this (ratio) | raster all threads ms: "
             f"{base_commit} / this (ratio) | Embree ms: {base_commit} / this (ratio) |",
             "|---|---|---|---|---|"]
    for r in rows:
        cells = [f"{r[f'base_{f}']:.2f} / {r[f'this_{f}']:.2f} ({r[f'ratio_{f}']:.3f})" for f in FIELDS]
        lines.append(f"| {r['case']} | {r['coverage']:.3f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + (
        f"\n\nEach case timed in {args.rounds} rounds, each round a fresh process of {base_commit} then one of this "
        f"checkout (bench/visibility.py's bench_case of each revision, medians of {args.repeats} after a warm-up); "
        "the table gives the medians over rounds and, in brackets, the median of the per-round ratios this / "
        f"{base_commit}. Embree (Open3D, the same rays in both) does not depend on pbrwarp's code: its ratio shows how "
        "far the machine itself drifted between the two processes of a round.\n")


if __name__ == "__main__":
    main()
