"""Compiled (numba) kernel of one whole round of the closed loop (:meth:`~.chain.Chain.quantise` with the compiled
kernels): every joint, parents first, in one call (imported only when numba is installed; module-level
functions, so that numba's on-disk cache keeps them across processes).

The per-joint path runs, for each of a skeleton's joints, a dozen NumPy steps and three or four compiled
kernels from Python (a 31-joint CMU skeleton: about 30 ms a round on 5,000 frames, most of it the calls
themselves). This kernel makes the same calls (:func:`.chainkernels.place`, :func:`.chainkernels.goal_angles`,
:func:`.chainkernels.compose`, :func:`.liftkernels.details`) and does the NumPy steps between them with the same
float operations in the same order (the knots' ``rint``, NumPy's ``mod`` as its ``fmod`` and sign rule, the
tolerances from the table NumPy's ``2.0 ** (-level / 2)`` gives): the same integers, decoded residual and joint
positions to the bit (tests/test_correction_round.py). End sites are left to the caller (a NumPy product).

Shapes: ``x``, ``base``, ``y``, ``values`` ``(frames, columns)`` (file units, angles in the file's angle unit);
``q`` ``(n, columns)`` int64 (``n`` the padded frames of :func:`~.lifting.plan`); ``pos``, ``positions``
``(frames, points, 3)``; ``slots`` ``(live, frames, 3, 3)`` the decoded global rotations of the joints still
needed (a joint's slot ``slot[j]``; or a slot per joint, kept from a round to the next); ``ends`` ``(joints with
end sites, frames, 3, 3)`` theirs, returned.
"""

# ruff: noqa: ANN001, PLR0913
from __future__ import annotations

import math

import numpy as np
from numba import njit

from mocapz.codecs.correction.chainkernels import compose, goal_angles, hinge_residual, place
from mocapz.codecs.correction.chainkernels import remainder as _remainder
from mocapz.codecs.correction.liftkernels import details

jit = njit(cache=True, nogil=True, error_model="numpy")

BIG = 1e30  # :data:`.lifting.BIG`


@jit
def _lift(x, cols, t0, group, levels, lo, halves, lv: int, n: int, factors, step_scale: float, pre: int, prefix,
          y, q, changed, start: int, again: bool, dirty_groups, dirty_x) -> None:
    """:func:`~.lifting.quantise` of the columns ``cols`` (residual ``x``, tolerances ``t0[c] * halves[levels[f,
    group[c]] - lo]`` capped at ``BIG``), written into ``y`` and ``q``; on a call redoing the one before
    (``again``) only the columns whose tolerances (``dirty_groups``) or residual (``dirty_x``) changed since (the
    others' integers and decoded values are those of that call, in ``q`` and ``y``), and ``changed`` ``(frames,
    the joint's columns from start)`` marks the decoded values that moved. ``prefix`` ``(columns, 1 + ghost
    levels)`` (read where ``pre``): a continued clip's first knots and ghosts (:func:`~.lifting.split_prefix`)."""
    frames = x.shape[0]
    todo = np.empty(cols.size, dtype=np.int64)
    m = 0
    for k in range(cols.size):
        c = cols[k]
        if not again or dirty_groups[group[c]] or dirty_x[c]:
            todo[m] = c
            m += 1
    if m == 0:
        return
    todo = todo[:m]
    # column-major work arrays: the detail levels run down each column (and the residual is column-major)
    xp = np.empty((m, n)).T
    tp = np.empty((m, n)).T
    yb = np.zeros((m, n)).T
    qb = np.zeros((m, n), dtype=np.int64).T
    for k in range(m):
        c = todo[k]
        g = group[c]
        for r in range(n):
            src = min(max(r - pre, 0), frames - 1)  # the grid's row before a continued clip, the padding after
            xp[r, k] = x[src, c]
            tv = t0[c] * halves[levels[src, g] - lo]
            tp[r, k] = BIG if tv > BIG else tv
    span = 1 << lv
    knots = (n - 1) // span + 1
    for k in range(m):
        c = todo[k]
        least = tp[0, k]
        for i in range(1, knots):
            least = min(least, tp[i * span, k])
        step0 = 2.0 * factors[lv] * least
        origin = 0.0
        fixed = False  # a continued clip's first knot: the frame before, known to the decoder
        if pre:
            fixed = not math.isnan(prefix[c, 0])
            origin = prefix[c, 0] if fixed else 0.0
        before = 0
        for i in range(knots):
            r = i * span
            qi = int(np.rint((xp[r, k] - origin) / step0)) if pre else int(np.rint(xp[r, k] / step0))
            if i == 0 and fixed:
                qi = 0
            yb[r, k] = origin + qi * step0 if pre else qi * step0
            qb[i, k] = qi - before
            before = qi
    ghost = np.full((prefix.shape[1] - 1 if pre else 0, m), np.nan)  # the columns' ghosts (liftkernels._across)
    for g in range(ghost.shape[0]):
        for k in range(m):
            ghost[g, k] = prefix[todo[k], 1 + g]
    details(xp, tp, yb, qb, lv, factors, step_scale, knots, ghost)
    for k in range(m):
        c = todo[k]
        for f in range(frames):
            v = yb[f + pre, k]
            if again and v != y[f, c]:
                changed[f, c - start] = True
            y[f, c] = v
        for r in range(n):
            q[r, c] = qb[r, k]


@jit
def _any(changed, cols, start: int, again: bool, out) -> None:
    """``out`` ``(frames,)``: where a decoded value of columns ``cols`` moved (every frame unless ``again``)."""
    for f in range(out.size):
        hit = not again
        for k in range(cols.size):
            if hit:
                break
            hit = changed[f, cols[k] - start]
        out[f] = hit


@jit
def run(x, base, t0, group, levels, lo: int, halves, lv: int, n: int, factors, step_scale: float, pre: int,
        prefix, y, q, pos, slots, ends, moved_p, moved_g, again: bool, kept: bool, dirty_groups, parents, starts,
        stops, plain_ptr, plain_idx, feedback, rot_cols, euler3, e3_cols, all_cols, axes, axis_frames, turned, aim,
        ijk, signs, goal_of, goal_all, positions, values, pos_axis, offsets, slot, end_slot, scale: float,
        period: float, cos_turn: float, turn_n, hinge_n, hinge_cols, bones, max_turn: float) -> None:
    """One round of the closed loop over every joint (:meth:`~.chain.Chain.quantise`): ``y``, ``q``, the joints'
    rows of ``pos`` and ``ends`` filled, the feedback joints' rotation columns of ``x`` set to their residual
    against the goal (on the frames where something above them moved, when ``again``), ``moved_p`` and
    ``moved_g`` ``(joints, frames)`` where each joint's decoded position and global rotation may have moved. On a
    call redoing the one before (``again``: ``y`` and ``q`` hold its coding), a column is coded again only where
    its group's tolerances changed (``dirty_groups`` ``(groups,)``) or its residual against the goal did; and
    where ``slots`` hold every joint's decoded global rotations as that call left them (``kept``: a slot per
    joint), a joint's are composed again only on the frames where they may have moved (``moved_g``).

    Per joint: ``parents``, ``starts``/``stops`` (its columns), ``plain_idx[plain_ptr[j]:plain_ptr[j + 1]]`` the
    columns coded against their own original, ``feedback`` and ``rot_cols`` ``(joints, 3)``, ``euler3`` and
    ``e3_cols`` ``(joints, 3)`` (its three distinct rotation axes' columns; joints without are those with no
    rotation channel; ``turn_n`` of them, one to three), ``all_cols`` ``(joints, 6)`` its columns (-1 past them),
    ``axes`` ``(joints, 3)``,
    ``axis_frames`` ``(joints, 3, 3)``, ``turned``, ``aim``, ``ijk`` ``(joints, 3)`` and ``signs`` (the Euler
    extraction), ``goal_of`` its row of ``goal_all`` ``(feedback joints, frames, 3, 3)``, ``pos_axis`` ``(joints,
    3)`` the column of each position channel (-1: the ``offsets``' value), ``slot`` and ``end_slot`` (-1: no end
    site); a hinge (``hinge_n`` columns ``hinge_cols`` ``(joints, 2)``, one or two axes) aims its ``bones`` ``(joints,
    3)`` at its child ``aim``, turning at most ``max_turn`` radians."""
    frames = x.shape[0]
    half = period / 2.0
    trans = np.empty((frames, 3))
    vals = np.empty((frames, 3))
    out = np.empty((frames, 3))
    every = np.arange(frames)
    picked = np.empty(frames, dtype=np.int64)
    own = np.empty(frames, dtype=np.bool_)
    dirty_x = np.zeros(x.shape[1], dtype=np.bool_)  # the residual columns rewritten with other values
    prev = np.empty((frames, 2))  # a hinge's residual before this round (its columns rewritten with others)
    eye = np.eye(3)
    for j in range(parents.size):
        p = parents[j]
        start = starts[j]
        width = stops[j] - start
        gp = slots[slot[p]] if p >= 0 else slots[slot[j]]  # a root's parent rotations are never read
        changed = np.zeros((frames, width), dtype=np.bool_)
        plain = plain_idx[plain_ptr[j]:plain_ptr[j + 1]]
        if plain.size:
            _lift(x, plain, t0, group, levels, lo, halves, lv, n, factors, step_scale, pre, prefix, y, q, changed,
                  start, again, dirty_groups, dirty_x)
        for a in range(3):
            col = pos_axis[j, a]
            for f in range(frames):
                trans[f, a] = base[f, col] + y[f, col] if col >= 0 else offsets[j, a]
        place(gp, pos, j, p, trans)
        _any(changed, plain, start, again, own)
        for f in range(frames):
            moved_p[j, f] = own[f] if p < 0 else own[f] or moved_p[p, f] or moved_g[p, f]
        if feedback[j]:
            rot = rot_cols[j]
            count = 0
            for f in range(frames):
                if moved_p[j, f] or moved_g[p, f]:
                    picked[count] = f
                    count += 1
            if count:
                rows = picked[:count]
                goal_angles(gp, pos, j, p, goal_all[goal_of[j]], positions, aim[j], cos_turn, axis_frames[j],
                            turned[j], ijk[j], signs[j], scale, values, rot, period, out, rows)
                for r in range(count):
                    f = rows[r]
                    for a in range(3):
                        c = rot[a]
                        v = _remainder(out[f, a] - base[f, c] + half, period) - half
                        if v != x[f, c]:
                            dirty_x[c] = True
                        x[f, c] = v
            _lift(x, rot, t0, group, levels, lo, halves, lv, n, factors, step_scale, pre, prefix, y, q, changed,
                  start, again, dirty_groups, dirty_x)
        elif hinge_n[j] > 0:  # a hinge aimed at its child (:func:`.chainkernels.hinge_residual`)
            hc = hinge_cols[j, :hinge_n[j]]
            count = 0
            for f in range(frames):
                if not again or moved_p[j, f] or moved_g[p, f]:
                    picked[count] = f
                    count += 1
            if count:
                rows = picked[:count]
                for r in range(count):
                    for k in range(hc.size):
                        prev[r, k] = x[rows[r], hc[k]]
                hinge_residual(gp, pos, j, aim[j], positions, axis_frames[j], bones[j], axes[j, :turn_n[j]], scale,
                               values, hc, base, period, max_turn, x, rows)
                for r in range(count):
                    for k in range(hc.size):
                        if x[rows[r], hc[k]] != prev[r, k]:
                            dirty_x[hc[k]] = True
            _lift(x, hc, t0, group, levels, lo, halves, lv, n, factors, step_scale, pre, prefix, y, q, changed,
                  start, again, dirty_groups, dirty_x)
        _any(changed, e3_cols[j] if turn_n[j] == 3 else all_cols[j, :width], start, again, own)
        for f in range(frames):
            moved_g[j, f] = own[f] if p < 0 else own[f] or moved_g[p, f]
        gj = slots[slot[j]]
        rows = every
        if again and kept:  # the others' are the last call's, in their slot
            count = 0
            for f in range(frames):
                if moved_g[j, f]:
                    picked[count] = f
                    count += 1
            rows = picked[:count]
        if euler3[j]:  # one to three rotation axes
            k = turn_n[j]
            for a in range(k):
                col = e3_cols[j, a]
                for f in range(frames):
                    vals[f, a] = base[f, col] + y[f, col]
            if k == 3:
                compose(gj, gp, p, vals, scale, axes[j], axis_frames[j], turned[j], rows)
            else:
                compose(gj, gp, p, vals[:, :k], scale, axes[j, :k], axis_frames[j], turned[j], rows)
        else:  # no rotation channel: the parent's rotation times the identity, as NumPy's product gives it
            for r in range(rows.size):
                f = rows[r]
                for a in range(3):
                    for b in range(3):
                        gj[f, a, b] = gp[f, a, 0] * eye[0, b] + gp[f, a, 1] * eye[1, b] + gp[f, a, 2] * eye[2, b] \
                            if p >= 0 else eye[a, b]
        if end_slot[j] >= 0:
            ends[end_slot[j], :, :, :] = gj
