"""Closed-loop correction down a skeleton's hierarchy: a joint's rotation is coded against its *decoded* parent.

Coding every channel against its own original value lets the errors of a chain's rotations add up: an error
``q`` on the hips turns every bone below them, so a hand is moved by ``q`` times the whole chain's length
(the lever) and every joint of the chain shares the position bound with all the others. Here the encoder
walks the joints parents first; for a joint ``j`` with three moving rotation channels (a *feedback* joint) it
codes the local rotation that, composed with the parent's decoded global rotation, gives back ``j``'s
original global rotation:

    R_local_target(j) = Rg_decoded(parent)^T  Rg_original(j)

so a joint's global rotation is off by its own quantisation error only, and that error moves the points
below it by at most ``|q| * |bone|`` (the bones leaving ``j``), not ``|q| * lever``. A joint that turns about
one or two axes (a *hinge*: an ASF/AMC knee, foot, elbow) cannot take every rotation: its angles are the ones
that point its bone at the original child (:mod:`.hinge`). The decoder is unchanged: it adds the coded
residuals to the channels as before (the loop is the encoder's alone).

Shapes: values ``(frames, columns)`` in the file's units (angles in the file's angle unit), rotations
``(frames, 3, 3)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from mocapz.codecs.correction import chainround, hinge, lifting
from mocapz.codecs.correction.bounds import ColumnTolerances
from mocapz.codecs.correction.compiled import kernels
from mocapz.model.kinematics import euler_angles, euler_rotations, local_translations
from mocapz.model.motion import Motion

MAX_TURN = 0.3  # radians a bone is turned at most to aim at its child (beyond: its global rotation is matched)
COS_TURN = float(np.cos(MAX_TURN))


class Chain:
    """What the closed loop needs of an original skeletal clip.

    Args:
        motion: the original clip.
        positions: its positions ``(frames, points, 3)`` (from forward kinematics).
        global_rot: its global rotations ``(frames, joints, 3, 3)`` (from forward kinematics); only the feedback
            joints' are kept (:attr:`goal_rot`), so the caller's array may be let go.
    """

    def __init__(self, motion: Motion, positions: np.ndarray, global_rot: np.ndarray) -> None:
        sk = motion.skeleton
        self.positions = positions
        self.skeleton = sk
        self.values = np.asarray(motion.channels, dtype=np.float64)
        self.scale = np.pi / 180.0 if sk.angle_unit == "deg" else 1.0
        self.period = 360.0 if sk.angle_unit == "deg" else 2 * np.pi
        moving = np.ptp(self.values, axis=0) > 0 if len(self.values) else np.zeros(sk.n_channels, dtype=bool)
        self.slices = sk.channel_slices()
        self.rot_cols: list[np.ndarray | None] = []  # per joint: its rotation columns in `order`, if feedback
        for sl, chs, order in zip(self.slices, sk.channels, sk.rotation_order, strict=True):
            cols = np.array([sl.start + chs.index(f"{a}rotation") for a in order], dtype=np.int64) \
                if len(order) == 3 else np.zeros(0, dtype=np.int64)
            ok = len(order) == 3 and len(set(order.upper())) == 3 and bool(moving[cols].all())
            self.rot_cols.append(cols if ok else None)
        self.turned = [not np.array_equal(a, np.eye(3)) for a in sk.axis]  # type: ignore[union-attr]
        self.feedback = np.array([c is not None for c in self.rot_cols], dtype=bool)
        self.feedback[sk.parents < 0] = False  # a root has nothing decoded above it
        # per feedback joint, its original global rotation ``(frames, 3, 3)`` (the goal under its decoded parent)
        held = np.flatnonzero(self.feedback)
        self.goal_all = np.empty((len(held), *global_rot.shape[:1], 3, 3))  # one array (the one-call round's)
        self.goal_index = np.full(sk.n_joints, -1, dtype=np.int64)
        for k, j in enumerate(held):
            self.goal_all[k], self.goal_index[j] = global_rot[:, j], k
        self.goal_rot = [self.goal_all[k] if k >= 0 else None for k in self.goal_index]
        self.finite = bool(np.isfinite(positions).all() and np.isfinite(self.values).all())
        kids: list[list[int]] = [[] for _ in range(sk.n_joints)]  # points (joints, end sites) hanging on j
        for c in range(sk.n_joints):
            if sk.parents[c] >= 0:
                kids[sk.parents[c]].append(c)
        for e, (j, _, _) in enumerate(sk.end_sites):
            kids[j].append(sk.n_joints + e)
        self.aim = np.array([k[0] if len(k) == 1 else -1 for k in kids], dtype=np.int64)
        # per joint with three distinct rotation axes: its columns in `order` and the axes (compiled kernels)
        self.euler3 = [np.array([sl.start + chs.index(f"{a}rotation") for a in order], dtype=np.int64)
                       if len(order) == 3 and len(set(order.upper())) == 3 else None
                       for sl, chs, order in zip(self.slices, sk.channels, sk.rotation_order, strict=True)]
        # per joint with one to three distinct rotation axes: their columns in `order` (the compiled compose)
        self.turns = [e3 if e3 is not None or not 1 <= len(o) <= 2 or len(set(o.upper())) != len(o)
                      else np.array([sl.start + chs.index(f"{a}rotation") for a in o], dtype=np.int64)
                      for e3, sl, chs, o in zip(self.euler3, self.slices, sk.channels, sk.rotation_order, strict=True)]
        # the joints turning about one or two axes that aim their bone at the original child (:mod:`.hinge`)
        self.hinge = [hinge.columns(sk, j, sl.start, moving, int(self.aim[j])) for j, sl in enumerate(self.slices)]
        # per joint, what every round of the loop asks for: the columns coded against their own original, the
        # axes and axis frame, its child joints and end sites
        self.plain = [np.arange(sl.start, sl.stop) if rot is None or not fb
                      else np.setdiff1d(np.arange(sl.start, sl.stop), rot)
                      for sl, rot, fb in zip(self.slices, self.rot_cols, self.feedback, strict=True)]
        self.plain = [p if h is None else np.setdiff1d(p, h) for p, h in zip(self.plain, self.hinge, strict=True)]
        self.axes = [_axes(order) for order in sk.rotation_order]
        self.axis_of = [self._axis(j) for j in range(sk.n_joints)]
        self.children = [[c for c in range(sk.n_joints) if sk.parents[c] == j] for j in range(sk.n_joints)]
        self.ends = [[e for e, site in enumerate(sk.end_sites) if site[0] == j] for j in range(sk.n_joints)]
        self.last: _Last | None = None  # what the last call of quantise kept (compiled kernels)
        self.round_plan = chainround.plan(self)  # the one-call round's arrays, or None (the per-joint loop)
        self.work = motion.n_frames  # frames of the whole job (a block's clip): whether the kernels pay for loading

    def levers(self, channels: np.ndarray) -> np.ndarray:
        """``(joints,)`` how far a rotation error of each joint moves a point (per radian, file units): the
        longest bone leaving it, continued through children without feedback (they turn with it)."""
        sk = self.skeleton
        trans = local_translations(sk, channels) if len(channels) else np.broadcast_to(sk.offsets, (1, sk.n_joints, 3))
        bone = np.linalg.norm(trans, axis=2).max(axis=0)  # (joints,) from the parent to each joint
        out = np.zeros(sk.n_joints)
        for j, off, _ in sk.end_sites:
            out[j] = max(out[j], float(np.linalg.norm(off)))
        for c in range(sk.n_joints - 1, -1, -1):  # children before parents
            p = sk.parents[c]
            if p >= 0:
                out[p] = max(out[p], bone[c] + (0.0 if self.feedback[c] else out[c]))
        return out

    def quantise(self, x: np.ndarray, base: np.ndarray, tol: np.ndarray | ColumnTolerances, levels: int,
                 shrink: float, prefix: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`~mocapz.codecs.correction.lifting.quantise` in closed loop: the residual of every feedback
        joint's rotation columns is taken against the decoded parent; ``x`` ``(frames, columns)`` is the plain
        residual (original minus ``base``, wrapped) used for every other column, and the feedback joints'
        rotation columns of ``x`` are overwritten with the residuals against their goals (in place: no second
        frames x columns array; those columns of the plain residual are never read). ``tol``: ``(frames,
        columns)``, dense or per column (taken a joint's columns at a time). Returns the integers and the
        decoded residual, as :func:`~mocapz.codecs.correction.lifting.quantise`, and the decoded positions
        ``(frames, points, 3)`` (the forward kinematics of ``base`` plus the decoded residual, joints then end
        sites: the loop has composed them already). A joint's decoded global rotations are kept only while a
        joint or end site below it needs them. With the compiled kernels the decoded residual (and, where the
        round runs in one call, :mod:`.chainround`, the integers) is the loop's own array, kept for the next call
        on the same ``x`` and ``base`` (which updates it in place): callers do not change it, and let it go
        before that call (or :meth:`forget` first). ``prefix`` ``(columns,)``: a continued clip's
        (:func:`~mocapz.codecs.correction.lifting.quantise`)."""
        sk = self.skeleton
        frames, cols = x.shape
        kern = kernels(max(frames, self.work))
        compiled = kern is not None
        last = self.last
        again = compiled and last is not None and last.x is x and last.base is base and last.key == (levels, shrink)
        y = last.y if again and last is not None else np.zeros_like(x)  # again: only what moved is redone
        prev, self.last = last, None  # kept again when this call is through (never half updated)
        round_kern = kernels(0, "roundkernels") if kern is not None and chainround.usable(self, x, base, tol) \
            else None
        if round_kern is not None:  # the whole round in one compiled call: the same numbers
            before = None if not again or prev is None or prev.q is None or prev.t0 is None \
                or not np.array_equal(prev.t0, tol.t0) else (prev.q, prev.levels, prev.rot)  # type: ignore[union-attr]
            last = prev = None  # its rotations are updated in place, or let go before new ones are made
            q, pos, rot = chainround.quantise(self, round_kern, x, base, tol, levels, shrink,  # type: ignore[arg-type]
                                              prefix, y, before, COS_TURN, MAX_TURN)
            self.last = _Last(x, base, (levels, shrink), y, q, tol.t0.copy(),  # type: ignore[union-attr]
                              np.array(tol.levels, copy=True), rot)  # type: ignore[union-attr]
            return q, y, pos
        _, n = lifting.plan(frames + (prefix is not None), levels)
        q = np.zeros((n, cols), dtype=np.int64)
        pos = np.empty((frames, sk.n_points, 3))
        p_dec = pos[:, : sk.n_joints]  # the joints' positions: a view of the points'
        g: dict[int, np.ndarray] = {}  # decoded global rotations (frames, 3, 3) of the joints still needed
        left = [len(c) for c in self.children]  # child joints not done yet, per joint
        moved_g: list[np.ndarray] = []  # per joint: the frames where its decoded global rotation may have moved
        moved_p: list[np.ndarray] = []  # and its decoded position
        for j in range(sk.n_joints):
            sl = self.slices[j]
            p = sk.parents[j]
            gp = g[p] if p >= 0 else _NO_PARENT
            rot = self.rot_cols[j] if self.feedback[j] else None
            plain = self.plain[j]
            changed = np.zeros((frames, sl.stop - sl.start), dtype=bool)  # the joint's decoded values that moved
            if plain.size:  # translations, and rotations coded against their own original
                _put(q, y, plain, *lifting.quantise(x[:, plain], tol[:, plain], levels, shrink, compiled,
                                                    None if prefix is None else prefix[plain]), changed,
                     sl.start, again)
            trans = self._translation(j, base[:, sl] + y[:, sl])
            if kern is not None:
                kern.place(gp, p_dec, j, p, trans)
            else:
                p_dec[:, j] = trans if p < 0 else p_dec[:, p] + np.einsum("fab,fb->fa", gp, trans)
            own = _moved(changed, plain, sl.start, again)
            moved_p.append(own if p < 0 else own | moved_p[p] | moved_g[p])
            aimed = rot if rot is not None else self.hinge[j]  # a joint is one or the other (3 axes, or 1-2)
            if aimed is not None:  # its residual against what aims it, under its decoded parent
                if rot is not None:
                    self._goal_residual(j, gp, p_dec, kern, base, x, moved_p[j] | moved_g[p])
                else:
                    self._hinge_residual(j, gp, p_dec, base, x, kern)
                _put(q, y, aimed, *lifting.quantise(x[:, aimed], tol[:, aimed], levels, shrink, compiled,
                                                    None if prefix is None else prefix[aimed]), changed,
                     sl.start, again)
            # the decoded global rotation, on every frame (a few products per frame), and where it may have moved
            own = _moved(changed, np.arange(sl.start, sl.stop) if self.euler3[j] is None else self.euler3[j],
                         sl.start, again)
            moved_g.append(own if p < 0 else own | moved_g[p])
            g[j] = self._global(j, gp, base[:, sl] + y[:, sl], kern)
            for e in self.ends[j]:
                pos[:, sk.n_joints + e] = p_dec[:, j] + g[j] @ np.asarray(sk.end_sites[e][1])
            if p >= 0:
                left[p] -= 1
                if not left[p]:
                    del g[p]  # every joint below it is placed
            if not left[j]:
                del g[j]
        self.last = _Last(x, base, (levels, shrink), y) if compiled else None
        return q, y, pos

    def forget(self) -> None:
        """Drop what :meth:`quantise` kept of its last call (the next call codes every frame anew)."""
        self.last = None

    def _global(self, j: int, gp: np.ndarray, values: np.ndarray, kern: ModuleType | None) -> np.ndarray:
        """Decoded global rotations ``(frames, 3, 3)`` of joint ``j`` from its parent's ``gp`` (a root: none) and
        its decoded channel values ``(frames, its channels)``."""
        cols = self.turns[j]
        p = self.skeleton.parents[j]
        if kern is not None and cols is not None:
            out = np.empty((values.shape[0], 3, 3))
            kern.compose(out, gp, p, np.ascontiguousarray(values[:, cols - self.slices[j].start]), self.scale,
                         self.axes[j], self.axis_of[j], self.turned[j], np.arange(values.shape[0]))
            return out
        local = self._local(j, values)
        return gp @ local if p >= 0 else local

    def _goal_residual(self, j: int, gp: np.ndarray, p_dec: np.ndarray, kern: ModuleType | None,
                       base: np.ndarray, goal: np.ndarray, moved: np.ndarray) -> None:
        """The residual of feedback joint ``j``'s rotation columns against its goal angles (:meth:`_goal_angles`),
        wrapped, into ``goal`` ``(frames, columns)``: with the compiled kernels on the frames ``moved`` only
        (the others' decoded parent and position are those of the call before), else on every frame."""
        rot = self.rot_cols[j]
        half = self.period / 2
        if kern is None:
            goal[:, rot] = np.mod(self._goal_angles(j, gp, p_dec, None) - base[:, rot] + half, self.period) - half
            return
        rows = np.flatnonzero(moved)
        if rows.size:
            angles = self._goal_angles(j, gp, p_dec, kern, rows)
            at = np.ix_(rows, rot)
            goal[at] = np.mod(angles[rows] - base[at] + half, self.period) - half

    def _hinge_residual(self, j: int, gp: np.ndarray, p_dec: np.ndarray, base: np.ndarray, goal: np.ndarray,
                        kern: ModuleType | None = None) -> None:
        """The residual of hinge ``j``'s rotation columns against the angles that aim its bone from the decoded
        joint (positions ``p_dec`` ``(frames, joints, 3)``) at the original child under the decoded parent
        (global rotations ``gp`` ``(frames, 3, 3)``) (:func:`.hinge.aim`), wrapped, into ``goal`` ``(frames,
        columns)``, on every frame (a few products per frame)."""
        sk, cols, child = self.skeleton, self.hinge[j], int(self.aim[j])
        a = self.axis_of[j]
        if kern is not None:  # the same, frame by frame (to float rounding)
            kern.hinge_residual(gp, p_dec, j, child, self.positions, a, a.T @ hinge.child_offset(sk, child),
                                self.axes[j], self.scale, self.values, cols, base, self.period, MAX_TURN, goal,
                                np.arange(len(goal)))
            return
        to_child = np.einsum("fba,fb->fa", gp, self.positions[:, child] - p_dec[:, j]) @ a  # in j's axis frame
        near = self.values[:, cols]
        angles, ok = hinge.aim(sk.rotation_order[j], a.T @ hinge.child_offset(sk, child), to_child,
                               near * self.scale, MAX_TURN)
        angles /= self.scale
        angles += self.period * np.round((near - angles) / self.period)  # the original's turn (float rounding)
        angles = np.where(ok[:, None], angles, near)
        half = self.period / 2
        goal[:, cols] = np.mod(angles - base[:, cols] + half, self.period) - half

    def _goal_angles(self, j: int, gp: np.ndarray, p_dec: np.ndarray, kern: ModuleType | None,
                     rows: np.ndarray | None = None) -> np.ndarray:
        """Euler angles ``(frames, 3)`` (file unit, nearest the original's) of feedback joint ``j``'s local
        rotation that gives back its original global rotation under its decoded parent (global rotations
        ``gp`` ``(frames, 3, 3)``), the bone turned first to point from the decoded joint (positions
        ``p_dec`` ``(frames, joints, 3)``) at the original child; the compiled kernel fills the frames ``rows``
        only (default: all)."""
        sk = self.skeleton
        p, aim, rot, order = sk.parents[j], int(self.aim[j]), self.rot_cols[j], sk.rotation_order[j]
        if kern is not None:
            out = np.empty((gp.shape[0], 3))
            i, k, m = ("XYZ".index(a) for a in order.upper())
            kern.goal_angles(gp, p_dec, j, p, self.goal_rot[j], self.positions, aim, COS_TURN,
                             self.axis_of[j], self.turned[j], np.array([i, k, m], dtype=np.int64),
                             1.0 if (k - i) % 3 == 1 else -1.0, self.scale, self.values, rot, self.period, out,
                             np.arange(len(out)) if rows is None else rows)
            return out
        goal = self.goal_rot[j]
        if aim >= 0:  # turn the bone to point from the decoded joint at the original child
            goal = _turn(self.positions[:, aim] - self.positions[:, j], self.positions[:, aim] - p_dec[:, j],
                         MAX_TURN) @ goal
        target = gp.swapaxes(1, 2) @ goal
        if self.turned[j]:
            a = self._axis(j)
            target = a.T @ target @ a
        return self._euler(target, order, self.values[:, rot])

    def _axis(self, j: int) -> np.ndarray:
        """The joint's axis frame ``(3, 3)`` (the identity but for ASF joints with axes)."""
        axis = self.skeleton.axis
        return np.eye(3) if axis is None else np.ascontiguousarray(axis[j], dtype=np.float64)

    def _translation(self, j: int, values: np.ndarray) -> np.ndarray:
        """Local translation ``(frames, 3)`` of joint ``j`` from its decoded channel values (its offset where
        it has no position channel)."""
        out = np.broadcast_to(self.skeleton.offsets[j], (values.shape[0], 3)).copy()
        for k, c in enumerate(self.skeleton.channels[j]):
            if c.endswith("position"):
                out[:, "XYZ".index(c[0])] = values[:, k]
        return out

    def _local(self, j: int, values: np.ndarray) -> np.ndarray:
        """Local rotation ``(frames, 3, 3)`` of joint ``j`` from its decoded channel values."""
        sk = self.skeleton
        order = sk.rotation_order[j]
        frames = values.shape[0]
        if not order:
            return np.broadcast_to(np.eye(3), (frames, 3, 3)).copy()
        chs = sk.channels[j]
        cols = [chs.index(f"{a}rotation") for a in order]
        r = euler_rotations(values[:, cols] * self.scale, order)
        if not self.turned[j]:
            return r
        a = sk.axis[j]  # type: ignore[index]
        return a @ r @ a.T

    def _euler(self, r: np.ndarray, order: str, near: np.ndarray) -> np.ndarray:
        """Intrinsic Euler angles ``(frames, 3)`` (file angle unit) of rotations ``(frames, 3, 3)`` in ``order``,
        of the two solutions and every turn the one nearest ``near`` ``(frames, 3)``."""
        a = euler_angles(r, order) / self.scale
        half = self.period / 2
        b = a + np.array([half, 0.0, half])
        b[:, 1] = half - a[:, 1]
        best = None
        for s in (a, b):
            s = s + self.period * np.round((near - s) / self.period)
            if best is None:
                best = s
            else:
                closer = np.abs(s - near).sum(axis=1) < np.abs(best - near).sum(axis=1)
                best = np.where(closer[:, None], s, best)
        assert best is not None
        return best


@dataclass
class _Last:
    """What :meth:`Chain.quantise` keeps of its last call with the compiled kernels: its arguments (``x``, which
    holds the residuals coded: feedback joints' against their goal, ``base``, ``(levels, shrink)``) and the
    decoded residual (the array returned, not a copy: the next call updates it in place). A call on the same
    ``x`` and ``base`` (the rounds of one fit, which change the tolerances only) redoes the goals only on the
    frames where a decoded value above them may have changed: each frame's are computed on their own, so the
    result is the same to the bit."""

    x: np.ndarray
    base: np.ndarray
    key: tuple[int, float]
    y: np.ndarray
    q: np.ndarray | None = None  # the one-call round's: its integers (updated in place by the next call)
    t0: np.ndarray | None = None  # and the tolerances they were made with
    levels: np.ndarray | None = None
    rot: np.ndarray | None = None  # and every joint's decoded global rotations, where kept (:mod:`.chainround`)


_NO_PARENT = np.empty((0, 3, 3))  # a root's parent rotations (never read)


def _put(q: np.ndarray, y: np.ndarray, cols: np.ndarray, qc: np.ndarray, yc: np.ndarray, changed: np.ndarray,
         start: int, again: bool) -> None:
    """Write the integers ``qc`` and decoded residual ``yc`` ``(frames, len(cols))`` of columns ``cols`` into ``q``
    and ``y``; on a call redoing the one before (``again``), mark first in ``changed`` ``(frames, the joint's
    columns from ``start``)`` where a decoded value differs from the one it replaces."""
    if again:
        changed[:, cols - start] = yc != y[:, cols]
    q[:, cols], y[:, cols] = qc, yc


def _moved(changed: np.ndarray, cols: np.ndarray, start: int, again: bool) -> np.ndarray:
    """``(frames,)`` True where a decoded value of columns ``cols`` moved (:func:`_put`); every frame on a call
    that codes every frame anew."""
    if not again:
        return np.ones(changed.shape[0], dtype=bool)
    return changed[:, cols - start].any(axis=1)


def _axes(order: str) -> np.ndarray:
    return np.array(["XYZ".index(a) for a in order.upper()], dtype=np.int64)


def _turn(a: np.ndarray, b: np.ndarray, most: float) -> np.ndarray:
    """The smallest rotations ``(frames, 3, 3)`` taking the directions of ``a`` to those of ``b`` ``(frames, 3)``;
    identity where either is zero or the turn is over ``most`` radians (a bone short beside the error of
    its joint: turning it would swing everything below)."""
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    ok = (na > 0) & (nb > 0)
    u = np.where(ok[:, None], a / np.where(ok, na, 1.0)[:, None], 0.0)
    w = np.where(ok[:, None], b / np.where(ok, nb, 1.0)[:, None], 0.0)
    v = np.cross(u, w)
    c = (u * w).sum(axis=1)
    k = np.zeros((len(a), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    ok &= c > np.cos(most)
    f = np.where(ok, 1.0 / (1.0 + np.maximum(c, -0.5)), 0.0)
    out = np.eye(3) + k + (k @ k) * f[:, None, None]
    out[~ok] = np.eye(3)
    return out
