"""Access to the correction layer's compiled (numba) kernels: :mod:`.chainkernels` (the closed loop down a
skeleton) and :mod:`.liftkernels` (the lifting's detail levels). Either is used only when numba is installed,
not turned off (:func:`mocapz.codecs.pga.ikjit.set_enabled`, ``MOCAPZ_NO_NUMBA``) and worth loading; the NumPy
path stays the reference."""

from __future__ import annotations

import importlib
import sys
from types import ModuleType

from mocapz import aot

#: frames from which the compiled kernels are loaded to code a clip (when numba is not loaded already: loading it and
#: the kernels from numba's cache takes about 0.5 s and 130 MB). The whole `mocapz compress` (effort fast) on CMU 02_05
#: (1,855 frames) took 0.64-0.73 s on the NumPy path against 1.10-1.42 s loading them with quant, 1.2-1.4 against
#: 1.6-2.2 s with patterns; 06_13's first 3,000 frames 1.68 against 1.55 s (quant); all 4,906 frames 4.3-4.7 s loading
#: them at once against 5.5 s with patterns when they were loaded after 30,000 frame-rounds on the NumPy path
LAZY_FRAMES = 2_500
#: the same to decode one, whose lifting takes milliseconds either way: `mocapz decompress` of 06_13's quant file
#: (4,906 frames) took 0.39 s on the NumPy path against 0.94 s loading them, of 68,684 frames 3.9 against 4.2 s
LAZY_DECODE_FRAMES = 100_000
#: frame-rounds coded so far by this process's corrections (:func:`note_round`: every round of every clip) from which
#: the kernels are loaded whatever the clip's length: a batch or library of short clips (one clip under
#: :data:`LAZY_FRAMES` codes 10,000-60,000: it never gets there alone)
LAZY_WORK = 200_000
_LOADED: dict[str, ModuleType] = {}  # the kernel modules imported so far (a look-up per call, not an import)
_WORK = [0]  # frame-rounds so far (:func:`note_round`)


def note_round(frames: int) -> None:
    """Count a correction round of ``frames`` frames (:data:`LAZY_WORK`)."""
    _WORK[0] += frames


def kernels(frames: int, module: str = "chainkernels", decoding: bool = False) -> ModuleType | aot.Kernels | None:
    """The compiled kernels ``module`` (of this package) for a clip of ``frames`` frames: those compiled ahead of
    time (:mod:`mocapz.aot`) whatever its length, else numba's module, or None: without numba, when turned off,
    under an address-space cap that leaves no room to compile, or on a clip under
    :data:`LAZY_FRAMES` (``decoding``: :data:`LAZY_DECODE_FRAMES`) while numba is not loaded yet and this process
    has coded fewer than :data:`LAZY_WORK` frame-rounds (loading it costs more than the NumPy path spends there).
    Either path gives the same bits."""
    from mocapz.codecs.pga import ikjit  # the one switch of the compiled kernels (here: no import cycle)

    if not ikjit.enabled():
        return None
    ahead = aot.kernels(module.removesuffix("kernels"))
    if ahead is not None:  # compiled ahead of time: nothing to load, whatever the clip's length
        return ahead
    if (frames < (LAZY_DECODE_FRAMES if decoding else LAZY_FRAMES) and _WORK[0] < LAZY_WORK
            and "numba" not in sys.modules) or not ikjit.room_to_compile():
        return None
    if module not in _LOADED:
        try:
            _LOADED[module] = importlib.import_module(f"{__package__}.{module}")
        except ImportError:  # numba not installed
            return None
    return _LOADED[module]
