"""Work queues shared by concurrent CPU launches: one int32 counter that each launch's threads
take the next item index from, atomically; or ranges of items, each owned by a launch that takes
them from its start while the others, once done with theirs, take them from its end.

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


@wp.func_native("return __atomic_load_n(counters.data + slot, __ATOMIC_RELAXED);")
def read_counter(counters: wp.array(dtype=wp.int32), slot: int) -> int:
    """counters[slot] as another thread may be changing it (a flag set from Python, say): read
    afresh at every call, never kept in a register across a loop."""
    ...


@wp.func
def take_next_item(counter: wp.array(dtype=wp.int32)) -> int:
    """The counter's (counter[0]'s) value before incrementing it by one, atomically across threads."""
    return take_next_item_from(counter, 0)


# int64 words between ranges (a 64-byte cache line, the 8 of the snippets below), lest one
# launch's takes evict another's range from its cache.
RANGE_STRIDE = 8


@wp.func_native("""
    __atomic_store_n(ranges.data + (size_t)index * 8, ((wp::int64)end << 32) | (unsigned int)start,
                     __ATOMIC_RELAXED);
    """)
def reset_range(ranges: wp.array(dtype=wp.int64), index: int, start: int, end: int):
    """Range ``index`` of ``ranges`` (RANGE_STRIDE words each) set to the items [start, end)."""
    ...


@wp.func_native("""
    wp::int64* word = ranges.data + (size_t)index * 8;
    wp::int64 held = __atomic_load_n(word, __ATOMIC_RELAXED);
    while (true) {
        int start = (int)(held & 0xffffffffLL);
        int end = (int)(held >> 32);
        if (start >= end) return -1;
        wp::int64 rest = from_start ? (((wp::int64)end << 32) | (unsigned int)(start + 1))
                                    : (((wp::int64)(end - 1) << 32) | (unsigned int)start);
        if (__atomic_compare_exchange_n(word, &held, rest, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED))
            return from_start ? start : end - 1;
    }
    """)
def take_from_range(ranges: wp.array(dtype=wp.int64), index: int, from_start: bool) -> int:
    """The first (``from_start``) or last item left in range ``index`` of ``ranges``, taken
    atomically across threads (one compare-and-swap of its word, end << 32 | start); -1 if none
    is left."""
    ...


@wp.func
def take_next_from_ranges(ranges: wp.array(dtype=wp.int64), first: int, launch: int, launches: int, owner: int):
    """(item, owner): the next item for ``launch`` of ranges first .. first + launches - 1, range
    first + k owned by launch k: from the start of its own range while any is left, then from the
    end of the others' in turn, ``owner`` being where the previous take found one (start with
    ``launch``); item -1 once every range is empty."""
    while True:
        item = take_from_range(ranges, first + owner, owner == launch)
        if item >= 0:
            return item, owner
        owner = (owner + 1) % launches
        if owner == launch:
            return -1, owner
