"""Whole turns of the decoded Euler angles, stored so that a window of frames decodes them alone (random access).

The IK's Euler angles lie within half a turn of zero; the decoder turns them by whole turns so that they run on
over time (a root turning on the spot reaches 720 degrees, as in the source; an angle near 180 degrees does not
flip to -180). ``np.unwrap`` does it from every frame before a window. A clip coded with the seekable layout
(:func:`~mocapz.codecs.correction.window.seekable`) instead stores, in its ``turns`` section, a *centre* per
rotation column and kept frame, a multiple of half a turn (0 unless stored otherwise), and the decoder puts each
angle within half a turn of its centre: ``v = raw + period * round((centre - raw) / period)``, an operation on
each value alone, so a window of frames gets the full decode's values to the bit. The encoder follows its own
decode of the angles, unwrapped (np.unwrap), and moves a column's centre to the nearest multiple of half a turn
only where the angle comes within :data:`EDGE` of half a turn from it: an angle hovering about 180 degrees costs
one event, a root turning on the spot one event per half turn or more.

Section layout: uvarints: the number of columns with events, then per column (in increasing order) its index,
its event count and per event (in order of frame) ``step << 2 | code``: ``step`` the frame's distance from the
column's event before (the first from frame 0), ``code`` 0 for the centre up half a turn, 1 for down half a
turn, 2 for more (the zigzagged half turns follow).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, write_uvarint

SECTION = "turns"
MAX_TURNS = 1 << 20  # half turns of one event
EDGE = 17 / 18  # of half a turn: how far from its centre an angle may come before the centre moves


@dataclass(frozen=True)
class Turns:
    """Centre moves: the kept frame ``(events,)`` from which a channel column's centre moves, the column and the
    move in half turns (not 0)."""

    frames: np.ndarray
    columns: np.ndarray
    turns: np.ndarray

    @classmethod
    def of(cls, raw: np.ndarray, rotation: np.ndarray, period: float) -> Turns:
        """The centre moves for decoded channels ``raw`` ``(frames, channels)`` (their angles within half a turn
        of 0), ``rotation`` a boolean mask ``(channels,)`` of the angle columns."""
        cols = np.flatnonzero(rotation)
        if not raw.shape[0] or not cols.size:
            return cls.none()
        half = period / 2
        u = np.unwrap(np.nan_to_num(raw[:, cols], nan=0.0, posinf=0.0, neginf=0.0), period=period, axis=0)
        rows: list[tuple[int, int, int]] = []
        for j in np.flatnonzero((np.abs(u) >= EDGE * half).any(axis=0)).tolist():
            centre, t = 0, 0  # the centre in half turns, the first frame not yet within its reach
            while True:
                out = np.flatnonzero(np.abs(u[t:, j] - centre * half) >= EDGE * half)
                if not out.size:
                    break
                t += int(out[0])
                new = int(np.round(u[t, j] / half))
                rows.append((t, int(cols[j]), new - centre))
                centre = new
        a = np.array(sorted(rows), dtype=np.int64).reshape(-1, 3)
        return cls(a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy())

    @classmethod
    def none(cls) -> Turns:
        empty = np.zeros(0, dtype=np.int64)
        return cls(empty, empty, empty)

    def to_bytes(self) -> bytes:
        """The section (see the module docstring)."""
        cols = np.unique(self.columns)
        out = bytearray(write_uvarint(int(cols.size)))
        for c in cols.tolist():
            mine = self.columns == c
            frames, turns = self.frames[mine].tolist(), self.turns[mine].tolist()
            out += write_uvarint(c) + write_uvarint(len(frames))
            prev = 0
            for t, k in zip(frames, turns, strict=True):
                code = 0 if k == 1 else 1 if k == -1 else 2
                out += write_uvarint((t - prev) << 2 | code)
                if code == 2:
                    out += write_uvarint(2 * k if k >= 0 else -2 * k - 1)
                prev = t
        return bytes(out)

    @classmethod
    def from_bytes(cls, data: bytes, frames: int, rotation: np.ndarray) -> Turns:
        """The centre moves of a ``turns`` section for ``frames`` kept frames and the rotation columns
        ``rotation`` (a boolean mask over the channels): FormatError unless every move lies within them, in
        order."""
        def bad(what: str) -> FormatError:
            return FormatError(None, f"corrupted PGA stream (turns: {what})")

        ncols, pos = read_uvarint(data, 0)
        if ncols > rotation.size:
            raise bad("column count")
        rows: list[tuple[int, int, int]] = []
        last = -1
        for _ in range(ncols):
            c, pos = read_uvarint(data, pos)
            count, pos = read_uvarint(data, pos)
            if not last < c < rotation.size or not rotation[c] or count > len(data) or count > frames:
                raise bad("column")
            last, t = c, 0
            for i in range(count):
                word, pos = read_uvarint(data, pos)
                t += word >> 2
                code = word & 3
                k = 1 if code == 0 else -1
                if code == 2:
                    z, pos = read_uvarint(data, pos)
                    k = z >> 1 if z % 2 == 0 else -((z + 1) >> 1)
                if code == 3 or (word >> 2 == 0 and i > 0) or t >= frames \
                        or (code == 2 and not 1 < abs(k) <= MAX_TURNS):
                    raise bad("event")
                rows.append((t, c, k))
        if pos != len(data):
            raise bad("trailing bytes")
        a = np.array(rows, dtype=np.int64).reshape(-1, 3)
        return cls(a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy())

    def unwrapper(self, first: int = 0):  # noqa: ANN201 (a closure of unwrap_columns' signature)
        """``(out, rotation, period) -> None``: puts the angles of decoded channels ``out`` ``(F, C)`` of the
        kept frames ``[first, first + F)`` within half a turn of their centres, in place (in
        :func:`~.channels.finish_channels`, in place of ``np.unwrap``)."""
        def unwrap(out: np.ndarray, rotation: np.ndarray, period: float) -> None:
            out[:, rotation] += 0.0  # -0.0 as np.unwrap leaves it: 0.0
            if not self.frames.size:
                return
            cols, which = np.unique(self.columns, return_inverse=True)
            f = out.shape[0]
            moves = np.zeros((f + 1, cols.size), dtype=np.int64)  # moves after the window fall on row f
            np.add.at(moves, (np.clip(self.frames - first, 0, f), which), self.turns)
            centre = np.cumsum(moves[:f], axis=0) * (period / 2)
            angles = out[:, cols]
            out[:, cols] = angles + period * np.round((centre - angles) / period)
        return unwrap


def raw(out: np.ndarray, rotation: np.ndarray, period: float) -> None:
    """The unwrapper that leaves the angles as the IK gives them (the encoder reads its events from them)."""
