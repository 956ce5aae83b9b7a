"""Poses written back as channel values: Euler angles of the local rotations (in the skeleton's angle
unit, unwrapped over time) and the position channels."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from mocapz.codecs.pga.joints import position_columns
from mocapz.model.skeleton import Skeleton


def euler_angles(r: np.ndarray, order: str) -> np.ndarray:
    """Angles ``(..., 3)`` (radians) of the intrinsic Euler sequence ``order`` (three distinct axes, e.g.
    ``"ZXY"``: ``R = Rz(a) @ Rx(b) @ Ry(c)``) of rotations ``(..., 3, 3)``, by the closed form (the middle
    angle in [-pi/2, pi/2]; at gimbal lock, ``cos b`` below 1e-9, the third angle is 0)."""
    i, j, k = ("XYZ".index(a) for a in order)
    s = 1.0 if (j - i) % 3 == 1 else -1.0  # +1 for the cyclic orders XYZ, YZX, ZXY
    cb = np.hypot(r[..., i, i], r[..., i, j])
    out = np.empty((*r.shape[:-2], 3))
    out[..., 1] = np.arctan2(s * r[..., i, k], cb)
    out[..., 0] = np.arctan2(-s * r[..., j, k], r[..., k, k])
    out[..., 2] = np.arctan2(-s * r[..., i, j], r[..., i, i])
    lock = cb < 1e-9
    if lock.any():
        out[lock, 0] = np.arctan2(s * r[..., k, j][lock], r[..., j, j][lock])
        out[lock, 2] = 0.0
    return out


def channels_from_rotations(skeleton: Skeleton, local_rot: np.ndarray, out: np.ndarray,
                            joints: np.ndarray | None = None) -> None:
    """Write Euler channels (the skeleton's angle unit) of local rotations ``(F, J, 3, 3)`` into ``out``
    ``(F, C)`` in place, for the given joints (all when None). Joints of the same Euler sequence are
    converted together."""
    deg = skeleton.angle_unit == "deg"
    axis = skeleton.axis
    assert axis is not None
    slices = skeleton.channel_slices()
    todo = range(skeleton.n_joints) if joints is None else joints
    by_seq: dict[str, list[int]] = {}
    for j in todo:
        order = skeleton.rotation_order[j]
        if order:
            by_seq.setdefault((order + "".join(a for a in "XYZ" if a not in order)).upper(), []).append(int(j))
    for seq, group in by_seq.items():
        r = local_rot[:, group]
        turned = [g for g, j in enumerate(group) if not np.array_equal(axis[j], np.eye(3))]
        if turned:
            r = r.copy()
            ax = axis[[group[g] for g in turned]]
            r[:, turned] = np.swapaxes(ax, -1, -2)[None] @ r[:, turned] @ ax[None]
        if len(set(seq)) == 3:
            ang = euler_angles(r, seq)
            if deg:
                ang = np.rad2deg(ang)
        else:  # a repeated axis (proper Euler angles): scipy's conversion
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                from scipy.spatial.transform import Rotation  # noqa: I001 (on use: scipy loads slowly)
                ang = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_euler(seq, degrees=deg).reshape(*r.shape[:2], 3)
        for g, j in enumerate(group):
            order = skeleton.rotation_order[j]
            chs = skeleton.channels[j]
            for i, a in enumerate(order):
                out[:, slices[j].start + chs.index(f"{a}rotation")] = ang[:, g, i]


ROWS = 512  # rows per chunk of the in-place passes (their temporaries stay small: cached, not fresh pages)


def unwrap_columns(out: np.ndarray, cols: np.ndarray, period: float) -> None:
    """``np.unwrap(out[:, cols], period=period, axis=0)`` in place (``cols`` a boolean mask ``(C,)`` of ``out``
    ``(F, C)``), quicker when few columns jump by half a turn or more: only those are unwrapped, the others get
    the 0.0 np.unwrap adds; the tests and additions by chunks of :data:`ROWS` rows."""
    smooth = cols.copy()  # NaN counts as a jump, as in np.unwrap
    for a in range(0, max(out.shape[0] - 1, 0), ROWS):
        smooth &= (np.abs(np.diff(out[a:a + ROWS + 1], axis=0)) < period / 2).all(axis=0)
    jumps = cols & ~smooth
    for a in range(0, out.shape[0], ROWS):
        np.add(out[a:a + ROWS], 0.0, out=out[a:a + ROWS], where=smooth)
    if jumps.any():
        out[:, jumps] = np.unwrap(out[:, jumps], period=period, axis=0)


Unwrapper = Callable[[np.ndarray, np.ndarray, float], None]


def finish_channels(skeleton: Skeleton, out: np.ndarray, root_pos: np.ndarray, other: np.ndarray,
                    unwrap: Unwrapper | None = None) -> np.ndarray:
    """Channel values ``(F, C)`` from the Euler angles in ``out`` (:func:`channels_from_rotations`), in place:
    the angles unwrapped along time (a full turn is 360 degrees or 2 pi radians, by the skeleton's angle unit) by
    ``unwrap(out, rotation columns, period)`` (:func:`unwrap_columns` by default, or the file's stored turns,
    :mod:`.turns`), the root position ``(F, 3)`` and the non-root position channels ``(F, p)`` (file units) added.
    Always finite (NaN and inf replaced)."""
    root_cols, other_cols = position_columns(skeleton)
    rot_cols = skeleton.rotation_columns()
    period = 360.0 if skeleton.angle_unit == "deg" else 2 * np.pi
    (unwrap or unwrap_columns)(out, rot_cols, period)
    labels = skeleton.channel_labels()
    for c in root_cols:
        out[:, c] = root_pos[:, "XYZ".index(labels[c].split(".")[-1][0])]
    out[:, other_cols] = other
    if all(np.isfinite(out[a:a + ROWS]).all() for a in range(0, out.shape[0], ROWS)):  # np.nan_to_num's passes
        return out  # only when they change something (same values)
    return np.nan_to_num(out)


def euler_tables(skeleton: Skeleton, joints: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """What the compiled :func:`~mocapz.codecs.pga.ikjit` ``euler_channels`` kernel needs to write the Euler
    channels of the root and of the model's ``joints``: per rotating joint its source (-1: root, else model
    slot), axes ``ijk``, parity, output columns, axis frame; None when a joint has a repeated axis (proper
    Euler angles: the NumPy path) or a rotating joint is neither the root nor a model joint. Kept per channel
    layout and joints (every decode and seek of a clip asks again; the kernel only reads them)."""
    axis = skeleton.axis
    assert axis is not None
    key = (tuple(skeleton.channels), tuple(skeleton.rotation_order), np.asarray(axis, np.float64).tobytes(),
           np.asarray(joints, np.int64).tobytes())
    if key not in _TABLES:
        if len(_TABLES) >= 64:
            _TABLES.clear()
        _TABLES[key] = _euler_tables(skeleton, joints)
    return _TABLES[key]


_TABLES: dict[tuple, tuple[np.ndarray, ...] | None] = {}  # channel layout and joints -> euler_tables


def _euler_tables(skeleton: Skeleton, joints: np.ndarray) -> tuple[np.ndarray, ...] | None:
    axis = skeleton.axis
    assert axis is not None
    slot = {int(j): i for i, j in enumerate(joints)}
    slices = skeleton.channel_slices()
    rows = []
    for j in range(skeleton.n_joints):
        order = skeleton.rotation_order[j]
        if not order:
            continue
        seq = (order + "".join(a for a in "XYZ" if a not in order)).upper()
        if len(set(seq)) != 3 or (j != 0 and j not in slot):
            return None
        i, jj, k = ("XYZ".index(a) for a in seq)
        chs = skeleton.channels[j]
        cols = [slices[j].start + chs.index(f"{a}rotation") for a in order] + [-1] * (3 - len(order))
        turned = not np.array_equal(axis[j], np.eye(3))
        rows.append((-1 if j == 0 else slot[j], (i, jj, k), 1.0 if (jj - i) % 3 == 1 else -1.0, cols,
                     np.asarray(axis[j], dtype=np.float64), turned))
    if not rows:
        return None
    return (np.array([r[0] for r in rows], dtype=np.int64), np.array([r[1] for r in rows], dtype=np.int64),
            np.array([r[2] for r in rows]), np.array([r[3] for r in rows], dtype=np.int64),
            np.ascontiguousarray(np.stack([r[4] for r in rows])), np.array([r[5] for r in rows], dtype=np.bool_))
