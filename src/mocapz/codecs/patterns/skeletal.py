"""Skeletal data as pattern-codec values: the root joint's channels and each joint's local rotation.

A joint with three rotation channels becomes its local rotation vector (axis * angle, radians); a joint
with one or two rotation channels keeps its (unwrapped) angles in radians. Each is multiplied by the
joint's *lever*, the rest-pose distance to its farthest descendant point, so that values are lengths (a
rotation error of ``e`` radians moves the descendants by about ``e * lever``) and one length threshold
serves every joint. Position channels of non-root joints are kept as constants when they never change,
else coded as values of their joint. The root joint's channels (position and orientation) are coded
absolutely per frame, like the paper's root marker. The skeleton itself is never changed.
"""

from __future__ import annotations

import struct

import numpy as np

from mocapz.codecs.gaps import pack_mask, unpack_mask
from mocapz.codecs.patterns.quantise import decode_trajectory
from mocapz.codecs.patterns.rotvec import continuous_rotvec, euler_rotvec, rotvec_euler
from mocapz.errors import FormatError
from mocapz.format.entropy import read_uvarint, write_uvarint
from mocapz.model.skeleton import Skeleton

HEAD_TO_HEIGHT = 0.11  # ADDH / body height of the CMU subjects (01_01.c3d: 194 mm / ~1.75 m)


def rest_points(skeleton: Skeleton) -> np.ndarray:
    """Rest-pose positions of joints then end sites ``(points, 3)`` (identity rotations)."""
    n = skeleton.n_joints
    pos = np.zeros((skeleton.n_points, 3))
    for j in range(n):
        p = skeleton.parents[j]
        pos[j] = skeleton.offsets[j] + (pos[p] if p >= 0 else 0.0)
    for e, (j, off, _) in enumerate(skeleton.end_sites):
        pos[n + e] = pos[j] + off
    return pos


def skeleton_addh(skeleton: Skeleton) -> float:
    """Length scale for skeletons: the head-marker diagonal of a body of this size (11 % of its extent)."""
    pts = rest_points(skeleton)
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) > 1 else 1.0
    return HEAD_TO_HEIGHT * max(extent, 1e-9)


def levers(skeleton: Skeleton) -> np.ndarray:
    """``(joints,)`` rest-pose distance from each joint to its farthest descendant point (floored)."""
    pts = rest_points(skeleton)
    parents = skeleton.point_parents
    lev = np.zeros(skeleton.n_joints)
    for p in range(len(pts) - 1, 0, -1):
        a = parents[p]
        while a >= 0:
            lev[a] = max(lev[a], float(np.linalg.norm(pts[p] - pts[a])))
            a = parents[a]
    floor = 0.2 * skeleton_addh(skeleton)
    return np.maximum(lev, floor)


def varying_positions(skeleton: Skeleton, channels_list: list[np.ndarray]) -> np.ndarray:
    """``(channels,)`` True for non-root position channels that change within some clip."""
    root = int(np.flatnonzero(skeleton.parents < 0)[0])
    names = [c for chs in skeleton.channels for c in chs]
    out = np.zeros(len(names), dtype=bool)
    root_cols = set(range(skeleton.channel_slices()[root].start, skeleton.channel_slices()[root].stop))
    for c, name in enumerate(names):
        if name.endswith("position") and c not in root_cols:
            out[c] = any(len(ch) and np.ptp(ch[:, c]) > 0 for ch in channels_list)
    return out


class SkeletalFeatures:
    """Conversion between a skeleton's channels and the codec's per-joint values."""

    def __init__(self, skeleton: Skeleton, addh: float, varying: np.ndarray | None = None) -> None:
        self.sk = skeleton
        self.addh = addh
        self.root = int(np.flatnonzero(skeleton.parents < 0)[0])
        slices = skeleton.channel_slices()
        self.root_columns = np.arange(slices[self.root].start, slices[self.root].stop)
        self.varying = np.zeros(skeleton.n_channels, dtype=bool) if varying is None else varying
        self.lever = levers(skeleton)
        self.scale = np.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0
        self.rot_cols: list[list[int]] = []
        self.pos_cols: list[list[int]] = []
        for j, (sl, chs, order) in enumerate(zip(slices, skeleton.channels, skeleton.rotation_order, strict=True)):
            self.rot_cols.append([sl.start + chs.index(f"{a}rotation") for a in order] if order else [])
            self.pos_cols.append([sl.start + k for k, c in enumerate(chs)
                                  if c.endswith("position") and self.varying[sl.start + k] and j != self.root])

    # ------------------------------------------------------------ root and constants
    def root_values(self, channels: np.ndarray, pos_step: float) -> tuple[np.ndarray, np.ndarray]:
        """Root channels ``(T, C)`` (angles unwrapped) and their quantisation steps ``(C,)``."""
        vals = channels[:, self.root_columns].copy()
        names = self.sk.channels[self.root]
        radius = self.addh / HEAD_TO_HEIGHT / 2.0
        steps = np.empty(len(names))
        for k, name in enumerate(names):
            if name.endswith("rotation"):
                vals[:, k] = np.unwrap(vals[:, k] * self.scale) / self.scale
                steps[k] = pos_step / radius / self.scale
            else:
                steps[k] = pos_step
        return vals, steps

    def decode_root(self, data: bytes, frames: int) -> np.ndarray:
        return decode_trajectory(data, (frames, len(self.root_columns)))[0]

    def constant_columns(self, channels: np.ndarray) -> bytes:
        """Exact values of the channels that are neither root, rotation nor varying positions."""
        cols = self.constant_index()
        if (cols.size == 0 and not self.varying.any()) or channels.shape[0] == 0:
            return b""
        vals = channels[0, cols]
        return write_uvarint(cols.size) + struct.pack(f"<{cols.size}d", *vals) + \
            pack_mask(self.varying)

    def constant_index(self) -> np.ndarray:
        coded = np.zeros(self.sk.n_channels, dtype=bool)
        coded[self.root_columns] = True
        for rc, pc in zip(self.rot_cols, self.pos_cols, strict=True):
            coded[rc] = True
            coded[pc] = True
        return np.flatnonzero(~coded)

    def apply_constants(self, out: np.ndarray, data: bytes) -> np.ndarray:
        cols = self.constant_index()
        if cols.size and data:
            n, pos = read_uvarint(data, 0)
            if n != cols.size or pos + 8 * n > len(data):
                raise FormatError(None, "corrupted constant channels")
            out[:, cols] = np.asarray(struct.unpack(f"<{n}d", data[pos : pos + 8 * n]))
        return out

    @staticmethod
    def varying_from(data: bytes, n_channels: int) -> np.ndarray:
        """The varying-position mask stored at the end of a constants section."""
        if not data:
            return np.zeros(n_channels, dtype=bool)
        n, pos = read_uvarint(data, 0)
        return unpack_mask(data[pos + 8 * n :], (n_channels,))

    # ------------------------------------------------------------ node values
    def node_features(self, channels: np.ndarray, members: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Values ``(T, D)`` of a node's joints and the member index of each column ``(D,)``."""
        cols, owner = [], []
        for i, j in enumerate(members):
            for block in self._joint_values(channels, j):
                cols.append(block)
                owner += [i] * block.shape[1]
        t = channels.shape[0]
        x = np.concatenate(cols, axis=1) if cols else np.zeros((t, 0))
        return x, np.asarray(owner, dtype=np.int64)

    def _joint_values(self, channels: np.ndarray, j: int) -> list[np.ndarray]:
        out = []
        rc = self.rot_cols[j]
        if len(rc) == 3:
            rv = euler_rotvec(self.sk.rotation_order[j], channels[:, rc] * self.scale)
            out.append(continuous_rotvec(rv) * self.lever[j])
        elif rc:
            out.append(np.unwrap(channels[:, rc] * self.scale, axis=0) * self.lever[j])
        if self.pos_cols[j]:
            out.append(channels[:, self.pos_cols[j]])
        return out

    def width(self, members: list[int]) -> int:
        """Number of values ``D`` of a node with these joints (:meth:`node_features`)."""
        return sum((3 if len(self.rot_cols[j]) == 3 else len(self.rot_cols[j])) + len(self.pos_cols[j])
                   for j in members)

    def put_node(self, out: np.ndarray, members: list[int], x: np.ndarray) -> None:
        """Write decoded node values ``(T, D)`` back into channel columns of ``out`` ``(T, channels)``."""
        c = 0
        for j in members:
            rc = self.rot_cols[j]
            if len(rc) == 3:
                ang = rotvec_euler(self.sk.rotation_order[j], x[:, c : c + 3] / self.lever[j])
                out[:, rc] = np.unwrap(ang, axis=0) / self.scale
                c += 3
            elif rc:
                out[:, rc] = x[:, c : c + len(rc)] / self.lever[j] / self.scale
                c += len(rc)
            pc = self.pos_cols[j]
            if pc:
                out[:, pc] = x[:, c : c + len(pc)]
                c += len(pc)
