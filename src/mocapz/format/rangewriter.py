"""Range-coded streams being written: constriction's ``RangeEncoder`` (the reference), or the compiled encoder of
:mod:`.rangekernels` (the same words, without an array per value and parameter made for every call).

A writer codes integers under quantized Laplace models (:meth:`RangeWriter.laplace`: a scale per block of rows
and column) and gives the stream's bytes (:meth:`RangeWriter.body`, its 32-bit words little-endian); constriction's
writer also takes its other models (:meth:`RangeWriter.encode`). :func:`mocapz.format.entropy.range_writer` picks
one.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

CHUNK_VALUES = 1 << 16  # values coded per call of constriction's coder (its per-value arrays: peak memory)


class RangeWriter:
    """constriction's ``RangeEncoder``."""

    def __init__(self) -> None:
        import constriction

        self._constriction = constriction
        self.enc = constriction.stream.queue.RangeEncoder()

    def laplace(self, values: np.ndarray, scale: np.ndarray, row0: int, block: int, limit: int) -> None:
        """Code ``values`` ``(rows, cols)`` (clipped to ``[-limit, limit]``) row by row, each under the quantized
        Laplace scale ``scale[(row0 + row) // block, col]`` on ``[-limit, limit]``, :data:`CHUNK_VALUES` values a
        call (the stream of a single call)."""
        rows, cols = values.shape
        model = self._constriction.stream.model.QuantizedLaplace(-limit, limit)
        step = max(1, CHUNK_VALUES // max(cols, 1))
        for a in range(0, rows, step):
            part = values[a:a + step]
            sym = np.clip(part, -limit, limit).astype(np.int32).ravel()
            blocks = np.arange(row0 + a, row0 + a + len(part)) // block
            self.enc.encode(sym, model, np.zeros(sym.size), np.ascontiguousarray(scale[blocks]).ravel())

    def encode(self, *args: Any) -> None:
        """constriction's ``encode`` (any of its models)."""
        self.enc.encode(*args)

    def body(self) -> bytes:
        """The stream's words so far, sealed."""
        return self.enc.get_compressed().tobytes()


class CompiledRangeWriter(RangeWriter):
    """:class:`RangeWriter` with the compiled encoder (:func:`.rangekernels.encode_laplace`): the same words."""

    def __init__(self, kernels: Any) -> None:
        self.kernels = kernels
        self.state = np.array([0, 2**64 - 1, 0, 0], dtype=np.uint64)
        self.parts: list[np.ndarray] = []

    def laplace(self, values: np.ndarray, scale: np.ndarray, row0: int, block: int, limit: int) -> None:
        v = np.ascontiguousarray(values, dtype=np.int64)
        out = np.empty(v.size + int(self.state[2]) + 1, dtype=np.uint32)
        n = self.kernels.encode_laplace(v, np.ascontiguousarray(scale, dtype=np.float64), row0, block, limit,
                                        self.state, out)
        self.parts.append(out[:n])

    def encode(self, *args: Any) -> None:
        raise TypeError("the compiled range writer codes Laplace models only (laplace)")

    def body(self) -> bytes:
        tail = np.empty(int(self.state[2]) + 2, dtype=np.uint32)
        n = self.kernels.seal(self.state, tail)
        return b"".join(p.tobytes() for p in self.parts) + tail[:n].tobytes()


def writer(kernels: ModuleType | Any | None) -> RangeWriter:
    """A writer: the compiled one with ``kernels`` (:mod:`.rangekernels` or its ahead-of-time build), else
    constriction's."""
    return RangeWriter() if kernels is None else CompiledRangeWriter(kernels)
