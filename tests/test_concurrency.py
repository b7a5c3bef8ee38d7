"""One Scene rendered from several Python threads at once gives the images serial renders give and
never crashes, and the scene cache (pbrwarp/scene_cache.py) builds each slot once however many
threads ask for it.

The hammer runs in a subprocess with a timeout, so that a deadlock or a corrupted interpreter
fails the test instead of the run. ``python tests/test_concurrency.py ROUNDS THREADS`` runs it
alone and prints each mismatch or error."""

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[1]
if __name__ == "__main__":  # the subprocess imports this checkout's pbrwarp, as pytest run from ROOT does
    sys.path.insert(0, str(ROOT))
    import warp as wp

    wp.config.quiet = True

import pbrwarp as pw  # noqa: E402
from pbrwarp.scene_cache import PROCESS_WIDE, SceneCache  # noqa: E402

ROUNDS = 12
THREADS = 4
# The kernels are compiled before the subprocess starts (test_one_scene_...): this bounds the
# hammer itself, which takes ~10 s on 2 busy cores (development runs).
TIMEOUT_SECONDS = 240
CAMERA = pw.Camera.look_at(eye=(0.0, 1.5, 4.0), target=(0.0, -0.3, 0.0))
# every lazily built part of a render: raster and ray-cast visibility (with sample positions for
# spp > 1), light buffers and their marks, shadow maps, the environment's prefiltering
VARIANTS = [dict(visibility=visibility, shadows=shadows) for visibility in ("raster", "raycast")
            for shadows in ("rays", pw.ShadowMap(resolution=256))]
OPTIONS = dict(width=40, height=30, spp=4, progress=False)


def fresh_scene() -> pw.Scene:
    """The issue's probe: a sphere, a box and a floor under a point and a directional light, here
    also lit by an environment of its own."""
    scene = pw.Scene()
    scene.add_mesh(trimesh.creation.icosphere(subdivisions=3, radius=0.7), pw.Material(base_color=(0.8, 0.3, 0.2),
                                                                                       roughness=0.4))
    scene.add_mesh(trimesh.creation.box((0.8, 0.8, 0.8)), pw.Material(metallic=1.0, roughness=0.3),
                   transform=trimesh.transformations.translation_matrix((1.3, -0.6, 0.2)))
    scene.add_mesh(trimesh.Trimesh([[-4, -1, -4], [4, -1, -4], [4, -1, 4], [-4, -1, 4]], [[0, 2, 1], [0, 3, 2]]),
                   pw.Material(base_color=(0.7, 0.7, 0.7)))
    scene.add_light(pw.PointLight(position=(1.5, 3.0, 2.0), intensity=40.0))
    scene.add_light(pw.DirectionalLight(direction=(-0.4, -1.0, -0.3), intensity=2.0))
    scene.environment = pw.Environment.sky(height=16, intensity=0.3)
    return scene


def frame(scene, variant: dict, threads=None) -> np.ndarray:
    return pw.render(scene, CAMERA, threads=threads, **variant, **OPTIONS).rgb


def hammer(rounds: int, threads: int) -> list[str]:
    """Per round, a fresh scene (and no sample positions kept) rendered by ``threads`` threads
    at once, half of them on every core, the others on 2 or 1 render threads: first all of them
    in each variant in turn (so every lazy build, and the first reuse of the light buffers, which
    marks them, happen with every thread asking at the same moment), then each in every variant,
    starting with a different one. Every frame must equal the serial one. Returns what went wrong."""
    serial_scene = fresh_scene()
    first = [frame(serial_scene, variant) for variant in VARIANTS]
    serial = [frame(serial_scene, variant) for variant in VARIANTS]  # reusing every cache, light buffers marked
    failures = [f"variant {i}: the serial first and second frames differ" for i in range(len(VARIANTS))
                if not np.array_equal(first[i], serial[i])]
    for round_ in range(rounds):
        PROCESS_WIDE.clear()
        scene = fresh_scene()
        for phase in ("together", "mixed"):
            frames, errors = {}, []
            start = threading.Barrier(threads)

            def work(k):
                try:
                    for step in range(len(VARIANTS)):
                        if phase == "together":
                            start.wait()
                        i = step if phase == "together" else (k + step) % len(VARIANTS)
                        frames[k, i] = frame(scene, VARIANTS[i], threads=None if k % 2 == 0 else 1 + k % 3)
                except BaseException as error:  # noqa: BLE001 - reported below
                    start.abort()
                    errors.append(f"round {round_}, {phase}, thread {k}: {type(error).__name__}: {error}")

            workers = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
            for worker in workers:
                worker.start()
            for worker in workers:
                worker.join()
            failures += errors
            failures += [f"round {round_}, {phase}, thread {k}: variant {i} differs from the serial frame"
                         for (k, i), rgb in sorted(frames.items()) if not np.array_equal(rgb, serial[i])]
    return failures


def test_one_scene_rendered_by_many_threads_at_once_matches_serial_renders():
    for variant in VARIANTS:  # compile here, so that the subprocess's timeout bounds the hammer alone
        frame(fresh_scene(), variant)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    try:
        run = subprocess.run([sys.executable, __file__, str(ROUNDS), str(THREADS)], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=TIMEOUT_SECONDS)
    except subprocess.TimeoutExpired as timeout:
        pytest.fail(f"the hammer did not finish in {TIMEOUT_SECONDS} s (a deadlock?)\n{timeout.stdout}")
    report = f"exit status {run.returncode}\n{run.stdout[-4000:]}\n{run.stderr[-4000:]}"
    assert run.returncode == 0, report  # negative: killed by a signal (-11: a segmentation fault)
    assert "every frame equals its serial frame" in run.stdout, report


def test_a_slot_is_built_once_for_all_the_threads_asking_for_it():
    cache = SceneCache()
    builds = []

    def build():
        builds.append(threading.get_ident())
        time.sleep(0.05)  # the other threads ask meanwhile
        return object()

    values = [None] * 8
    start = threading.Barrier(len(values))

    def ask(k):
        start.wait()
        values[k] = cache.get("shadow maps", "key", build)

    workers = [threading.Thread(target=ask, args=(k,)) for k in range(len(values))]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert len(builds) == 1 and all(value is values[0] for value in values)
    assert cache.get("shadow maps", "another key", object) is not values[0]


def test_an_improvement_is_made_once_while_the_others_keep_the_value_they_had():
    cache = SceneCache()
    plain = cache.get("light buffers", "key", lambda: "plain")
    improving = threading.Event()
    release = threading.Event()

    def improve(current):
        improving.set()
        release.wait(10.0)
        return current + ", improved"

    improver = threading.Thread(target=lambda: cache.improve("light buffers", "key", plain, improve))
    improver.start()
    improving.wait(10.0)
    # while one thread improves the slot, another gets the plain value at once
    assert cache.improve("light buffers", "key", plain, lambda current: pytest.fail("improved twice")) == "plain"
    release.set()
    improver.join()
    assert cache.lookup("light buffers", "key") == "plain, improved"


def test_a_new_geometry_drops_what_was_derived_from_the_old():
    class Primitive:  # a stand-in: identity and revision are all the cache reads of it
        _revision = 0

    cache = SceneCache()
    kept, dropped = Primitive(), Primitive()
    cache.get("geometry", ((kept, 0), (dropped, 0)), lambda: "old geometry")
    cache.get("texels", (), lambda: "texels")
    for slot in ("rows", ("face flags", "culling", (True,)), "longest edges", "light buffers", "shadow maps"):
        cache.get(slot, "old geometry", lambda: "derived")
    for primitive in (kept, dropped):
        cache.fact("bounds", primitive, lambda p: "bounds")
    cache.get("geometry", ((kept, 0),), lambda: "new geometry")
    assert cache.lookup("texels", ()) == "texels"
    assert cache.lookup(("bounds", kept), 0) == "bounds"
    assert cache.lookup(("bounds", dropped), 0) is None
    assert all(cache.lookup(slot, "old geometry") is None
               for slot in ("rows", ("face flags", "culling", (True,)), "longest edges", "light buffers", "shadow maps"))


def test_a_group_of_slots_keeps_its_most_recently_used():
    cache = SceneCache()
    for n in range(3):
        cache.get(("face flags", "culling", n), "g", lambda n=n: n, keep=2)
    cache.lookup(("face flags", "culling", 1), "g")  # used: now the most recent
    cache.get(("face flags", "culling", 3), "g", lambda: 3, keep=2)
    assert [cache.lookup(("face flags", "culling", n), "g") for n in range(4)] == [None, 1, None, 3]


def test_rendering_puts_no_attributes_into_the_users_objects():
    scene = fresh_scene()
    before = {id(obj): set(vars(obj)) for obj in (scene, *scene.primitives, *scene.lights, scene.environment,
                                                    *(p.material for p in scene.primitives))}
    for variant in VARIANTS:
        frame(scene, variant)
    pw.explain(scene)
    for obj in (scene, *scene.primitives, *scene.lights, scene.environment, *(p.material for p in scene.primitives)):
        assert set(vars(obj)) == before[id(obj)], type(obj).__name__


def test_scenes_sharing_an_environment_prefilter_it_once():
    environment = pw.Environment.sky(height=16)
    a, b = environment.data(), environment.data()
    assert a is not b and a.sh is b.sh and a.radiance.texels is b.radiance.texels
    environment.intensity = 2.0
    assert environment.data().intensity == 2.0 and a.intensity == 1.0


if __name__ == "__main__":
    started = time.perf_counter()
    problems = hammer(int(sys.argv[1]), int(sys.argv[2]))
    print("\n".join(problems) if problems else "every frame equals its serial frame",
          f"({time.perf_counter() - started:.1f} s)")
    sys.exit(1 if problems else 0)
