"""Access to the correction layer's compiled (numba) kernels: :mod:`.chainkernels` (the closed loop down a
skeleton) and :mod:`.liftkernels` (the lifting's detail levels). Either is used only when numba is installed,
not turned off (:func:`mocapz.codecs.pga.ikjit.set_enabled`, ``MOCAPZ_NO_NUMBA``) and worth loading; the NumPy
path stays the reference."""

from __future__ import annotations

import importlib
import sys
from types import ModuleType

LAZY_FRAMES = 500  # frames from which the compiled kernels are loaded (when numba is not loaded already)
_LOADED: dict[str, ModuleType] = {}  # the kernel modules imported so far (a look-up per call, not an import)


def kernels(frames: int, module: str = "chainkernels") -> ModuleType | None:
    """The compiled kernels ``module`` (of this package) for a clip of ``frames`` frames, or None: without numba,
    when turned off, under an address-space cap that leaves no room to compile, or on a short clip while numba
    is not loaded yet (loading it costs more than the NumPy path spends there)."""
    from mocapz.codecs.pga import ikjit  # the one switch of the compiled kernels (here: no import cycle)

    if not ikjit.enabled() or (frames < LAZY_FRAMES and "numba" not in sys.modules) \
            or not ikjit.room_to_compile():
        return None
    if module not in _LOADED:
        try:
            _LOADED[module] = importlib.import_module(f"{__package__}.{module}")
        except ImportError:  # numba not installed
            return None
    return _LOADED[module]
