"""What renders derive from a scene and keep for the next render, and the locks that let several
threads share it. Nothing is kept in attributes of the user's objects: everything lives in one of
the caches below.

Per scene: ``Scene.cache``, a :class:`SceneCache`. Its slots, what each holds, and the key that
decides when it is rebuilt (a key is computed from the scene at every lookup; a different key
builds the slot anew, which then replaces the old value):

====================================  ================================  =======================================
slot                                  value (built by)                  key
====================================  ================================  =======================================
"geometry"                            merged vertex arrays, BVH and     the primitives, by identity and
                                      clusters (gpu_scene.upload)       revision (validate.revision)
"texels"                              texture table and texels          the textures, by identity and
                                      (gpu_scene.upload)                revision, and sRGB flags of the
                                                                        primitives with UVs
"rows"                                the GpuScene: SceneData with      geometry, texels, the contents of
                                      material and light rows           every material and light
                                      (gpu_scene.upload)
("face flags", kind, flags)           per-triangle uint8 flags          the geometry; the last
                                      (gpu_scene.face_flags)            KEPT_FACE_FLAGS sets of each kind
"longest edges"                       per-triangle longest edge         the geometry
                                      (light_buffers)
"light buffers"                       the lights' light buffers         the geometry, the lights' placement
                                      (light_buffers.build)             (not colour or intensity), each
                                                                        material's sides and alpha mode
"shadow maps"                         the lights' depth maps            the geometry, the lights' placement,
                                      (shadow_maps.build)               the ShadowMap settings, the alpha
                                                                        cut-outs
"emitters"                            the path tracer's light table     the uploaded scene ("rows"), by
                                      (emitters.light_table)            identity
(fact, primitive), fact one of        a primitive's bounds, whether it  the primitive's revision
"bounds", "closed volume", "convex",  is a closed volume, or convex,
"hull points"                         its convex hull's vertices
                                      (gpu_scene, features, camera)
====================================  ================================  =======================================

A primitive's or texture's revision counts the assignments to its fields (``prim.positions =
...``, ``texture.image = ...``), so that setting one rebuilds what was derived from it; an array
changed in place is not seen (replace it instead). What no key holds (the camera, light colours
and intensities, material factors) is read anew by every render. A new geometry drops, at once,
every slot derived from the old one and the facts of primitives no longer in the scene (their
keys would no longer match; dropping frees the memory).
The light buffers are built without their interiors' marks; the first render that finds them
built (a second frame) stores a marked copy in their place (``Cache.improve``).

Process-wide: :data:`PROCESS_WIDE`, for what depends on no scene:

- ("sample positions", layout): the rasterizer's sample positions, which depend only on the
  image size, samples per pixel, stratification grid and seed; the last CACHED_SAMPLE_LAYOUTS
  layouts (pbrwarp.raster).
- ("prefiltered environment", id): an Environment's prefiltered levels and SH coefficients
  (:func:`prefiltered_environment`). Several scenes may share one Environment, whose texels are
  read-only, so it is prefiltered once for all of them; dropped when the Environment is collected.
- ("environment sampler", id): an Environment's importance sampler (:func:`environment_sampler`),
  kept and dropped in the same way.

Locks. Each cache has one lock over its table, held only to look up, store or drop an entry, never
while building one. Building a slot holds that slot's own build lock: a thread that needs a slot
another thread is building waits for it and takes its result, it never builds it again; different
slots, and different scenes' slots, build at the same time. A build may look up other slots but
never its own, and only downwards in this order, so no two threads can wait for each other:
rows, geometry, texels; emitters, light buffers and shadow maps; face flags and longest edges; facts; the
process-wide slots. A stored value is never changed: a render keeps using what it looked up,
whatever another thread stores meanwhile, and an improvement is a copy swapped in.
"""

from __future__ import annotations

import contextlib
import threading
import weakref

# The slots derived from the geometry, dropped with it.
GEOMETRY_DERIVED = ("rows", "face flags", "longest edges", "light buffers", "shadow maps", "emitters")
# The per-primitive facts' slot names: (fact, primitive).
PRIMITIVE_FACTS = ("bounds", "closed volume", "convex", "hull points")


class _Entry:
    __slots__ = ("key", "value")

    def __init__(self, key, value):
        self.key = key
        self.value = value


class _BuildTurn:
    """A slot's build lock and how many threads hold or wait for it (dropped at none)."""

    __slots__ = ("lock", "users")

    def __init__(self):
        self.lock = threading.RLock()
        self.users = 0


def _family(slot):
    """The name of ``slot``'s kind: the slot itself, or its first element."""
    return slot[0] if isinstance(slot, tuple) else slot


class Cache:
    """Values built once per (slot, key) and shared by every thread (see the module docstring).

    A slot is any hashable name; its key is compared with ``==`` (objects that compare by
    identity, like Primitive and Texture, stand for themselves and are kept alive by it). Values
    are never None and never changed once stored."""

    def __init__(self):
        self._lock = threading.Lock()
        self._entries: dict = {}
        self._turns: dict = {}

    # pickled or deep-copied (with a Scene), a cache starts empty
    def __getstate__(self):
        return {}

    def __setstate__(self, state):
        self.__init__()

    def lookup(self, slot, key):
        """The value of ``slot`` if it was built for ``key``, else None."""
        with self._lock:
            entry = self._entries.get(slot)
            if entry is None or entry.key != key:
                return None
            self._entries[slot] = self._entries.pop(slot)  # most recently used last
            return entry.value

    def get(self, slot, key, build, keep: int | None = None):
        """The value of ``slot`` for ``key``: the one kept, else ``build()``'s, stored in its place.
        One thread builds; others asking meanwhile wait for its result. ``keep``: at most this many
        slots that agree but for their last element (("face flags", kind, ...)) are kept, the least
        recently used dropped."""
        value = self.lookup(slot, key)
        if value is not None:
            return value
        with self._build_turn(slot) as _:
            value = self.lookup(slot, key)  # built while this thread waited
            if value is None:
                value = build()
                self._store(slot, key, value, keep)
        return value

    def improve(self, slot, key, current, improve):
        """``improve(current)``, a better value of ``slot`` for ``key`` made without changing
        ``current``, stored in its place and returned; by one thread: while another builds this
        slot, ``current`` is returned at once (the caller renders with it rather than wait). Returns
        what the slot holds instead if it no longer holds ``current``."""
        with self._build_turn(slot, blocking=False) as acquired:
            if not acquired:
                return current
            found = self.lookup(slot, key)
            if found is not current:
                return current if found is None else found
            better = improve(current)
            with self._lock:
                entry = self._entries.get(slot)
                if entry is not None and entry.value is current:
                    entry.value = better
        return better

    def drop(self, slot):
        """Forget ``slot`` (no error if it holds nothing)."""
        with self._lock:
            self._entries.pop(slot, None)

    def clear(self):
        """Forget every slot: the next renders build what they need again."""
        with self._lock:
            self._entries.clear()

    @contextlib.contextmanager
    def dropped(self, slot):
        """Within the block, ``slot`` holds nothing at first (for timing its build); afterwards it
        holds what it held before, if anything, in place of what the block stored."""
        with self._lock:
            kept = self._entries.pop(slot, None)
        try:
            yield
        finally:
            if kept is not None:
                with self._lock:
                    self._entries[slot] = kept

    def _store(self, slot, key, value, keep):
        if value is None:
            raise ValueError(f"a cache slot cannot hold None ({slot!r})")
        with self._lock:
            self._entries.pop(slot, None)
            self._entries[slot] = _Entry(key, value)
            if keep is not None:
                group = [s for s in self._entries if isinstance(s, tuple) and s[:-1] == slot[:-1]]
                for oldest in group[:max(len(group) - keep, 0)]:
                    del self._entries[oldest]
            self._stored(slot, key)

    def _stored(self, slot, key):
        """Called under the table's lock after ``slot`` was stored for ``key``."""

    @contextlib.contextmanager
    def _build_turn(self, slot, blocking: bool = True):
        """Holds ``slot``'s build lock within the block (yields whether it got it; with
        ``blocking`` it always does)."""
        with self._lock:
            turn = self._turns.get(slot)
            if turn is None:
                turn = self._turns[slot] = _BuildTurn()
            turn.users += 1
        acquired = turn.lock.acquire(blocking)
        try:
            yield acquired
        finally:
            if acquired:
                turn.lock.release()
            with self._lock:
                turn.users -= 1
                if turn.users == 0:
                    del self._turns[slot]


class SceneCache(Cache):
    """One scene's cache (``Scene.cache``): :class:`Cache` plus the rule that a new geometry drops
    what was derived from the old one (see the module docstring)."""

    def _stored(self, slot, key):
        if slot != "geometry":
            return
        primitives = {primitive for primitive, _ in key}  # key: (primitive, revision) pairs
        for stale in [s for s in self._entries if _family(s) in GEOMETRY_DERIVED
                      or (_family(s) in PRIMITIVE_FACTS and s[1] not in primitives)]:
            del self._entries[stale]

    def fact(self, name: str, primitive, compute):
        """A fact about ``primitive`` (one of PRIMITIVE_FACTS), ``compute(primitive)`` the first time."""
        return self.get((name, primitive), primitive._revision, lambda: compute(primitive))


PROCESS_WIDE = Cache()


def prefiltered_environment(environment, build):
    """``environment``'s prefiltered data, ``build()`` the first time in this process; dropped from
    PROCESS_WIDE when the environment is collected (before its id can name another)."""
    return _of_environment("prefiltered environment", environment, build)


def environment_sampler(environment, build):
    """``environment``'s importance sampler, ``build()`` the first time in this process; dropped
    as its prefiltered data is."""
    return _of_environment("environment sampler", environment, build)


def _of_environment(kind, environment, build):
    slot = (kind, id(environment))

    def build_and_forget_later():
        value = build()
        weakref.finalize(environment, PROCESS_WIDE.drop, slot)
        return value

    return PROCESS_WIDE.get(slot, None, build_and_forget_later)
