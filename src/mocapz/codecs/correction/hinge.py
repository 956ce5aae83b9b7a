"""The closed loop's aim for joints that turn about one or two axes (*hinges*: CMU's ASF/AMC knees, elbows and
toes turn about one; its feet, hands and clavicles about two).

:mod:`.chain` codes a joint with three rotation channels against its decoded parent, so that it takes back the
errors above it. A hinge cannot take every rotation, but it can turn its bone toward the original position of
the point below it: here are the angles that, under the decoded parent's global rotation and from the decoded
joint's position, point the bone at the original child, as near the original angles as they come.

One axis ``e``: the angle about ``e`` that brings the bone's component across ``e`` onto the goal's. Two axes in
matrix-product order (``R = R_a(alpha) @ R_b(beta)``, :func:`mocapz.model.kinematics.euler_rotations`): ``R_a``
keeps a vector's component along ``a``, so ``beta`` brings the bone's to the goal's (of the two solutions the
one nearer the original angle; the nearest it comes where none reaches), then ``alpha`` as for one axis. Where
a bone or its goal has no length, or an angle would turn more than ``max_turn`` from the original, the original
angles are kept (what the plain residual codes).

Shapes: the bone ``(3,)`` and goals ``(frames, 3)`` in the joint's axis frame (any length unit), angles ``(frames,
axes)`` in radians.
"""

from __future__ import annotations

import numpy as np

from mocapz.model.skeleton import Skeleton


def columns(sk: Skeleton, j: int, start: int, moving: np.ndarray, child: int) -> np.ndarray | None:
    """Joint ``j``'s rotation columns (its channels from column ``start``) in its rotation order, if it is a hinge
    the loop aims: one or two distinct rotation axes, every one of them ``moving`` ``(columns,)``, a parent, and
    one ``child`` point (joint or end site; -1: none or several) whose offset is fixed (no position channels);
    else None."""
    order = sk.rotation_order[j]
    if not 1 <= len(order) <= 2 or len(set(order.upper())) != len(order) or sk.parents[j] < 0 or child < 0:
        return None
    if child < sk.n_joints and any(c.endswith("position") for c in sk.channels[child]):
        return None
    cols = np.array([start + sk.channels[j].index(f"{a}rotation") for a in order], dtype=np.int64)
    return cols if bool(moving[cols].all()) else None


def child_offset(sk: Skeleton, child: int) -> np.ndarray:
    """The fixed offset ``(3,)`` of a child point (joint, or end site numbered after the joints) from its joint."""
    if child < sk.n_joints:
        return np.asarray(sk.offsets[child], dtype=np.float64)
    return np.asarray(sk.end_sites[child - sk.n_joints][1], dtype=np.float64)


def aim(order: str, bone: np.ndarray, goal: np.ndarray, near: np.ndarray, max_turn: float
        ) -> tuple[np.ndarray, np.ndarray]:
    """Angles ``(frames, len(order))`` (radians) about the axes of ``order`` that turn ``bone`` ``(3,)`` toward
    ``goal`` ``(frames, 3)``, each solution taken nearest the original angles ``near`` (same shape), and ``(frames,)``
    True where they hold: False where the bone or its goal has no length or an angle would turn over
    ``max_turn`` (the caller keeps the original there)."""
    axes = np.eye(3)[["XYZ".index(a) for a in order.upper()]]
    n_bone, n_goal = float(np.linalg.norm(bone)), np.linalg.norm(goal, axis=1)
    ok = (n_goal > 0) & (n_bone > 0)
    v = bone / (n_bone if n_bone > 0 else 1.0)
    u = goal / np.where(ok, n_goal, 1.0)[:, None]
    out = np.empty_like(near)
    if len(order) == 1:
        out[:, 0] = _about(axes[0], np.broadcast_to(v, u.shape), u)
    else:
        a, b = axes
        across = v - (v @ b) * b  # the bone's part that R_b turns
        p, q = float(across @ a), float(np.cross(b, v) @ a)  # R_b(beta) v . a = p cos(beta) + q sin(beta)
        reach = float(np.hypot(p, q))
        ok &= reach > 0
        phi = np.arctan2(q, p)
        spread = np.arccos(np.clip((u @ a) / (reach if reach > 0 else 1.0), -1.0, 1.0))
        first, second = _nearest(phi + spread, near[:, 1]), _nearest(phi - spread, near[:, 1])
        beta = np.where(np.abs(first - near[:, 1]) <= np.abs(second - near[:, 1]), first, second)
        turned = (v @ b) * b + np.cos(beta)[:, None] * across + np.sin(beta)[:, None] * np.cross(b, v)
        out[:, 0], out[:, 1] = _about(a, turned, u), beta
    out[:, 0] = _nearest(out[:, 0], near[:, 0])
    ok &= (np.abs(out - near) < max_turn).all(axis=1)
    return out, ok


def _about(e: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``(frames,)`` the angle about unit axis ``e`` ``(3,)`` that brings ``v``'s component across ``e`` onto
    ``u``'s (both ``(frames, 3)``)."""
    vp = v - (v @ e)[:, None] * e
    up = u - (u @ e)[:, None] * e
    return np.arctan2(np.cross(vp, up) @ e, (vp * up).sum(axis=1))


def _nearest(angle: np.ndarray, near: np.ndarray) -> np.ndarray:
    """``angle`` plus the whole turns that bring it nearest ``near`` (radians)."""
    return angle + 2.0 * np.pi * np.round((near - angle) / (2.0 * np.pi))
