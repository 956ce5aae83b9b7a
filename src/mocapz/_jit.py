"""The one switch of mocapz's compiled (numba) kernels outside the lossless codec, and whether there is room to
compile them.

numba is optional (``pip install mocapz[fast]``); every kernel has a NumPy (or constriction) path that stays the
reference. ``MOCAPZ_NO_NUMBA=1`` in the environment, or :func:`set_enabled` (tests), selects those paths: the
PGA decoder's kernels (:mod:`mocapz.codecs.pga.ikjit`), the correction layer's
(:mod:`mocapz.codecs.correction.compiled`) and the range decoder's (:mod:`mocapz.format.entropy`).
"""

from __future__ import annotations

import os

_ENABLED = os.environ.get("MOCAPZ_NO_NUMBA", "") in ("", "0")
COMPILE_ROOM = 1 << 30  # bytes of address space numba / LLVM may need to compile or load the kernels


def set_enabled(on: bool) -> bool:
    """Use the compiled kernels (when numba is installed) or not; returns the previous setting (tests)."""
    global _ENABLED
    old, _ENABLED = _ENABLED, bool(on)
    return old


def enabled() -> bool:
    """Whether compiled kernels may be used: numba is not turned off (:func:`set_enabled`, ``MOCAPZ_NO_NUMBA``)."""
    return _ENABLED


def room_to_compile() -> bool:
    """False under an address-space cap leaving less than :data:`COMPILE_ROOM` (LLVM aborts the whole process
    when it runs out of memory: a caller that caps memory, as the hostile-file tests do around every decode,
    gets the NumPy path instead)."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft == resource.RLIM_INFINITY:
            return True
        with open("/proc/self/status") as f:
            vm = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:"))
        return soft - vm >= COMPILE_ROOM
    except (ImportError, OSError, StopIteration, ValueError):  # pragma: no cover - not Linux
        return True
