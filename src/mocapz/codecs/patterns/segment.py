"""Adaptive segmentation of one node's motion (paper §III.B, Algorithm 1 "MotionDataPartition").

Algorithm 1 grows the current segment ``S`` frame by frame and starts a new one at frame ``F_i`` when::

    W^T |F_i - LastFrm(S)|  /  W^T |AveFrameDiff(S)|   >   ratio

``|.|`` is the per-member (marker / joint) Euclidean length, ``W`` the member weights, and
``AveFrameDiff(S) = (LastFrm(S) - FirstFrm(S)) / (|S| - 1)`` the segment's average frame difference (its
mean velocity). The test fires when the motion turns (the mean velocity collapses while the frames keep
moving) or suddenly speeds up. To make the threshold independent of units and to ignore marker jitter,
each member's ``|AveFrameDiff|`` is floored at ``theta * ADDH / (|S| - 1)`` (paper §V.a: thresholds are a
coefficient ``theta`` times the average diagonal distance of the head markers): a segment whose members
have moved less than ``theta * ADDH`` is only cut once its frames have travelled ``ratio`` times that far.
A one-frame segment has no average frame difference: it is closed only by a jump, a step longer than
``ratio * JUMP * ADDH`` (an added T-pose frame, a marker swap), which so stays out of the next segment.
Members missing at the new frame (gaps) are left out of both sums, so gaps never cause chopping points;
a member that reappears after a gap counts with the step from its interpolated value (its last observed
position spread over the gap). A segment also ends where a member starts or stops being observed, so that
every segment sees each marker either throughout or not at all (a normalised segment then never has to
stretch a few observed frames inside a long gap).
"""

from __future__ import annotations

import numpy as np

JUMP = 0.1  # a step over ratio * JUMP * ADDH right after a segment's first frame is a jump


def partition(frames: np.ndarray, observed: np.ndarray, weights: np.ndarray, theta: float, addh: float,
              ratio: float = 2.0, max_length: int = 0) -> np.ndarray:
    """Chopping points of a node's motion.

    Args:
        frames: ``(T, members, c)`` node frames (``c`` = 3 for markers), gaps filled.
        observed: ``(T, members)`` True where the member was observed.
        weights: ``(members,)`` non-negative member weights ``W``.
        theta: key-frame threshold as a fraction of ``addh``.
        addh: the length scale (average diagonal distance of the head markers), file units.
        ratio: Algorithm 1's ratio threshold.
        max_length: longest allowed segment in frames (0: unlimited).

    Returns:
        ``(segments,)`` int64 start frame of every segment (the first is 0); segment ``k`` runs up to
        the next start (or ``T``).
    """
    t = frames.shape[0]
    if t == 0:
        return np.zeros(0, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    step = np.linalg.norm(np.diff(frames, axis=0), axis=-1)  # (T-1, m): |F_i - F_{i-1}|
    seen = np.maximum.accumulate(observed, axis=0)  # observed at least once so far
    ok = (observed[1:] & seen[:-1]).astype(np.float64) * w  # usable members per step
    floor = max(theta * addh, 1e-12)
    flips = np.zeros(t, dtype=bool)
    flips[1:] = ((observed[1:] != observed[:-1]) & (w > 0)).any(axis=1)
    starts = [0]
    first = 0
    while True:
        cut = _next_cut(frames, seen, step, ok, flips, first, floor, JUMP * addh, ratio, max_length)
        if cut is None:
            return np.asarray(starts, dtype=np.int64)
        starts.append(cut)
        first = cut


def _next_cut(frames: np.ndarray, seen: np.ndarray, step: np.ndarray, ok: np.ndarray, flips: np.ndarray, first: int,
              floor: float, jump: float, ratio: float, max_length: int) -> int | None:
    """First frame ``i`` that Algorithm 1 puts in a new segment when the current one starts at ``first``.

    Candidates are tested in windows that double in size, all frames of a window at once.
    """
    t = frames.shape[0]
    lo, win = first + 1, 32
    while lo < t:
        idx = np.arange(lo, min(t, lo + win))
        n = idx - first  # frames already in S
        chord = np.linalg.norm(frames[idx - 1] - frames[first], axis=-1)  # (k, m)
        okc = ok[idx - 1] * seen[first]
        den = (np.maximum(chord, floor) * okc).sum(axis=1) / np.maximum(n - 1, 1)
        den[n == 1] = (jump * okc[n == 1]).sum(axis=1)
        num = (step[idx - 1] * okc).sum(axis=1)
        bad = ((den > 0) & (num > ratio * den)) | flips[idx]
        if max_length:
            bad |= n >= max_length
        if bad.any():
            return int(idx[np.argmax(bad)])
        lo, win = lo + win, win * 2
    return None


def lengths_of(starts: np.ndarray, total: int) -> np.ndarray:
    """Segment lengths in frames from start frames and the sequence length."""
    return np.diff(np.append(starts, total)).astype(np.int64)
