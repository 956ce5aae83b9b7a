"""Optional numba kernels of the lossless codec (``pip install mocapz[fast]``).

The plain numpy path (:mod:`.coding`, :mod:`.decode`, :mod:`.encode`) stays the reference and works
without numba; the kernels (:mod:`._kernels`) compute the very same integers, faster:

* ``decode_residual_rows``: the residual stream's range decoder (constriction's ``RangeDecoder``: 64-bit
  state, 32-bit words, quantized Laplace models at 24-bit precision, reimplemented with the same integer
  arithmetic and the same CDF expression), fused with the escapes, the low bits and the running scale
  states, in one pass over the rows instead of one Python call per row;
* ``row_models``: the encoder's per-row low-bit counts and Laplace scales (the running states);
* ``undo_prediction``: second differences from residuals and cross-channel predictions, then the two
  cumulative sums, for every frame in one pass.

numba is imported lazily, on first use; ``MOCAPZ_NO_NUMBA=1`` (or :func:`set_enabled`) turns it off.
"""

from __future__ import annotations

import os
from types import ModuleType

_state: dict[str, ModuleType | None] = {}
_enabled = os.environ.get("MOCAPZ_NO_NUMBA", "") in ("", "0")


def set_enabled(flag: bool) -> bool:
    """Use the numba kernels (when numba is installed) or not; returns the previous setting."""
    global _enabled
    before, _enabled = _enabled, bool(flag)
    return before


def kernels() -> ModuleType | None:
    """The kernels module, or None without numba (or when turned off)."""
    if not _enabled:
        return None
    if "mod" not in _state:
        try:
            from mocapz.codecs.lossless import _kernels
        except ImportError:  # numba not installed
            _state["mod"] = None
        else:
            _state["mod"] = _kernels
    return _state["mod"]
