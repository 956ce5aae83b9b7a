"""Optional numba kernels of the lossless codec (``pip install mocapz[fast]``).

The plain numpy path (:mod:`.coding`, :mod:`.decode`, :mod:`.encode`) stays the reference and works
without numba; the kernels (:mod:`._kernels`) compute the very same integers, faster:

* ``decode_residual_rows``: the residual stream's range decoder (the step of
  :mod:`mocapz.format.rangekernels`: constriction's ``RangeDecoder`` with quantized Laplace models,
  reimplemented with the same integer arithmetic and the same CDF expression), fused with the escapes, the low
  bits and the running scale states, in one pass over the rows instead of one Python call per row;
* ``row_models``: the encoder's per-row low-bit counts and Laplace scales (the running states);
* ``undo_prediction``: second differences from residuals and cross-channel predictions, then the two
  cumulative sums, for every frame in one pass.

numba is imported lazily: loading it (and the cached kernels) costs about half a second once per process,
more than the numpy path spends on a clip or two, so it is loaded once this process has asked the lossless
codec for :data:`LAZY_VALUES` values in all (or when numba is already imported), or at the first block of a clip of
:data:`LAZY_AHEAD` values (:func:`expect`); ``MOCAPZ_NO_NUMBA=1`` (or
:func:`set_enabled`) turns it off. Either path gives the same bytes and values.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType
from typing import Any

from mocapz import aot

LAZY_VALUES = 3_000_000  # values (frames x columns) coded or decoded before numba is worth loading: `mocapz
# decompress` of 06_13 played to 14,718 frames (1.4 M values) took 1.19 s on the NumPy path against 1.78 s loading it,
# of 68,684 frames 5.4 against 4.0 s; compress broke even at 14,718 (2.65 s either way)

LAZY_AHEAD = 1_500_000  # values of one clip coded or decoded block by block from which numba is loaded at its
# first block (:func:`expect`): the whole clip pays for it. The 10-minute synthetic clip (72,000 frames, 6.9 M
# values) decoded in 1.15-1.48 s loaded first against 2.83-3.24 s with its first 3 M values on the NumPy path;
# 06_13 (4,906 frames, 0.47 M) 0.25-0.28 s on the NumPy path against 0.47-0.58 loading it

_state: dict[str, Any] = {}
_work = [0]
_enabled = os.environ.get("MOCAPZ_NO_NUMBA", "") in ("", "0")


def set_enabled(flag: bool) -> bool:
    """Use the numba kernels (when numba is installed) or not; returns the previous setting."""
    global _enabled
    before, _enabled = _enabled, bool(flag)
    return before


def kernels(work: int = 0, force: bool = False) -> ModuleType | aot.Kernels | None:
    """The kernels (compiled ahead of time, :mod:`mocapz.aot`, else numba's module), or None: without numba, when
    turned off, or while loading numba would not pay yet.

    Args:
        work: values (frames x columns) about to be coded or decoded (added to this process's total).
        force: load numba now whatever the total.
    """
    if not _enabled:
        return None
    _work[0] += work
    if "mod" not in _state and (ahead := aot.kernels("lossless")) is not None:
        _state["mod"] = ahead  # compiled ahead of time: nothing to load
    if "mod" not in _state:
        if not (force or "numba" in sys.modules or _work[0] >= LAZY_VALUES):
            return None
        try:
            from mocapz.codecs.lossless import _kernels
        except ImportError:  # numba not installed
            _state["mod"] = None
        else:
            _state["mod"] = _kernels
    return _state["mod"]


def expect(values: int) -> None:
    """A clip of ``values`` values (frames x columns) is being coded or decoded block by block: the kernels are
    loaded now where it holds :data:`LAZY_AHEAD` values or more (not after its first :data:`LAZY_VALUES`)."""
    if values >= LAZY_AHEAD:
        kernels(force=True)
