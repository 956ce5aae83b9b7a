"""Batched forward kinematics: all frames at once, one vectorised step per joint (or, where the kernels compiled
ahead of time are built, :mod:`.fkkernels`: the same numbers, to the bit, a frame at a time in one call)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz import _jit, aot
from mocapz.model.skeleton import Skeleton

POSITION_CHUNK = 1024  # frames whose rotations :func:`forward_positions` (and whose temporaries
# :func:`local_rotations`) holds at once


def axis_rotations(angle: np.ndarray, axis: int) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` about coordinate axis ``axis`` (0 x, 1 y, 2 z) by ``angle`` ``(...)``
    radians."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((*angle.shape, 3, 3))
    i, k = (axis + 1) % 3, (axis + 2) % 3
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., k, k] = c
    out[..., i, k] = -s
    out[..., k, i] = s
    return out


def euler_rotations(angles: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic Euler rotations ``(..., 3, 3)`` from ``angles`` ``(..., len(order))`` radians about the axes
    of ``order`` in matrix-product order (``"ZXY"``: ``R = Rz(a0) @ Rx(a1) @ Ry(a2)``, as BVH applies its
    channels; scipy's ``Rotation.from_euler("ZXY", ...)`` to float rounding)."""
    r = axis_rotations(angles[..., 0], "XYZ".index(order[0].upper()))
    for k in range(1, len(order)):
        # R @ R_axis(t) mixes two columns of R: (i, k) -> (c i + s k, c k - s i)
        axis = "XYZ".index(order[k].upper())
        i, j = (axis + 1) % 3, (axis + 2) % 3
        c, s = np.cos(angles[..., k])[..., None], np.sin(angles[..., k])[..., None]
        ci, cj = r[..., :, i].copy(), r[..., :, j].copy()
        r[..., :, i] = c * ci + s * cj
        r[..., :, j] = c * cj - s * ci
    return r


def euler_angles(r: np.ndarray, order: str) -> np.ndarray:
    """Inverse of :func:`euler_rotations` for three distinct axes: angles ``(..., 3)`` radians of rotations
    ``(..., 3, 3)``, the middle one in ``[-pi/2, pi/2]`` (at gimbal lock the last is 0)."""
    i, j, k = ("XYZ".index(a) for a in order.upper())
    s = 1.0 if (j - i) % 3 == 1 else -1.0  # cyclic order (XYZ, YZX, ZXY) or not
    mid = np.arcsin(np.clip(s * r[..., i, k], -1.0, 1.0))
    lock = np.abs(s * r[..., i, k]) > 1.0 - 1e-12
    first = np.arctan2(-s * r[..., j, k], r[..., k, k])
    last = np.arctan2(-s * r[..., i, j], r[..., i, i])
    if lock.any():  # only first + last (or first - last) is defined: last = 0
        first = np.where(lock, np.arctan2(s * r[..., k, j], r[..., j, j]), first)
        last = np.where(lock, 0.0, last)
    return np.stack([first, mid, last], axis=-1)


def local_rotations(skeleton: Skeleton, channels: np.ndarray) -> np.ndarray:
    """Local rotation matrices ``(frames, joints, 3, 3)`` from channel values ``(frames, channels)``: the joints
    of one rotation order in one vectorised step."""
    frames = channels.shape[0]
    if (kern := _kernel()) is not None and np.asarray(channels).dtype == np.float64:
        out = np.empty((frames, skeleton.n_joints, 3, 3))
        scale, _, rot_cols, rot_axes, n_rot, turned, axis_t = _tables(skeleton)[:7]
        kern.local(np.ascontiguousarray(channels, dtype=np.float64), scale, rot_cols, rot_axes, n_rot, turned, axis_t,
                   out)
        return out
    out = np.broadcast_to(np.eye(3), (frames, skeleton.n_joints, 3, 3)).copy()
    scale = np.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0
    axis = skeleton.axis
    assert axis is not None
    by_order: dict[str, tuple[list[int], list[list[int]]]] = {}
    for j, (sl, chs, order) in enumerate(
        zip(skeleton.channel_slices(), skeleton.channels, skeleton.rotation_order, strict=True)
    ):
        if order:
            joints, cols = by_order.setdefault(order, ([], []))
            joints.append(j)
            cols.append([sl.start + chs.index(f"{a}rotation") for a in order])
    for order, (joints, cols) in by_order.items():
        at = np.array(cols)
        for a in range(0, frames, POSITION_CHUNK):  # a chunk of frames at a time: small temporaries, the same numbers
            out[a:a + POSITION_CHUNK, joints] = euler_rotations(channels[a:a + POSITION_CHUNK, at] * scale, order)
    turned = [j for j in range(skeleton.n_joints) if not np.array_equal(axis[j], np.eye(3))]
    if turned:  # ASF joint axes: the rotation is about the joint's own frame
        a = axis[turned]
        out[:, turned] = a @ out[:, turned] @ np.swapaxes(a, -1, -2)
    return out


def local_translations(skeleton: Skeleton, channels: np.ndarray) -> np.ndarray:
    """Local translations ``(frames, joints, 3)``: offsets, replaced by position channels where present."""
    frames = channels.shape[0]
    out = np.broadcast_to(skeleton.offsets, (frames, skeleton.n_joints, 3)).copy()
    for j, (sl, chs) in enumerate(zip(skeleton.channel_slices(), skeleton.channels, strict=True)):
        for k, c in enumerate(chs):
            if c.endswith("position"):
                out[:, j, "XYZ".index(c[0])] = channels[:, sl.start + k]
    return out


def forward_kinematics(skeleton: Skeleton, channels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global positions and rotations of a skeleton for every frame.

    Args:
        skeleton: the hierarchy.
        channels: ``(frames, channels)`` values in file units.

    Returns:
        positions ``(frames, joints + end_sites, 3)`` in file units (joints then end sites) and
        global rotations ``(frames, joints, 3, 3)``.
    """
    channels = np.asarray(channels, dtype=np.float64)
    if (kern := _kernel()) is not None:
        pos = np.empty((channels.shape[0], skeleton.n_points, 3))
        rot = np.empty((channels.shape[0], skeleton.n_joints, 3, 3))
        kern.forward(np.ascontiguousarray(channels), *_tables(skeleton), pos, rot, True)
        return pos, rot
    rot = local_rotations(skeleton, channels)
    trans = local_translations(skeleton, channels)
    return chain(skeleton, rot, trans)


def forward_positions(skeleton: Skeleton, channels: np.ndarray, chunk: int = POSITION_CHUNK) -> np.ndarray:
    """The positions of :func:`forward_kinematics` alone, ``(frames, joints + end_sites, 3)`` in file units,
    made ``chunk`` frames at a time (every frame is its own product chain, so the values are the same to the
    bit): the rotations of a few frames live at once, not ``(frames, joints, 3, 3)`` of every kind (peak
    memory)."""
    channels = np.asarray(channels, dtype=np.float64)
    frames = channels.shape[0]
    if (kern := _kernel()) is not None:  # a frame at a time: 9 floats of rotations per joint, whatever the length
        pos = np.empty((frames, skeleton.n_points, 3))
        kern.forward(np.ascontiguousarray(channels), *_tables(skeleton), pos,
                     np.empty((1, skeleton.n_joints, 3, 3)), False)
        return pos
    if frames <= chunk:
        return forward_kinematics(skeleton, channels)[0]
    out = np.empty((frames, skeleton.n_points, 3))
    for a in range(0, frames, chunk):
        out[a:a + chunk] = forward_kinematics(skeleton, channels[a:a + chunk])[0]
    return out


def chain(skeleton: Skeleton, rot: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compose local rotations ``(F, J, 3, 3)`` and translations ``(F, J, 3)`` down the tree."""
    frames, n = rot.shape[0], skeleton.n_joints
    g_rot = np.empty_like(rot)
    pos = np.empty((frames, skeleton.n_points, 3))
    for j in range(n):
        p = skeleton.parents[j]
        if p < 0:
            g_rot[:, j] = rot[:, j]
            pos[:, j] = trans[:, j]
        else:
            g_rot[:, j] = g_rot[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fab,fb->fa", g_rot[:, p], trans[:, j])
    for e, (j, off, _) in enumerate(skeleton.end_sites):
        pos[:, n + e] = pos[:, j] + g_rot[:, j] @ np.asarray(off)
    return pos, g_rot


def _kernel() -> Any:
    """The compiled forward kinematics (:mod:`.fkkernels`) from the extension built ahead of time, or None (no
    extension, or numba turned off: NumPy's path, the same numbers)."""
    return aot.kernels("fk") if _jit.enabled() else None


TABLES_KEPT = 16  # skeletons whose tables are kept (a rate search asks for one skeleton's a hundred times)
_TABLES: dict[tuple[Any, ...], tuple[Any, ...]] = {}


def content_key(skeleton: Skeleton) -> tuple[Any, ...]:
    """What a skeleton's kinematics are made of, as a key (a skeleton changed in place is another key)."""
    return (skeleton.angle_unit, np.asarray(skeleton.parents).tobytes(), np.asarray(skeleton.offsets).tobytes(),
            np.asarray(skeleton.axis).tobytes(), tuple(map(tuple, skeleton.channels)), tuple(skeleton.rotation_order),
            tuple((int(j), np.asarray(o).tobytes()) for j, o, _ in skeleton.end_sites))


def _tables(skeleton: Skeleton) -> tuple[Any, ...]:
    """:func:`.fkkernels.forward`'s arguments after the channels, from ``scale`` to ``end_off``: made once per
    skeleton, kept by what they are made of (a skeleton changed in place is another key; never written to)."""
    assert skeleton.axis is not None
    key = content_key(skeleton)
    made = _TABLES.pop(key, None)
    if made is None:
        made = _make_tables(skeleton)
    _TABLES[key] = made  # the most recent last
    while len(_TABLES) > TABLES_KEPT:
        del _TABLES[next(iter(_TABLES))]
    return made


def _make_tables(skeleton: Skeleton) -> tuple[Any, ...]:
    """:func:`_tables`, made."""
    n = skeleton.n_joints
    rot_cols, rot_axes = np.zeros((n, 3), dtype=np.int64), np.zeros((n, 3), dtype=np.int64)
    n_rot = np.zeros(n, dtype=np.int64)
    pos_cols = np.full((n, 3), -1, dtype=np.int64)
    for j, (sl, chs, order) in enumerate(
        zip(skeleton.channel_slices(), skeleton.channels, skeleton.rotation_order, strict=True)
    ):
        n_rot[j] = len(order)
        for k, a in enumerate(order):
            rot_cols[j, k] = sl.start + chs.index(f"{a}rotation")
            rot_axes[j, k] = "XYZ".index(a.upper())
        for k, c in enumerate(chs):
            if c.endswith("position"):
                pos_cols[j, "XYZ".index(c[0])] = sl.start + k
    assert skeleton.axis is not None
    axis = np.array(skeleton.axis, dtype=np.float64, order="C")  # copies: kept, they must not follow the skeleton
    turned = np.array([not np.array_equal(axis[j], np.eye(3)) for j in range(n)], dtype=np.bool_)
    ends = skeleton.end_sites
    return (np.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0, np.array(skeleton.parents, dtype=np.int64),
            rot_cols, rot_axes, n_rot, turned, axis, pos_cols, np.array(skeleton.offsets, dtype=np.float64, order="C"),
            np.array([j for j, _, _ in ends], dtype=np.int64),
            np.array([o for _, o, _ in ends], dtype=np.float64).reshape(len(ends), 3))
