"""Access to the correction layer's compiled (numba) kernels: :mod:`.chainkernels` (the closed loop down a
skeleton) and :mod:`.liftkernels` (the lifting's detail levels). Either is used only when numba is installed,
not turned off (:func:`mocapz.codecs.pga.ikjit.set_enabled`, ``MOCAPZ_NO_NUMBA``) and worth loading; the NumPy
path stays the reference."""

from __future__ import annotations

import importlib
import sys
from types import ModuleType

#: frames from which the compiled kernels are loaded to code a clip (when numba is not loaded already: loading it and
#: the kernels from numba's cache takes about 0.5 s and 130 MB). The whole `mocapz compress --codec quant` (effort
#: fast) on CMU 02_05 (1,855 frames) took 0.64 s on the NumPy path against 1.10 s loading them; 06_13's first 3,000
#: frames 1.68 against 1.55 s, all 4,906 2.2 against 2.1 s (99 against 235 MB), 06_13 played to 14,718 7.7 against 5.3 s
LAZY_FRAMES = 5_000
#: the same to decode one, whose lifting takes milliseconds either way: `mocapz decompress` of 06_13's quant file
#: (4,906 frames) took 0.39 s on the NumPy path against 0.94 s loading them, of 68,684 frames 3.9 against 4.2 s
LAZY_DECODE_FRAMES = 100_000
_LOADED: dict[str, ModuleType] = {}  # the kernel modules imported so far (a look-up per call, not an import)


def kernels(frames: int, module: str = "chainkernels", decoding: bool = False) -> ModuleType | None:
    """The compiled kernels ``module`` (of this package) for a clip of ``frames`` frames, or None: without numba,
    when turned off, under an address-space cap that leaves no room to compile, or on a clip under
    :data:`LAZY_FRAMES` (``decoding``: :data:`LAZY_DECODE_FRAMES`) while numba is not loaded yet (loading it costs
    more than the NumPy path spends there). Either path gives the same bits."""
    from mocapz.codecs.pga import ikjit  # the one switch of the compiled kernels (here: no import cycle)

    if not ikjit.enabled() or (frames < (LAZY_DECODE_FRAMES if decoding else LAZY_FRAMES)
                               and "numba" not in sys.modules) \
            or not ikjit.room_to_compile():
        return None
    if module not in _LOADED:
        try:
            _LOADED[module] = importlib.import_module(f"{__package__}.{module}")
        except ImportError:  # numba not installed
            return None
    return _LOADED[module]
