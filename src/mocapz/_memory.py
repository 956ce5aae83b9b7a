"""Giving freed memory back to the system between the encoder's big steps (peak resident memory, issue 12).

glibc's ``malloc`` keeps the memory of freed arrays in its heap for reuse: after a step that made and freed
a clip's worth of arrays (the correction's verification rounds), the heap holds megabytes of free pages that
count in the process's resident memory, and a next step whose memory comes from elsewhere (zstd's work space
at level 19, ``mmap``-ed) adds to them. :func:`release_free_memory` hands those pages back
(``malloc_trim(0)``); it changes no value, only where the next allocations land. A no-op where the C library
is not glibc.
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim`` (among the symbols the process has loaded), or None (another C library)."""
    try:
        fn = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn  # type: ignore[no-any-return]


def release_free_memory() -> None:
    """Hand the free pages of the C heap back to the system (glibc; elsewhere nothing)."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
