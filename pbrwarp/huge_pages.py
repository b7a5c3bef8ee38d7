"""Fresh CPU arrays backed by transparent huge pages where Linux offers them.

The first touch of fresh memory page-faults once per 4 KiB page, and page faults serialize on
the process's memory map: filling a new 2048² visibility buffer (32 MiB, 8192 faults) scaled
badly across threads. Asking for huge pages (madvise(MADV_HUGEPAGE); honoured when
/sys/kernel/mm/transparent_hugepage/enabled is "madvise" or "always") makes that one fault per
2 MiB. Elsewhere, or if the kernel refuses, the array is an ordinary one.
"""

from __future__ import annotations

import ctypes
import sys

import warp as wp

MADV_HUGEPAGE = 14  # linux/mman.h
HUGE_PAGE = 2 << 20
# Smallest array worth the advice: it applies to whole 2 MiB pages only.
MIN_BYTES = 2 * HUGE_PAGE


def _madvise():
    if not sys.platform.startswith("linux"):
        return None
    try:
        madvise = ctypes.CDLL(None, use_errno=True).madvise
    except (OSError, AttributeError):
        return None
    madvise.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
    madvise.restype = ctypes.c_int
    return madvise


_MADVISE = _madvise()


def empty(shape, dtype) -> wp.array:
    """wp.empty(shape, dtype) on the CPU, its untouched pages advised to be huge."""
    array = wp.empty(shape, dtype=dtype, device="cpu")
    size = array.capacity
    if _MADVISE is not None and size >= MIN_BYTES:
        # madvise wants a page-aligned start; the advice covers the huge pages inside the range
        start = array.ptr & ~4095
        _MADVISE(start, array.ptr + size - start, MADV_HUGEPAGE)
    return array


def zeros(shape, dtype) -> wp.array:
    """wp.zeros(shape, dtype) on the CPU, its pages advised to be huge before they are zeroed."""
    array = empty(shape, dtype)
    array.zero_()
    return array
