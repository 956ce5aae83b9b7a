"""A round of the closed loop in one compiled call (:mod:`.roundkernels`): what the call needs of a skeleton, as
arrays made once per :class:`~.chain.Chain` (:class:`RoundPlan`), and the call itself (:func:`quantise`).

:meth:`.chain.Chain.quantise` takes this path with the compiled kernels where no joint repeats a rotation axis (BVH,
ASF with its one- and two-axis hinges), the tolerances are per column (:class:`.bounds.ColumnTolerances`, as
the verification rounds make them) and the values are finite; otherwise its per-joint loop (the same numbers).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from mocapz.codecs.correction import hinge, lifting
from mocapz.codecs.correction.bounds import ColumnTolerances

Chain = Any  # a :class:`.chain.Chain` (which imports this module)
KEPT_BYTES = 64 << 20  # every joint's decoded rotations kept from a round to the next up to this size (a CMU
# skeleton's for 30,000 frames): a round composes again only the frames where they may have moved


@dataclass(frozen=True)
class RoundPlan:
    """A skeleton's joints as :func:`.roundkernels.run` takes them (its docstring says what each array holds)."""

    arrays: dict[str, np.ndarray]
    n_slots: int  # decoded global rotations alive at once
    n_ends: int  # joints with end sites


def plan(chain: Chain) -> RoundPlan | None:
    """The arrays of ``chain``'s skeleton (joints with one to three distinct rotation axes, ASF hinges aimed at
    their child), or None where a joint repeats an axis (its rotation is composed by the per-joint path's NumPy
    product)."""
    sk = chain.skeleton
    n = sk.n_joints
    if any(chain.turns[j] is None and sk.rotation_order[j] for j in range(n)):
        return None
    width = max((sl.stop - sl.start for sl in chain.slices), default=0)
    a: dict[str, np.ndarray] = {
        "parents": np.asarray(sk.parents, dtype=np.int64),
        "starts": np.array([sl.start for sl in chain.slices], dtype=np.int64),
        "stops": np.array([sl.stop for sl in chain.slices], dtype=np.int64),
        "plain_ptr": np.cumsum([0] + [len(p) for p in chain.plain]).astype(np.int64),
        "plain_idx": np.concatenate([np.asarray(p, dtype=np.int64) for p in chain.plain] or [np.zeros(0, np.int64)]),
        "feedback": np.asarray(chain.feedback, dtype=np.bool_),
        "rot_cols": np.zeros((n, 3), dtype=np.int64),
        "euler3": np.array([c is not None for c in chain.turns], dtype=np.bool_),  # one to three axes
        "turn_n": np.array([0 if c is None else len(c) for c in chain.turns], dtype=np.int64),
        "hinge_n": np.array([0 if c is None else len(c) for c in chain.hinge], dtype=np.int64),
        "hinge_cols": np.zeros((n, 2), dtype=np.int64),
        "bones": np.zeros((n, 3)),
        "e3_cols": np.zeros((n, 3), dtype=np.int64),
        "all_cols": np.full((n, max(width, 1)), -1, dtype=np.int64),
        "axes": np.zeros((n, 3), dtype=np.int64),
        "axis_frames": np.ascontiguousarray(np.stack([chain.axis_of[j] for j in range(n)]), dtype=np.float64),
        "turned": np.asarray(chain.turned, dtype=np.bool_),
        "aim": np.asarray(chain.aim, dtype=np.int64),
        "ijk": np.zeros((n, 3), dtype=np.int64),
        "signs": np.zeros(n),
        "goal_of": np.full(n, -1, dtype=np.int64),
        "pos_axis": np.full((n, 3), -1, dtype=np.int64),
        "offsets": np.ascontiguousarray(sk.offsets, dtype=np.float64),
        "slot": np.zeros(n, dtype=np.int64),
        "end_slot": np.full(n, -1, dtype=np.int64),
    }
    for j in range(n):
        sl = chain.slices[j]
        a["all_cols"][j, : sl.stop - sl.start] = np.arange(sl.start, sl.stop)
        if chain.turns[j] is not None:
            k = len(chain.turns[j])
            a["e3_cols"][j, :k] = chain.turns[j]
            a["axes"][j, :k] = chain.axes[j]
        if chain.hinge[j] is not None:
            a["hinge_cols"][j, :len(chain.hinge[j])] = chain.hinge[j]
            a["bones"][j] = chain.axis_of[j].T @ hinge.child_offset(sk, int(chain.aim[j]))
        if chain.feedback[j]:
            a["rot_cols"][j] = chain.rot_cols[j]
            i, k, m = ("XYZ".index(c) for c in sk.rotation_order[j].upper())
            a["ijk"][j] = (i, k, m)
            a["signs"][j] = 1.0 if (k - i) % 3 == 1 else -1.0  # as the per-joint path's goal angles
            a["goal_of"][j] = chain.goal_index[j]
        for k, c in enumerate(sk.channels[j]):
            if c.endswith("position"):
                a["pos_axis"][j, "XYZ".index(c[0])] = sl.start + k
    # slots: a joint's decoded rotation lives from its turn until its last child's (as the per-joint path keeps it)
    left = [len(c) for c in chain.children]
    free: list[int] = []
    slots = 0
    for j in range(n):
        if free:
            a["slot"][j] = free.pop()
        else:
            a["slot"][j], slots = slots, slots + 1
        p = int(sk.parents[j])
        if p >= 0:
            left[p] -= 1
            if not left[p]:
                free.append(int(a["slot"][p]))
        if not left[j]:
            free.append(int(a["slot"][j]))
    holders = sorted({int(j) for j, _, _ in sk.end_sites})
    a["end_slot"][holders] = np.arange(len(holders))
    return RoundPlan(a, slots, len(holders))


def usable(chain: Chain, x: np.ndarray, base: np.ndarray, tol: object) -> bool:
    """Whether this call can take the one-call path: a plan, per-column tolerances and finite values (a NaN takes
    the per-joint path, which codes it as NumPy does)."""
    return chain.round_plan is not None and isinstance(tol, ColumnTolerances) and chain.finite \
        and bool(np.isfinite(x).all()) and bool(np.isfinite(base).all())


def quantise(chain: Chain, kern: ModuleType, x: np.ndarray, base: np.ndarray, tol: ColumnTolerances, levels: int,
             shrink: float, prefix: np.ndarray | None, y: np.ndarray,
             before: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None,
             cos_turn: float, max_turn: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:meth:`.chain.Chain.quantise`'s round in one call: fills ``y`` ``(frames, columns)`` and returns the integers
    ``(n, columns)``, the decoded positions ``(frames, points, 3)`` and every joint's decoded global rotations
    ``(joints, frames, 3, 3)`` where they are kept for the next call (at most :data:`KEPT_BYTES`; else None).
    ``before``: on a call redoing the one before (the same ``x``, ``base``, ``t0`` and column groups; ``y`` holds
    its decoded residual), its integers (updated in place and returned), its tolerance levels ``(frames, groups)``
    and its rotations (or None): the columns whose tolerances and residual are unchanged keep their coding, and the
    joints' rotations are composed again only on the frames where they may have moved."""
    rp = chain.round_plan
    assert rp is not None
    sk = chain.skeleton
    frames, cols = x.shape
    pre = int(prefix is not None)
    lv, n = lifting.plan(frames + pre, levels)
    lo, hi = int(tol.levels.min()), int(tol.levels.max())
    halves = 2.0 ** (-np.arange(lo, hi + 1).astype(np.float64) / 2.0)  # NumPy's own numbers for every level
    factors = np.array([lifting.level_factor(level, shrink) for level in range(lv + 1)])
    again = before is not None and before[1].shape == tol.levels.shape
    if again and before is not None:
        q, dirty = before[0], (before[1] != tol.levels).any(axis=0)
    else:
        q = np.zeros((n, cols), dtype=np.int64, order="F" if x.flags.f_contiguous and cols > 1 else "C")
        dirty = np.ones(tol.levels.shape[1], dtype=np.bool_)
    pos = np.empty((frames, sk.n_points, 3))
    a = rp.arrays
    each = (sk.n_joints, frames, 3, 3)  # a slot per joint, kept for the next round where it is small enough
    kept = None if before is None or before[2] is None or before[2].shape != each else before[2]
    if kept is None and 8 * int(np.prod(each)) <= KEPT_BYTES:
        kept = np.empty(each)
    slots = np.empty((rp.n_slots, frames, 3, 3)) if kept is None else kept
    slot = a["slot"] if kept is None else np.arange(sk.n_joints, dtype=np.int64)
    ends = np.empty((rp.n_ends, frames, 3, 3))
    moved = np.empty((2, sk.n_joints, frames), dtype=np.bool_)
    reused = again and before is not None and kept is not None and kept is before[2]  # the last call's, in place
    kern.run(x, base, tol.t0, tol.group, tol.levels, lo, halves, lv, n, factors, lifting.STEP, pre,
             np.zeros((0, 1)) if prefix is None else np.asarray(prefix, dtype=np.float64).reshape(cols, -1), y, q, pos,
             slots, ends, moved[0], moved[1], again, reused, dirty, a["parents"], a["starts"], a["stops"],
             a["plain_ptr"], a["plain_idx"], a["feedback"], a["rot_cols"], a["euler3"], a["e3_cols"], a["all_cols"],
             a["axes"], a["axis_frames"], a["turned"], a["aim"], a["ijk"], a["signs"], a["goal_of"], chain.goal_all,
             chain.positions, chain.values, a["pos_axis"], a["offsets"], slot, a["end_slot"], chain.scale,
             chain.period, cos_turn, a["turn_n"], a["hinge_n"], a["hinge_cols"], a["bones"], max_turn)
    for e, (j, off, _) in enumerate(sk.end_sites):
        pos[:, sk.n_joints + e] = pos[:, j] + ends[a["end_slot"][j]] @ np.asarray(off)
    return q, pos, kept
