"""A work queue shared by concurrent CPU launches: one int32 counter that each launch's threads
take the next item index from, atomically.

Warp's own atomic_add is a plain read-modify-write on the CPU (a CPU launch runs on one thread),
so launches running side by side on a thread pool need a real atomic instruction to share work:
each item is then taken by exactly one launch, and a launch that finishes its items early takes
more instead of idling while another works through a heavier share.
"""

import warp as wp


@wp.func_native("return __atomic_fetch_add(counters.data + slot, 1, __ATOMIC_RELAXED);")
def take_next_item_from(counters: wp.array(dtype=wp.int32), slot: int) -> int:
    """counters[slot] before incrementing it by one, atomically across threads."""
    ...


@wp.func_native("__atomic_fetch_add(counters.data + slot, amount, __ATOMIC_RELAXED);")
def add_atomically(counters: wp.array(dtype=wp.int32), slot: int, amount: int):
    """counters[slot] += amount, atomically across threads."""
    ...


@wp.func
def take_next_item(counter: wp.array(dtype=wp.int32)) -> int:
    """The counter's (counter[0]'s) value before incrementing it by one, atomically across threads."""
    return take_next_item_from(counter, 0)
