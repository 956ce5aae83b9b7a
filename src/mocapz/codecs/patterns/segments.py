"""Per-clip segment stream: for every segment its pattern index and original frame count (paper Fig. 7).

Both are coded with adaptive arithmetic coding (constriction's range coder, models updated after every
symbol), interleaved segment by segment:

* the pattern index. Patterns are stored in order of first use, so in a single clip the index of a pattern
  never used before is always the next one: it is coded as a "new" escape whose probability is the count
  of distinct patterns seen so far (PPM method C); known patterns are coded by their usage counts. In a
  library the counts start from the database's shared usage counts instead (no escape).
* the frame count, as the zig-zagged difference from a prediction: the frame count this pattern had the
  last time it was used, else the previous segment's.
"""

from __future__ import annotations

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import (
    HAVE_CONSTRICTION,
    constriction,
    pack_uint64,
    read_uvarint,
    unpack_uint64,
    write_uvarint,
)

CODER_RANGE = 1
CODER_ZSTD = 2
LENGTH_ALPHA = 0.3


class _Lengths:
    """Adaptive model of zig-zagged frame-count differences, alphabet ``[0, 2 * top]``."""

    def __init__(self, top: int) -> None:
        self.counts = np.full(2 * top + 1, LENGTH_ALPHA)
        self.last_of: dict[int, int] = {}
        self.last = 1

    def predict(self, label: int) -> int:
        return self.last_of.get(label, self.last)

    def update(self, label: int, length: int, sym: int) -> None:
        self.counts[sym] += 1.0
        self.last_of[label] = length
        self.last = length


class _Labels:
    """Adaptive pattern-index model (escape for new patterns, or a shared prior)."""

    def __init__(self, k: int, prior: np.ndarray | None) -> None:
        self.escape = prior is None
        base = np.zeros(k) if prior is None else np.asarray(prior, dtype=np.float64) + 0.5
        if not self.escape and k == 1:
            # the range coder takes no one-symbol alphabet: a never-used second symbol (costs ~0 bits)
            base = np.append(base, 0.0)
        self.counts = np.concatenate([[1.0], base]) if self.escape else base
        self.distinct = 0

    def symbol(self, label: int) -> int:
        if not self.escape:
            return label
        return 0 if label == self.distinct else label + 1

    def label(self, sym: int) -> int:
        if not self.escape:
            return sym
        return self.distinct if sym == 0 else sym - 1

    def probs(self) -> np.ndarray:
        return self.counts

    def update(self, label: int) -> None:
        if self.escape:
            if label == self.distinct:
                self.distinct += 1
                self.counts[0] = max(1.0, float(self.distinct))
            self.counts[label + 1] += 1.0
        else:
            self.counts[label] += 1.0


def encode_segments(labels: np.ndarray, lengths: np.ndarray, k: int, prior: np.ndarray | None = None) -> bytes:
    """Code a clip's segment stream; ``prior`` (library) replaces the first-use escape."""
    n = len(lengths)
    top = int(lengths.max()) if n else 1
    head = write_uvarint(n) + write_uvarint(top)
    if prior is None and n and np.any(labels > np.maximum.accumulate(np.r_[-1, labels[:-1]]) + 1):
        raise ValueError("labels are not in first-use order")
    if not HAVE_CONSTRICTION:
        return head + bytes([CODER_ZSTD]) + pack_uint64(np.concatenate([labels, lengths]).astype(np.uint64))
    model = constriction.stream.model.Categorical(perfect=False)
    enc = constriction.stream.queue.RangeEncoder()
    lab_m, len_m = _Labels(k, prior), _Lengths(top)
    for label, length in zip(labels.tolist(), lengths.tolist(), strict=True):
        enc.encode(np.array([lab_m.symbol(label)], dtype=np.int32), model, lab_m.probs()[None, :])
        lab_m.update(label)
        d = length - len_m.predict(label)
        sym = 2 * d if d >= 0 else -2 * d - 1
        enc.encode(np.array([sym], dtype=np.int32), model, len_m.counts[None, :])
        len_m.update(label, length, sym)
    return head + bytes([CODER_RANGE]) + enc.get_compressed().tobytes()


def decode_segments(data: bytes, k: int, prior: np.ndarray | None = None,
                    frames: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`encode_segments`: ``(labels, lengths)``.

    ``frames``: the clip's frame count, which bounds the segment count and the longest segment (checked
    before the models are allocated).
    """
    n, pos = read_uvarint(data, 0)
    top, pos = read_uvarint(data, pos)
    most = min(1 << 28, frames if frames is not None else 1 << 28)
    if pos >= len(data) or n > most or top > min(1 << 24, max(most, 1)):
        raise FormatError(None, "corrupted segment stream (segment count or length)")
    coder = data[pos]
    body = data[pos + 1 :]
    if coder == CODER_ZSTD:
        v = unpack_uint64(body, 2 * n)
        if np.any(v[n:] > most):
            raise FormatError(None, "corrupted segment stream (frame count)")
        labels, lengths = v[:n].astype(np.int64), v[n:].astype(np.int64)
    elif coder == CODER_RANGE:
        labels, lengths = _decode_range(body, n, top, k, prior)
    else:
        raise FormatError(None, "unknown segment stream coder")
    if n and (labels.min() < 0 or labels.max() >= max(k, 1) or lengths.min() < 1):
        raise FormatError(None, "corrupted segment stream (pattern index or frame count)")
    return labels, lengths


def _decode_range(body: bytes, n: int, top: int, k: int, prior: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    if not HAVE_CONSTRICTION:
        raise FormatError(None, "this stream needs the constriction range coder, which is not installed")
    if len(body) % 4:
        raise FormatError(None, "truncated segment stream")
    labels = np.zeros(n, dtype=np.int64)
    lengths = np.zeros(n, dtype=np.int64)
    model = constriction.stream.model.Categorical(perfect=False)
    lab_m, len_m = _Labels(k, prior), _Lengths(top)
    try:
        dec = constriction.stream.queue.RangeDecoder(np.frombuffer(body, dtype=np.uint32).copy())
        for i in range(n):
            label = lab_m.label(int(dec.decode(model, lab_m.probs()[None, :])[0]))
            if not 0 <= label < k:
                raise FormatError(None, "corrupted segment stream (pattern index)")
            lab_m.update(label)
            sym = int(dec.decode(model, len_m.counts[None, :])[0])
            length = len_m.predict(label) + (sym // 2 if sym % 2 == 0 else -(sym + 1) // 2)
            len_m.update(label, length, sym)
            labels[i], lengths[i] = label, length
    except FormatError:
        raise
    except Exception as exc:  # constriction raises plain exceptions on corrupt input
        raise FormatError(None, f"corrupted segment stream ({exc})") from None
    return labels, lengths
