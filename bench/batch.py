"""The batch layer's cost: a turntable through pw.render_batch (Dask) against a plain loop of pw.render.

    python bench/batch.py [--views 64] [--size 512] [--spp 1] [--repeats 3]

Scene: the Stanford bunny (the full 69,451-triangle scan from the shared assets when they are beside
the clone, else the decimated one installed with pbrwarp; --model another file), lit by one
directional light, seen from --views eyes around it (pbrwarp.batch.turntable_jobs), PNG images.
"loop": one process, its scene loaded once for all rounds, calls pw.render and Frame.save per
view, every core rendering. "batch": pw.render_batch of the same jobs file on a LocalCluster of one worker process
(one job at a time, every core rendering, as `pbrwarp batch` starts it), its scene already loaded
and its kernels compiled by a warm-up batch, so that both sides time the same steady state; the
cluster's start-up is timed on its own. Each round times the loop and the batch in turn, each into
a fresh folder; medians over --repeats rounds after a warm-up round of each. Reports seconds per
image of each, the batch's overhead (batch / loop - 1; the issue's target: at most 5%), the
median of the jobs' own seconds in the worker (load, render, save) and the rest of the batch's
time per image (scheduling, messages, the manifest). Writes bench/results/batch.{md,json}
(--results another folder, e.g. for a smoke run).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import RESULTS, command_line, write_results  # noqa: E402

import pbrwarp as pw  # noqa: E402
from pbrwarp import batch  # noqa: E402
from pbrwarp.meshes import SAMPLES, asset  # noqa: E402

LIGHT = "dir:-1,-1,-1:3"


def default_model() -> str:
    try:
        return str(asset("meshes/stanford-bunny.obj"))
    except pw.AssetNotFoundError:
        return str(SAMPLES / "bunny-decimated.off")


def plan(model: str, folder: Path, views: int, size: int, spp: int) -> Path:
    """A turntable jobs file in ``folder`` (created), its images beside it."""
    folder.mkdir(parents=True)
    jobs = batch.turntable_jobs(model, views, folder, options={"width": size, "height": size, "spp": spp,
                                                               "lights": [LIGHT]})
    path = folder / "jobs.jsonl"
    batch.write_jobs(path, jobs)
    return path


def loaded_scene(jobs_path: Path):
    """The jobs' scene with their lights, loaded once for every round of the loop, as a batch
    worker keeps it."""
    job = batch.read_jobs(jobs_path)[0]
    scene = pw.Scene.load(job.args.input)
    for light in job.args.light:
        scene.add_light(light)
    return scene


def loop(scene, jobs: list) -> None:
    """The jobs as a plain loop of pw.render and Frame.save in this process."""
    for job in jobs:
        width, height = job.args.size
        frame = pw.render(scene, job.camera, width=width, height=height, spp=job.args.spp, progress=False)
        frame.save(job.output)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="batch.py", description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=64)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--model", default=None, help="scene file (default: the Stanford bunny)")
    ap.add_argument("--results", default=str(RESULTS), help="folder of batch.{md,json} (default bench/results)")
    args = ap.parse_args(argv)
    import distributed

    model = args.model or default_model()
    work = Path(tempfile.mkdtemp(prefix="pbrwarp-bench-batch-"))
    t0 = time.perf_counter()
    cluster = batch.local_cluster(1)  # as pw.render_batch starts it
    client = distributed.Client(cluster)
    client.wait_for_workers(1)
    startup = time.perf_counter() - t0
    try:
        loop_times, batch_times, job_seconds, scene = [], [], [], None
        for round_ in range(1 + args.repeats):  # round 0 warms up both (scene loaded, kernels compiled)
            jobs_path = plan(model, work / f"loop{round_}", args.views, args.size, args.spp)
            scene = scene or loaded_scene(jobs_path)
            jobs = batch.read_jobs(jobs_path)
            t0 = time.perf_counter()
            loop(scene, jobs)
            loop_seconds = time.perf_counter() - t0
            jobs_path = plan(model, work / f"batch{round_}", args.views, args.size, args.spp)
            t0 = time.perf_counter()
            records = pw.render_batch(jobs_path, client=client, progress=False)
            batch_seconds = time.perf_counter() - t0
            assert all(r["status"] == "ok" for r in records), [r for r in records if r["status"] != "ok"][:1]
            if round_:
                loop_times.append(loop_seconds / args.views)
                batch_times.append(batch_seconds / args.views)
                job_seconds += [r["seconds"] for r in records]
            print(f"round {round_}: loop {loop_seconds:.2f} s, batch {batch_seconds:.2f} s", file=sys.stderr)
    finally:
        client.close()
        cluster.close()
        shutil.rmtree(work, ignore_errors=True)
    row = {"model": os.path.basename(model), "views": args.views, "size": args.size, "spp": args.spp,
           "loop_s_per_image": statistics.median(loop_times), "batch_s_per_image": statistics.median(batch_times),
           "job_s_in_worker": statistics.median(job_seconds), "cluster_startup_s": startup}
    row["overhead"] = row["batch_s_per_image"] / row["loop_s_per_image"] - 1.0
    row["batch_s_per_image_outside_jobs"] = row["batch_s_per_image"] - row["job_s_in_worker"]
    markdown = (
        "| model | views | size | spp | loop s/image | batch s/image | overhead | job s in worker | "
        "batch s/image outside jobs | cluster start-up s |\n|---|---|---|---|---|---|---|---|---|---|\n"
        f"| {row['model']} | {row['views']} | {row['size']}² | {row['spp']} | {row['loop_s_per_image']:.3f} | "
        f"{row['batch_s_per_image']:.3f} | {100 * row['overhead']:+.1f}% | {row['job_s_in_worker']:.3f} | "
        f"{row['batch_s_per_image_outside_jobs']:.4f} | {row['cluster_startup_s']:.1f} |\n\n"
        "Seconds per image: medians over the rounds of each side's wall time / views, the loop and the batch "
        "timed in turn each round after a warm-up round. The batch runs on a LocalCluster of one worker "
        "process (one job at a time, every core rendering) started once, outside the timings (its start-up "
        "is the last column). \"job s in worker\": the median job's own time in the worker (scene lookup, "
        "render, save); \"outside jobs\": the rest of the batch's time per image (Dask scheduling and "
        "messages, the manifest, the resume check).\n")
    write_results("batch", command_line(ap, args), {"rows": [row]}, markdown, Path(args.results))


if __name__ == "__main__":
    main()
