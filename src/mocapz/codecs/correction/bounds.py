"""Tolerances of the correction layer: from a position bound per point and frame to a bound per value.

The correction codes a residual in the codec's value domain (skeletons: the channels, rotation channels in
the file's angle unit; markers: the coordinates). Every value column ``c`` gets a base tolerance ``T0[c]``
and every group ``g`` of columns (a joint's channels, a marker's coordinates) a tightening level per frame
``L[t, g] >= 0``; the tolerance of a sample is ``T0[c] * 2 ** (-L[t, g(c)] / 2)``.

Skeletons (ACL's hierarchical error, over every joint and end site): an error ``e`` on a rotation channel
of joint ``a`` moves a point ``p`` below ``a`` by at most ``|e| * |p - a|`` (radians), an error on a
translation channel by at most ``|e|``; errors add along the chain. Each column gets the share
``E / (n * lever)`` of the bound ``E`` (``n``: the most moving channels acting on one point it moves, the
optimal equal split for one chain), times a relaxation ``RELAX`` (errors rarely line up): the encoder
verifies by forward kinematics and raises the level of every joint on the chain of a point that misses
its bound at that frame. :func:`safe_levels` is the level at which the worst-case sum holds, so the
tightening always ends with every point within its bound.

Markers: the bound applies to the distance, so a coordinate gets ``E / sqrt(3)`` at the safe level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapz import _jit, aot
from mocapz.model.motion import AnyMotion, Motion

SAFETY = 0.98  # share of the bound handed out (float rounding, the coarse knots' shared step)
RELAX = 8.0  # base tolerances are this many times the worst-case share (verified, then tightened)
TINY = 2.0**-24  # relative tolerance of channels constant in the original (they cost nothing)


@dataclass
class Layout:
    """How the value columns of a clip map to groups and points.

    Attributes:
        group: ``(columns,)`` the group of every column.
        acts: ``(groups, points)`` True where an error in the group can move the point.
        t_safe: ``(columns,)`` the worst-case-safe tolerance per unit of position bound (``T = t_safe * E``
            keeps every point within ``E`` when all columns acting on it have their safe tolerance).
        moving: ``(columns,)`` False for columns constant in the original.
    """

    group: np.ndarray
    acts: np.ndarray
    t_safe: np.ndarray
    moving: np.ndarray

    @property
    def n_groups(self) -> int:
        return int(self.acts.shape[0])


def layout(motion: AnyMotion, positions: np.ndarray, levers: np.ndarray | None = None) -> Layout:
    """The layout of a clip from its original positions ``(frames, points, 3)`` (file units); ``levers``
    ``(joints,)``: how far a rotation error of each joint moves a point, per radian (default: the longest
    distance from the joint to a point below it, i.e. errors that add up along the chain)."""
    if not isinstance(motion, Motion):
        m = motion.n_markers
        group = np.repeat(np.arange(m), 3)
        filled = np.nan_to_num(motion.positions.reshape(motion.n_frames, 3 * m))
        moving = np.ptp(filled, axis=0) > 0 if motion.n_frames else np.zeros(3 * m, dtype=bool)
        return Layout(group, np.eye(m, dtype=bool), np.full(3 * m, SAFETY / math.sqrt(3.0)), moving)
    sk = motion.skeleton
    n_j, n_p = sk.n_joints, sk.n_points
    below = sk.below()  # below[a, p]: p strictly below joint a
    lever = _levers(positions, below)
    if levers is not None:
        lever = np.minimum(lever, levers)
    group = np.concatenate([np.full(len(chs), j) for j, chs in enumerate(sk.channels)]).astype(np.int64) \
        if sk.n_channels else np.zeros(0, dtype=np.int64)
    is_rot = np.array([c.endswith("rotation") for chs in sk.channels for c in chs], dtype=bool)
    acts_col = below[group].copy()  # (columns, points)
    acts_col[~is_rot, group[~is_rot]] = True  # a translation moves its own joint too
    ch = motion.channels
    moving = np.ptp(ch, axis=0) > 0 if len(ch) else np.zeros(sk.n_channels, dtype=bool)
    n_acting = (acts_col & moving[:, None]).sum(axis=0)  # (points,)
    share = np.array([n_acting[a].max() if a.any() else 1 for a in acts_col], dtype=np.float64)
    per_unit = math.pi / 180.0 if sk.angle_unit == "deg" else 1.0
    gain = np.where(is_rot, lever[group] * per_unit, 1.0)  # position error per unit of value error
    with np.errstate(divide="ignore"):
        t_safe = np.where(gain > 0, SAFETY / (np.maximum(share, 1.0) * gain), np.inf)
    t_safe = np.where(acts_col.any(axis=1), t_safe, np.inf)
    acts = np.zeros((n_j, n_p), dtype=bool)
    acts[group] |= acts_col
    return Layout(group, acts, t_safe, moving)


def _levers(positions: np.ndarray, below: np.ndarray) -> np.ndarray:
    """``(joints,)`` the longest distance from each joint to a point below it ``below`` ``(joints, points)`` over
    the clip's positions ``(frames, points, 3)`` (0 without one): :mod:`mocapz.metrics.errkernels`' ``farthest``
    where built (no ``(frames, points, 3)`` differences; the same numbers), else NumPy's norms."""
    lever = np.zeros(below.shape[0])
    if not len(positions) or not below.any():
        return lever
    kern = aot.kernels("err") if _jit.enabled() and positions.dtype == np.float64 else None
    if kern is None:
        for j in np.flatnonzero(below.any(axis=1)):
            lever[j] = float(np.linalg.norm(positions[:, below[j]] - positions[:, j : j + 1], axis=2).max())
        return lever
    joints, points = np.nonzero(below)  # by joint
    far = np.empty(joints.size)
    kern.farthest(positions, joints.astype(np.int64), points.astype(np.int64), far)
    firsts = np.flatnonzero(np.diff(joints, prepend=-1))
    lever[joints[firsts]] = np.maximum.reduceat(far, firsts)
    return lever


def covers(kept: Layout, lay: Layout) -> bool:
    """Whether layout ``kept`` (of other frames of the clip) is safe for the frames of ``lay``: its tolerances
    are as tight (to a millionth: the levers' float rounding) and it moves every column ``lay`` moves."""
    return kept.t_safe.shape == lay.t_safe.shape and bool(np.all(kept.t_safe <= lay.t_safe * (1.0 + 1e-6))) \
        and bool(np.all(kept.moving | ~lay.moving)) and np.array_equal(kept.acts, lay.acts)


def safe_levels(lay: Layout, bound: np.ndarray, e_max: float, relax: float = RELAX) -> np.ndarray:
    """``(frames, groups)`` levels at which the worst-case sum keeps every point ``p`` within
    ``bound[t, p]``, for base tolerances ``relax * t_safe * e_max``."""
    frames = bound.shape[0]
    out = np.zeros((frames, lay.n_groups), dtype=np.int64)
    ratio = np.ones((frames, lay.n_groups))  # smallest bound / e_max over the points a group moves
    for g in range(lay.n_groups):
        if lay.acts[g].any():
            ratio[:, g] = bound[:, lay.acts[g]].min(axis=1) / e_max
    with np.errstate(divide="ignore"):
        lv = np.ceil(2.0 * np.log2(relax / np.maximum(ratio, 1e-12)) - 1e-9)
    out[:] = np.clip(lv, 0, 60).astype(np.int64)
    return out


@dataclass(frozen=True)
class ColumnTolerances:
    """The tolerances of a clip's samples held per column and group instead of as a dense ``(frames, columns)``
    array: base tolerances ``t0`` ``(columns,)``, the ``group`` ``(columns,)`` of every column and the levels
    ``(frames, groups)`` (a reference: what they are when columns are asked for). ``tol[:, cols]`` gives the
    dense ``(frames, len(cols))`` tolerances of those columns (the same numbers as the dense array's columns),
    so the closed loop makes a joint's at a time; ``np.asarray(tol)`` all of them."""

    t0: np.ndarray
    group: np.ndarray
    levels: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.levels.shape[0]), int(self.t0.shape[0])

    def columns(self, cols: np.ndarray | slice) -> np.ndarray:
        """``(frames, len(cols))`` tolerances ``t0 * 2 ** (-level / 2)`` of the columns ``cols``."""
        return self.t0[cols][None, :] * 2.0 ** (-self.levels[:, self.group[cols]].astype(np.float64) / 2.0)

    def __getitem__(self, key: tuple[slice, np.ndarray | slice]) -> np.ndarray:
        rows, cols = key
        if rows != slice(None):
            raise IndexError("ColumnTolerances gives whole columns only (tol[:, cols])")
        return self.columns(cols)

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        out = self.columns(slice(None))
        return out if dtype is None else out.astype(dtype)


def tolerances(t0: np.ndarray, lay: Layout, levels: np.ndarray) -> ColumnTolerances:
    """Tolerances ``(frames, columns)`` from base tolerances ``t0`` ``(columns,)`` and levels ``(frames,
    groups)``, per column (:class:`ColumnTolerances`; ``np.asarray`` makes the dense array)."""
    return ColumnTolerances(t0, lay.group, levels)


def groups_moving(lay: Layout, points: np.ndarray) -> np.ndarray:
    """``(frames, groups)`` True where a group moves one of the ``(frames, points)`` True points."""
    if lay.acts.shape[0] == lay.acts.shape[1] and np.array_equal(lay.acts, np.eye(lay.acts.shape[0], dtype=bool)):
        return points.copy()  # markers: each group is its own point
    out = np.zeros((points.shape[0], lay.n_groups), dtype=bool)
    rows = np.flatnonzero(points.any(axis=1))  # the frames with a point at all (misses are few)
    if rows.size:
        out[rows] = (points[rows].astype(np.float32) @ lay.acts.T.astype(np.float32)) > 0
    return out


def tighten(levels: np.ndarray, cap: np.ndarray, lay: Layout, misses: np.ndarray, step: int = 1,
            only: np.ndarray | None = None) -> bool:
    """Raise (in place) by ``step`` (at most to ``cap``) the level of every group acting on a point that misses
    its bound.

    Args:
        levels: ``(frames, groups)`` current levels; ``cap`` the safe levels, never exceeded.
        misses: ``(frames, points)`` True where the decoded point is farther than its bound.
        only: ``(groups,)`` True on the groups that may be raised (default: all).

    Returns:
        False if nothing could be raised (every missing point's chain is already at its safe level).
    """
    raise_ = groups_moving(lay, misses) & (levels < cap)
    if only is not None:
        raise_ &= only[None, :]
    levels[raise_] = np.minimum(levels[raise_] + step, cap[raise_])
    return bool(raise_.any())


# ---------------------------------------------------------------- step codes
CODE_BIAS = 200  # tolerance = 2 ** ((code - CODE_BIAS) / 8); code 255 = any value (no point moved)
FREE = 255


def code_for(t: np.ndarray) -> np.ndarray:
    """Largest code ``(columns,)`` uint8 whose tolerance is at most ``t`` (inf -> FREE)."""
    t = np.asarray(t, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.floor(8.0 * np.log2(np.maximum(t, 1e-300))) + CODE_BIAS
    c = np.clip(np.nan_to_num(c, nan=0.0), 0, FREE - 1).astype(np.int64)
    over = tol_of(c) > t
    c[over & (c > 0)] -= 1
    c[~np.isfinite(t)] = FREE
    return c.astype(np.uint8)


def tol_of(code: np.ndarray) -> np.ndarray:
    """Base tolerances ``(columns,)`` of codes (FREE -> a huge tolerance)."""
    code = np.asarray(code, dtype=np.float64)
    return np.where(code >= FREE, 1e30, 2.0 ** ((code - CODE_BIAS) / 8.0))
