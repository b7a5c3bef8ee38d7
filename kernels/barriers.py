"""Barriers of concurrent CPU launches: launches running side by side on a thread pool (a Warp CPU
launch runs on one thread) wait for each other in the kernel, spinning, rather than return to
Python between stages; see all_done."""

import warp as wp

wp.set_module_options({"enable_backward": False})

# Spins (pause instructions) of a waiting launch between yields of its core (see all_arrived).
SPINS_BEFORE_YIELD = wp.constant(1024)


@wp.func_native("""
    __atomic_add_fetch(sync.data + slot, amount, __ATOMIC_ACQ_REL);
    int spins = 0;
    while (__atomic_load_n(sync.data + slot, __ATOMIC_ACQUIRE) < total) {
        if (__atomic_load_n(sync.data + aborted, __ATOMIC_ACQUIRE) != 0) return false;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
        __builtin_arm_yield();
#endif
        if (++spins < spins_before_yield || os_yield == 0) continue;
        spins = 0;
        ((wp::int32 (*)(void))os_yield)();
    }
    return true;
    """)
def all_done(sync: wp.array(dtype=wp.int32), slot: int, amount: int, total: int, aborted: int,
             spins_before_yield: int, os_yield: wp.uint64) -> bool:
    """A barrier of the call's launches, which run side by side on a thread pool: adds ``amount``
    (the work this launch did) to counter ``slot`` and spins until it reaches ``total`` (what each
    wrote before is then visible to all); False if the call was aborted meanwhile. After every
    spins_before_yield spins (tens of microseconds) it calls ``os_yield`` (the address of the C
    library's sched_yield; 0: never), lest a launch waiting for another that is not running (more
    threads than cores, or cores taken by other processes) hold the core that one needs. Spinning
    rather than returning to Python between stages: a Python barrier's wake-ups, and the GIL
    passed back and forth for each stage's launch, would cost more than a small frame's drawing
    and make two threads slower than one."""
    ...


@wp.func_native("""
    int spins = 0;
    while (__atomic_load_n(released.data, __ATOMIC_ACQUIRE) < epoch) {
        if (__atomic_load_n(sync.data + aborted, __ATOMIC_ACQUIRE) != 0) return;
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
        __builtin_arm_yield();
#endif
        if (++spins < spins_before_yield || os_yield == 0) continue;
        spins = 0;
        ((wp::int32 (*)(void))os_yield)();
    }
    """)
def wait_for_release(released: wp.array(dtype=wp.int64), epoch: wp.int64, sync: wp.array(dtype=wp.int32),
                     aborted: int, spins_before_yield: int, os_yield: wp.uint64):
    """Spins as all_done does until released[0] >= epoch, which the caller's Python sets once
    launch 0 has returned to it: a pool thread's launch returning with launch 0's may take the
    GIL first, and the caller would then wait for the pool thread's way back to its queue.
    released[0] only grows, so that a
    launch that sees it late, after the caller's next call began, still stops."""
    ...


@wp.func
def all_arrived(sync: wp.array(dtype=wp.int32), slot: int, launches: int, aborted: int, spins_before_yield: int,
                os_yield: wp.uint64) -> bool:
    """all_done of one unit per launch: a barrier that every launch must reach."""
    return all_done(sync, slot, 1, launches, aborted, spins_before_yield, os_yield)
