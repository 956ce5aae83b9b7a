"""Integer matrices in and out of one byte string: each entropy-coded, length-prefixed, concatenated; and
:func:`once`, the rate search's memo of what a setting's streams cost to make."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any, TypeVar

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix, read_uvarint, write_uvarint

T = TypeVar("T")


def once(memo: dict[Hashable, Any] | None, key: Hashable, make: Callable[[], T]) -> T:
    """``make()``, kept in ``memo`` under ``key`` (None: made every time). A rate search's memo holds each stream
    by the settings (or, decoding, the bytes) it is a function of: a candidate that changes one setting codes and
    decodes only the streams that setting changes, with the same numbers (what is kept is never written to)."""
    if memo is None:
        return make()
    if key not in memo:
        memo[key] = make()
    return memo[key]  # type: ignore[no-any-return]


def pack_matrices(mats: list[np.ndarray]) -> bytes:
    """Entropy-code 2-D int matrices, one length-prefixed stream each, concatenated."""
    return pack_streams([encode_int_matrix(m) for m in mats])


def pack_streams(streams: list[bytes]) -> bytes:
    """Entropy-coded matrices (:func:`~mocapz.format.entropy.encode_int_matrix`'s bytes), length-prefixed."""
    return b"".join(write_uvarint(len(b)) + b for b in streams)


def split_streams(data: bytes, count: int) -> list[bytes]:
    """The first ``count`` entropy-coded matrices of ``data`` (:func:`pack_streams`), each its bytes."""
    out, pos = [], 0
    for _ in range(count):
        n, pos = read_uvarint(data, pos)
        if pos + n > len(data):
            raise FormatError(None, "truncated PGA stream")
        out.append(bytes(data[pos : pos + n]))
        pos += n
    return out


def unpack_matrices(data: bytes, count: int) -> list[np.ndarray]:
    """Inverse of :func:`pack_matrices`: the first ``count`` matrices of ``data``."""
    return [decode_int_matrix(b) for b in split_streams(data, count)]
