"""Integer matrices in and out of one byte string: each entropy-coded, length-prefixed, concatenated."""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import decode_int_matrix, encode_int_matrix, read_uvarint, write_uvarint


def pack_matrices(mats: list[np.ndarray]) -> bytes:
    """Entropy-code 2-D int matrices, one length-prefixed stream each, concatenated."""
    out = bytearray()
    for m in mats:
        b = encode_int_matrix(m)
        out += write_uvarint(len(b)) + b
    return bytes(out)


def unpack_matrices(data: bytes, count: int) -> list[np.ndarray]:
    """Inverse of :func:`pack_matrices`: the first ``count`` matrices of ``data``."""
    out, pos = [], 0
    for _ in range(count):
        n, pos = read_uvarint(data, pos)
        if pos + n > len(data):
            raise FormatError(None, "truncated PGA stream")
        out.append(decode_int_matrix(data[pos : pos + n]))
        pos += n
    return out
