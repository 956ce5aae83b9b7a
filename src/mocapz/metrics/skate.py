"""Foot skate and jitter: what a viewer sees of a decoded motion beyond the position errors.

- ``foot_skate``: decoded minus original mean horizontal foot speed over planted steps, frame to frame
  (METRICS.md; measures jitter and drift together).
- ``foot_skate_window``: the same over windows of ``round(0.1 * fps)`` frame steps lying wholly inside a
  planted interval: the horizontal displacement of the foot over the window divided by the window's duration
  (measures drift, a planted foot sliding away, and ignores frame-to-frame trembling).
- ``jitter_pct``: added acceleration energy, ``100 * (E(decoded) / E(original) - 1)`` with
  ``E = sum over frames and points of |p[t+1] - 2 p[t] + p[t-1]|^2`` (markers: only where the three
  samples are present in the original).

Planted steps come from :func:`mocapz.metrics.contacts.find_contacts` on the original positions.
Speeds are in file units per second (``* unit_cm`` gives cm/s).
"""

from __future__ import annotations

import numpy as np

from mocapz.metrics.chunks import frame_chunks
from mocapz.metrics.contacts import Contacts, find_contacts
from mocapz.model.motion import AnyMotion

#: Duration of the windows of ``foot_skate_window``, seconds.
SKATE_WINDOW_S = 0.1


def window_steps(frame_rate: float) -> int:
    """Frame steps in one ``foot_skate_window`` window: ``round(0.1 * fps)``, at least 1."""
    return max(1, int(round(SKATE_WINDOW_S * frame_rate)))


def horizontal_speeds(p: np.ndarray, horiz: list[int], w: int, fps: float) -> np.ndarray:
    """Horizontal speed over every window of ``w`` steps of one point's ``(frames, 3)`` positions:
    ``(frames - w,)`` in units per second."""
    return np.linalg.norm(p[w:][:, horiz] - p[:-w][:, horiz], axis=1) * (fps / w)


def full_windows(steps: np.ndarray, w: int) -> np.ndarray:
    """``(frames - w,)`` True where the window of ``w`` steps from frame t lies wholly in planted steps.

    ``steps`` is ``(frames - 1,)`` bool (one foot's column of :attr:`Contacts.steps`).
    """
    c = np.concatenate([[0], np.cumsum(steps, dtype=np.int64)])
    return (c[w:] - c[:-w]) == w


def skate_difference(con: Contacts, a: np.ndarray, b: np.ndarray, fps: float, w: int) -> float | None:
    """Mean over feet of (decoded minus original) mean horizontal foot speed over planted windows of ``w``
    steps (``w = 1``: frame to frame).

    Args:
        con: the original's planted steps.
        a, b: original and decoded positions ``(frames, points, 3)``, file units.
        fps: frames per second.
        w: window length in frame steps.

    Returns:
        File units per second, or ``None`` when no foot has a planted window of that length.
    """
    if a.shape[0] <= w:
        return None
    diffs = []
    for i, f in enumerate(con.feet):  # the two feet
        full = full_windows(con.steps[:, i], w)
        if full.any():
            sa = horizontal_speeds(a[:, f], con.horizontal, w, fps)[full]
            sb = horizontal_speeds(b[:, f], con.horizontal, w, fps)[full]
            diffs.append(float(sb.mean() - sa.mean()))
    return float(np.mean(diffs)) if diffs else None


def foot_skates(motion: AnyMotion, a: np.ndarray, b: np.ndarray, valid: np.ndarray,
                unit_cm: float | None) -> tuple[float | None, float | None]:
    """``(foot_skate, foot_skate_window)`` of decoded positions ``b`` against the original ``a``.

    Args:
        motion: the original motion (frame rate, skeleton for the foot end sites).
        a, b: ``(frames, points, 3)`` positions in file units.
        valid: ``(frames, points)`` present samples of the original.
        unit_cm: centimetres per file unit (``None``: thresholds relative to the body height).

    Returns:
        Frame-to-frame and 0.1-s-window skate in file units per second (``None`` under 3 frames or
        without planted steps).
    """
    if a.shape[0] < 3:
        return None, None
    con = find_contacts(motion, a, valid, unit_cm)
    fps = float(motion.frame_rate)
    return (skate_difference(con, a, b, fps, 1),
            skate_difference(con, a, b, fps, window_steps(fps)))


def acceleration_energy(p: np.ndarray, ok: np.ndarray, valid: np.ndarray | None = None) -> float:
    """``sum |p[t+1] - 2 p[t] + p[t-1]|^2`` over frames t and points where ``ok`` ``(frames - 2, points)``.

    ``p`` is ``(frames, points, 3)``, its samples taken as 0 where ``valid`` ``(frames, points)`` is False; the
    result is in squared file units (per squared frame). The terms are made a chunk of frames at a time
    (:data:`~mocapz.metrics.chunks.CHUNK_FRAMES`: a long clip's work arrays stay small) and summed at once, in the
    order of the whole array.
    """
    sq = np.zeros(ok.shape)
    for t in frame_chunks(sq.shape[0]):
        q = p[t.start:t.stop + 2]
        if valid is not None:
            q = np.where(valid[t.start:t.stop + 2, :, None], q, 0.0)
        acc = q[2:] - 2.0 * q[1:-1] + q[:-2]
        sq[t] = np.where(ok[t], np.sum(acc * acc, axis=-1), 0.0)
    return float(sq.sum())


def jitter_pct(a: np.ndarray, b: np.ndarray, valid: np.ndarray) -> float | None:
    """Added acceleration energy of ``b`` against ``a`` in percent (``(frames, points, 3)`` each).

    Only second differences whose three samples are present in the original (``valid``
    ``(frames, points)``) count. ``None`` under 3 frames; ``inf`` when the original has no acceleration at
    all and the decoded has some.
    """
    if a.shape[0] < 3:
        return None
    ok = valid[2:] & valid[1:-1] & valid[:-2]
    ea = acceleration_energy(a, ok, valid)
    eb = acceleration_energy(b, ok, valid)
    if ea == 0.0:
        return 0.0 if eb == 0.0 else float("inf")
    return 100.0 * (eb / ea - 1.0)
