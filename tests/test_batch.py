"""Batch rendering on a real Dask LocalCluster (two worker processes): the images equal serial
renders, a second run skips every job, a corrupt scene is one "error" line, a worker killed
mid-batch loses no image; and the jobs' validation and the message without Dask."""

import concurrent.futures
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from PIL import Image

import pbrwarp as pw
from pbrwarp import batch
from pbrwarp.cli import main
from pbrwarp.render_options import parse_light
from pbrwarp.meshes import SAMPLES

distributed = pytest.importorskip("distributed")

SIZE = 32
LIMIT = 120  # seconds any one batch may take here before the test fails rather than hang
BUNNY = "bunny-decimated.off"
LIGHT = "dir:-1,-1,-1:3"


def _within(seconds, function, *args, **kwargs):
    """function(*args, **kwargs), or a failed test after ``seconds`` (a hang must not stall CI)."""
    pool = concurrent.futures.ThreadPoolExecutor(1)
    try:
        return pool.submit(function, *args, **kwargs).result(timeout=seconds)
    except concurrent.futures.TimeoutError:
        pytest.fail(f"{getattr(function, '__name__', function)} took over {seconds} s")
    finally:
        pool.shutdown(wait=False)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=40)
    dask_client = distributed.Client(cluster)
    dask_client.wait_for_workers(2, timeout=LIMIT)
    yield dask_client
    dask_client.close()
    cluster.close()


def _jobs(folder, names, broken=False):
    """Jobs of 32 x 32 images of the bunny in ``folder`` (with a corrupt scene's job if
    ``broken``), each seen and lit in its own way, written to folder/jobs.jsonl."""
    shutil.copy(SAMPLES / BUNNY, folder / BUNNY)
    kinds = [
        {"camera": {"eye": [0.0, 0.12, 0.35], "target": [0.0, 0.1, 0.0], "fov_y": 40}, "lights": [LIGHT], "spp": 2},
        {"camera": "frame", "lights": ["point:0.2,0.4,0.3:0.5:1,0.8,0.6"], "seed": 3},
        {"camera": {"direction": [1.0, 0.3, 0.5]}, "lights": [LIGHT, "dir:1,-0.5,0:1"], "spp": 2,
         "shadows": False},
    ]
    jobs = [{"id": name, "scene": BUNNY, "output": f"out/{name}.{'npy' if i == 1 else 'png'}", "width": SIZE,
             "height": SIZE, **kinds[i % len(kinds)]} for i, name in enumerate(names)]
    if broken:
        (folder / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00 not a binary glTF")
        jobs.insert(1, {"id": "broken", "scene": "broken.glb", "output": "out/broken.png", "width": SIZE,
                        "height": SIZE, "lights": [LIGHT]})
    path = folder / "jobs.jsonl"
    path.write_text("".join(json.dumps(job) + "\n" for job in jobs))
    return path, jobs


def _serial(folder, job):
    """The job rendered in this process by pw.render, and loaded as the batch output is: (H, W, 3)
    uint8 for an image, (H, W, 4) float32 for .npy."""
    scene = pw.Scene.load(folder / job["scene"])
    for spec in job["lights"]:
        scene.add_light(parse_light(spec))
    view = job["camera"]
    if view == "frame":
        camera = pw.Camera.frame(scene)
    elif "direction" in view:
        camera = pw.Camera.frame(scene, direction=view["direction"])
    else:
        camera = pw.Camera.look_at(view["eye"], view["target"], fov_y=view["fov_y"])
    frame = pw.render(scene, camera, width=SIZE, height=SIZE, spp=job.get("spp", 1), seed=job.get("seed", 0),
                      shadows=job.get("shadows", True), progress=False)
    reference = folder / ("reference" + os.path.splitext(job["output"])[1])
    frame.save(reference)
    return _read(reference)


def _read(path):
    path = str(path)
    if path.endswith(".npy"):
        return np.load(path)
    with Image.open(path) as image:
        return np.asarray(image)


def _manifest(path):
    return [json.loads(line) for line in path.read_text().splitlines()]


@pytest.fixture(scope="module")
def first_run(client, tmp_path_factory):
    """A batch of three bunny jobs and one of a corrupt scene, after the serial renders (which also
    compile the kernels the workers then find in Warp's cache)."""
    folder = tmp_path_factory.mktemp("batch")
    jobs_path, jobs = _jobs(folder, ["front", "framed", "side"], broken=True)
    references = {job["id"]: _serial(folder, job) for job in jobs if job["id"] != "broken"}
    records = _within(LIMIT, pw.render_batch, jobs_path, client=client, progress=False)
    return folder, jobs, references, records


def test_batch_images_equal_serial_renders(first_run):
    folder, jobs, references, records = first_run
    by_id = {r["id"]: r for r in records}
    for job_id, reference in references.items():
        assert by_id[job_id]["status"] == "ok", by_id[job_id]
        output = _read(folder / next(j["output"] for j in jobs if j["id"] == job_id))
        assert output.shape == reference.shape
        assert np.array_equal(output, reference), job_id  # the render does not depend on threads


def test_a_corrupt_scene_is_one_error_line_and_the_others_ok(first_run):
    folder, jobs, _, records = first_run
    manifest = _manifest(folder / "jobs.manifest.jsonl")
    assert sorted(line["id"] for line in manifest) == sorted(job["id"] for job in jobs)
    errors = [line for line in manifest if line["status"] == "error"]
    assert [line["id"] for line in errors] == ["broken"]
    assert "broken.glb" in errors[0]["error"]
    assert all(line["status"] == "ok" and line["worker"].startswith("tcp://") and line["seconds"] > 0
               for line in manifest if line["id"] != "broken")
    assert not (folder / "out" / "broken.png").exists()
    assert [r["id"] for r in records] == [job["id"] for job in jobs]  # the records in the jobs' order


def test_running_a_batch_again_skips_every_finished_job(first_run, client):
    folder, jobs, _, _ = first_run
    outputs = sorted((folder / "out").iterdir())
    times = [p.stat().st_mtime_ns for p in outputs]
    records = _within(LIMIT, pw.render_batch, folder / "jobs.jsonl", client=client, progress=False)
    assert {r["id"]: r["status"] for r in records} == {
        job["id"]: "error" if job["id"] == "broken" else "skipped" for job in jobs}
    assert sorted((folder / "out").iterdir()) == outputs
    assert [p.stat().st_mtime_ns for p in outputs] == times
    assert len(_manifest(folder / "jobs.manifest.jsonl")) == 2 * len(jobs)  # appended


def test_an_unfinished_output_is_rendered_again(first_run, tmp_path):
    folder, jobs, _, _ = first_run
    job = batch.parse_job(jobs[0], str(folder))
    assert batch.finished(job)
    whole = (folder / jobs[0]["output"]).read_bytes()
    truncated = tmp_path / "front.png"
    truncated.write_bytes(whole[: len(whole) // 2])
    assert not batch.finished(batch.parse_job({**jobs[0], "output": str(truncated)}, str(folder)))
    other_size = batch.parse_job({**jobs[0], "width": SIZE + 1}, str(folder))
    assert not batch.finished(other_size)


def _renders(key, job_id) -> bool:
    """Whether the Dask task ``key`` renders the job ``job_id`` (keys: batch.job_key)."""
    return f"-{job_id}-" in str(key)


class _KillOnce(distributed.WorkerPlugin):
    """Kills (SIGKILL) the worker process whose job ``victim`` enters the state ``moment``
    ("executing": it starts; "memory": it has returned, its image written, and the scheduler is
    yet to hear of it), the first time only (``marker``, created exclusively, records the
    worker's address)."""

    def __init__(self, victim, moment, marker):
        self.victim, self.moment, self.marker = victim, moment, marker

    def setup(self, worker):
        self.address = worker.address

    def transition(self, key, start, finish, **kwargs):
        if finish != self.moment or not _renders(key, self.victim):
            return
        try:
            fd = os.open(self.marker, os.O_WRONLY | os.O_CREAT | os.O_EXCL)
        except FileExistsError:
            return
        os.write(fd, self.address.encode())
        os.close(fd)
        os.kill(os.getpid(), signal.SIGKILL)


@pytest.mark.parametrize("moment", ["executing", "memory"])
def test_a_worker_killed_mid_batch_loses_no_image(client, tmp_path, moment):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this file
    client.wait_for_workers(2, timeout=LIMIT)  # the last test's victim restarted
    names = [f"view{i}" for i in range(6)]
    jobs_path, jobs = _jobs(tmp_path, names)
    marker = tmp_path / "killed"
    client.register_plugin(_KillOnce("view2", moment, str(marker)), name="kill-once")
    try:
        records = _within(LIMIT, pw.render_batch, jobs_path, client=client, progress=False)
    finally:
        client.unregister_worker_plugin("kill-once")
    assert marker.exists(), "the victim's worker was not killed"
    killed = marker.read_text()
    assert [(r["id"], r["status"]) for r in records] == [(name, "ok") for name in names]
    assert next(r for r in records if r["id"] == "view2")["worker"] != killed  # rendered again elsewhere
    # (killed after writing its image, the worker's job is rendered and written again: harmless)
    manifest = _manifest(tmp_path / "jobs.manifest.jsonl")
    assert sorted(line["id"] for line in manifest) == sorted(names)  # one line per job
    # every image whole, and nothing else in the folder (no temporary file left behind)
    assert sorted(os.listdir(tmp_path / "out")) == sorted(os.path.basename(job["output"]) for job in jobs)
    assert all(batch.finished(batch.parse_job(job, str(tmp_path))) for job in jobs)


class _KillAlways(distributed.WorkerPlugin):
    """Kills (SIGKILL) every worker process as it starts the job ``victim``: a job that crashes
    whatever runs it (a segfault, the kernel's OOM killer)."""

    def __init__(self, victim):
        self.victim = victim

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and _renders(key, self.victim):
            os.kill(os.getpid(), signal.SIGKILL)


def test_a_job_that_kills_every_worker_is_an_error_and_the_others_are_ok(tmp_path):
    """On the local cluster render_batch starts (two workers; after one retry here, where the
    default allows three), the job that kills its worker is an "error" record, and only it: a
    worker holds no queued job that its death would count against. The ids are words, each of
    which Dask would take for a task group of its own were it the key's prefix."""
    import cloudpickle
    import dask

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this file
    names = ["front", "doomed", "back", "left", "right", "top"]
    jobs_path, _ = _jobs(tmp_path, names)
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = batch.local_cluster(2)
    with cluster, distributed.Client(cluster) as dask_client:
        dask_client.wait_for_workers(2, timeout=LIMIT)
        dask_client.register_plugin(_KillAlways("doomed"), name="kill-always")
        records = _within(LIMIT, pw.render_batch, jobs_path, client=dask_client, progress=False)
    assert [(r["id"], r["status"]) for r in records] == [(n, "error" if n == "doomed" else "ok") for n in names]
    assert "every worker that rendered it died" in records[1]["error"]
    assert [line["id"] for line in _manifest(tmp_path / "jobs.manifest.jsonl")].count("doomed") == 1


@pytest.mark.parametrize("job_id", ["front", "view_3", "2", "deadbeef", "a-b", "x y", "Änderung"])
def test_every_job_of_a_batch_is_in_one_dask_task_group(job_id):
    """Dask queues only a task group larger than twice the cluster's threads, a group being the
    key as dask.utils.key_split reads it: whatever its id, a job is in the batch's group."""
    from dask.utils import key_split

    assert key_split(batch.job_key(7, job_id, "0a1b2c3d4e5f")) == key_split(batch.job_key(0, "view0", "ffffffffffff"))


def _session_processes(session: int) -> list[int]:
    """The ids of the live processes of ``session`` (Linux's /proc; zombies count as ended)."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
        except (OSError, IndexError):  # not a process, or one that ended meanwhile
            continue
        if fields[0] != "Z" and int(fields[3]) == session:
            found.append(int(entry))
    return found


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="counts processes through Linux's /proc")
def test_ctrl_c_during_a_batch_ends_every_process_and_leaves_only_whole_files(tmp_path):
    """``pbrwarp batch`` on its own local cluster, its whole process group sent SIGINT (as a
    terminal's Ctrl-C) once a job is in the manifest: it says "interrupted" and exits 130, every
    process it started ends, each manifest line is a whole record, each output there is a whole
    image."""
    names = [f"view{i}" for i in range(16)]
    jobs_path, small = _jobs(tmp_path, names)
    jobs = [{**job, "width": 256, "height": 256, "spp": 8} for job in small]  # long enough to interrupt
    jobs_path.write_text("".join(json.dumps(job) + "\n" for job in jobs))
    manifest = tmp_path / "jobs.manifest.jsonl"
    process = subprocess.Popen([sys.executable, "-m", "pbrwarp", "batch", str(jobs_path)],
                               start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + LIMIT
        while not (manifest.exists() and manifest.read_text().count("\n") >= 1):
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.01)
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=LIMIT)
        while _session_processes(process.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _session_processes(process.pid) == [], "processes of the batch outlived it"
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130 and err.strip().endswith("pbrwarp: interrupted"), err
    done = _manifest(manifest)
    assert 1 <= len(done) < len(names) and all(line["status"] == "ok" for line in done)
    written = [job for job in jobs if (tmp_path / job["output"]).exists()]
    assert all(batch.finished(batch.parse_job(job, str(tmp_path))) for job in written)


def _count_scene_loads():
    """In a worker: make pw.Scene.load count its calls in pbrwarp.scene.loads_counted."""
    from pbrwarp import scene as scene_module

    scene_module.loads_counted = 0
    load = scene_module.Scene.__dict__["load"].__func__

    def counted(cls, *args, **kwargs):
        scene_module.loads_counted += 1
        return load(cls, *args, **kwargs)

    scene_module.Scene.original_load = scene_module.Scene.__dict__["load"]
    scene_module.Scene.load = classmethod(counted)


def _scene_loads_counted():
    """In a worker: the count _count_scene_loads kept, its Scene.load restored."""
    from pbrwarp import scene as scene_module

    scene_module.Scene.load = scene_module.Scene.__dict__["original_load"]
    del scene_module.Scene.original_load
    return scene_module.loads_counted


def test_each_worker_of_a_cluster_loads_a_scene_once_for_all_its_jobs(client, tmp_path):
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this file
    client.wait_for_workers(2, timeout=LIMIT)  # a killed worker restarted
    names = [f"view{i}" for i in range(8)]
    jobs_path, _ = _jobs(tmp_path, names)
    client.run(_count_scene_loads)
    try:
        records = _within(LIMIT, pw.render_batch, jobs_path, client=client, progress=False)
    finally:
        loads = client.run(_scene_loads_counted)
    assert all(r["status"] == "ok" for r in records)
    workers = {r["worker"] for r in records}
    assert {address: count for address, count in loads.items() if count} == dict.fromkeys(workers, 1)


def test_a_worker_keeps_each_scene_loaded_until_its_file_changes(tmp_path):
    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    path = str(tmp_path / BUNNY)
    first, _ = batch._loaded_scene(path)
    assert batch._loaded_scene(path)[0] is first
    os.utime(path, ns=(0, os.stat(path).st_mtime_ns + 10**9))
    assert batch._loaded_scene(path)[0] is not first


def test_a_worker_keeps_each_environment_until_its_file_or_intensity_changes(tmp_path):
    from assets import hdr

    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    shutil.copy(hdr("studio_small_03"), tmp_path / "sky.hdr")
    job = {"id": 1, "scene": BUNNY, "output": "one.png", "environment": "sky.hdr"}

    def environment(**change):
        return batch._loaded_environment(batch.parse_job({**job, **change}, str(tmp_path)).args)

    first = environment()
    assert environment() is first
    brighter = environment(env_intensity=2.0)
    assert brighter is not first and brighter.intensity == 2.0
    path = str(tmp_path / "sky.hdr")
    os.utime(path, ns=(0, os.stat(path).st_mtime_ns + 10**9))
    assert environment() is not first


@pytest.mark.parametrize("change, words", [
    ({"spp": 0}, "'spp': invalid samples per pixel '0'"),
    ({"width": 0}, "'width/height': invalid size '0x32'"),
    ({"lights": ["dir:0,0,0:3"]}, "'lights': invalid light 'dir:0,0,0:3'"),
    ({"lights": "dir:-1,-1,-1:3"}, "'lights' must be a list"),
    ({"tonemap": "filmic"}, "'tonemap': invalid choice"),
    ({"shadows": "soft"}, "'shadows' must be"),
    ({"camera": {"eye": [0, 0, 1], "target": [0, 0, 1]}}, "'camera'"),
    ({"camera": {"eye": [0, 0, 1]}}, "eye and target required"),
    ({"camera": {"eye": "here", "target": [0, 0, 0]}}, "'camera' eye"),
    ({"camera": {"direction": [0, 0, 0]}}, "'camera' direction"),
    ({"camera": "orbit"}, "'camera' must be"),
    ({"spq": 4}, "unknown key 'spq'"),
    ({"scene": "missing.obj"}, "scene file not found"),
    ({"environment": "sky.png"}, "not found"),
    ({"output": "out/image.xyz"}, "unknown image extension"),
    ({"id": None}, "needs an \"id\""),
])
def test_a_bad_job_is_an_error_record_naming_what_is_wrong(tmp_path, change, words):
    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    good = {"id": "good", "scene": BUNNY, "output": "out/good.png", "width": SIZE, "height": SIZE}
    (bad,) = [r for r in batch.read_jobs([good, {**good, "id": "bad", "output": "out/bad.png", **change}], tmp_path)
              if not isinstance(r, batch.Job)]
    assert bad["status"] == "error" and words in bad["error"], bad["error"]


def test_jobs_file_lines_that_are_not_jobs_or_repeat_an_output_are_errors(tmp_path):
    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    good = {"id": "a", "scene": BUNNY, "output": "out/a.png"}
    path = tmp_path / "jobs.jsonl"
    path.write_text(json.dumps(good) + "\n\n{not json\n" + json.dumps({**good, "id": "b"}) + "\n[1]\n")
    parsed = batch.read_jobs(path)
    assert isinstance(parsed[0], batch.Job) and parsed[0].output == str(tmp_path / "out" / "a.png")
    assert [(r["id"], r["error"].split(":")[0]) for r in parsed[1:]] == [
        ("line 3", f"line 3 of {path} is not JSON"), ("b", "its output is that of line 1"),
        ("line 5", "a job must be a JSON object, got list")]
    assert parsed[2]["output"] == parsed[0].output  # the error's record names the output it was to write
    path.write_bytes(b'{"id": "\xff"}\n')
    with pytest.raises(pw.InputError, match="not UTF-8"):
        batch.read_jobs(path)


def test_without_dask_the_batch_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed raises ImportError
    jobs = tmp_path / "jobs.jsonl"
    jobs.write_text("")
    with pytest.raises(ImportError, match=r'pip install "pbrwarp\[batch\]"'):
        pw.render_batch(jobs)
    assert main(["batch", str(jobs)]) == 2
    assert 'pip install "pbrwarp[batch]"' in capsys.readouterr().err


def test_the_cli_renders_a_turntable_against_a_scheduler_address(client, tmp_path, capsys):
    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    out = tmp_path / "turntable"
    argv = ["batch", "turntable", str(tmp_path / BUNNY), "--views", "3", "-o", str(out), "--size", "32x24",
            "--light", LIGHT]
    assert main(argv + ["--plan"]) == 0
    assert not list(out.glob("*.png"))
    jobs = [json.loads(line) for line in (out / "jobs.jsonl").read_text().splitlines()]
    assert [job["id"] for job in jobs] == ["view-000", "view-001", "view-002"]
    assert all(job["lights"] == [LIGHT] and (job["width"], job["height"]) == (32, 24) for job in jobs)
    # the eyes: on a circle about the bounds' centre, 120 degrees apart from +Z, 20 degrees up, at
    # the distance where the bounds' sphere spans the (narrower, vertical) 45 degree view
    lo, hi = pw.Scene.load(tmp_path / BUNNY).bounds()
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    eyes = np.array([job["camera"]["eye"] for job in jobs]) - centre
    distance = np.linalg.norm(eyes, axis=1)
    np.testing.assert_allclose(radius / distance, np.sin(np.radians(22.5)), rtol=1e-9)
    np.testing.assert_allclose(np.degrees(np.arcsin(eyes[:, 1] / distance)), 20.0, rtol=1e-9)
    np.testing.assert_allclose(np.degrees(np.arctan2(eyes[:, 0], eyes[:, 2])), [0.0, 120.0, -120.0], atol=1e-9)
    assert all(np.allclose(job["camera"]["target"], centre) for job in jobs)

    address = client.scheduler_info()["address"]
    capsys.readouterr()
    assert _within(LIMIT, main, argv + ["--scheduler", address]) == 0
    err = capsys.readouterr().err
    assert "3 rendered, 0 skipped (already done), 0 failed" in err
    assert "3/3" in err and ("image/s" in err or "s/image" in err)  # the progress bar, with its rate
    for job in jobs:
        with Image.open(out / job["output"]) as image:
            assert image.size == (32, 24)
    assert main(argv + ["--scheduler", address, "--workers", "2"]) == 2
    assert "--workers sets the size of the local cluster" in capsys.readouterr().err


def test_the_folder_generator_plans_views_of_every_scene_under_a_folder(tmp_path, capsys):
    library = tmp_path / "library"
    (library / "sub").mkdir(parents=True)
    shutil.copy(SAMPLES / BUNNY, library / "a.off")
    shutil.copy(SAMPLES / BUNNY, library / "sub" / "b.off")
    (library / "notes.txt").write_text("not a scene")
    out = tmp_path / "out"
    assert main(["batch", "folder", str(library), "--views", "2", "-o", str(out), "--format", "npy", "--plan"]) == 0
    jobs = [json.loads(line) for line in (out / "jobs.jsonl").read_text().splitlines()]
    assert [(job["id"], job["scene"], job["output"]) for job in jobs] == [
        ("a.off/view-000", "../library/a.off", "a.off/view-000.npy"),
        ("a.off/view-001", "../library/a.off", "a.off/view-001.npy"),
        ("sub/b.off/view-000", "../library/sub/b.off", "sub/b.off/view-000.npy"),
        ("sub/b.off/view-001", "../library/sub/b.off", "sub/b.off/view-001.npy")]
    directions = np.array([job["camera"]["direction"] for job in jobs[:2]])
    np.testing.assert_allclose(directions @ [0.0, 1.0, 0.0], np.sin(np.radians(20.0)))
    # azimuths 180 degrees apart: cos(20)^2 cos(180) + sin(20)^2
    np.testing.assert_allclose(directions[0] @ directions[1], -np.cos(np.radians(40.0)), atol=1e-12)
    assert all(isinstance(job, batch.Job) for job in batch.read_jobs(out / "jobs.jsonl"))
    assert main(["batch", "folder", str(tmp_path / "out"), "--views", "2", "-o", str(out), "--plan"]) == 2
    assert "no scene file" in capsys.readouterr().err


def test_without_a_client_the_batch_starts_and_closes_a_local_cluster(tmp_path):
    shutil.copy(SAMPLES / BUNNY, tmp_path / BUNNY)
    job = {"id": 7, "scene": BUNNY, "output": "seven.png", "width": SIZE, "height": SIZE, "lights": [LIGHT]}
    manifest = tmp_path / "done.jsonl"
    records = _within(LIMIT, pw.render_batch, [job], manifest=manifest, workers=1, root=tmp_path, progress=False)
    assert [(r["id"], r["status"]) for r in records] == [("7", "ok")]
    assert _manifest(manifest) == records
    assert batch.finished(batch.parse_job(job, str(tmp_path)))


def test_a_jobs_file_that_cannot_be_read_is_one_line_exit_2(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "missing.jsonl")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot read the jobs file" in err and "missing.jsonl" in err
