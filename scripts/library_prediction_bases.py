"""Bases for ``scripts/library_prediction.py``: clip B's motion predicted from another clip A of the same subject.

Every array here is in the clip's file units: root positions in the BVH's length unit, rotations in degrees
(the channel values as loaded), ``(frames, columns)`` for channel values. Frames are the clip's own (CMU clips:
120 fps, the first frame the added T-pose). A's values are used as they are in its file, as if decoded exactly.

- Features for matching (:class:`ClipData`): per joint its 3x3 local rotation matrix times the joint's lever
  (the pattern codec's, :func:`mocapz.codecs.patterns.skeletal.levers`), the root's heading (yaw about the
  vertical Y axis) taken out, plus the root height. The squared distance of two frames is then about
  2 * sum (lever * angle)^2, a position-like error.
- Alignment (:func:`align`), a frame of A for every frame of B: ``win60`` / ``win120`` (per window of B of 60
  or 120 frames the offset into A and the time scale of :data:`SPEEDS` nearest on the features), ``dtw``
  (subsequence dynamic time warping, A stepping 0, 1 or 2 frames per frame of B) or ``oracle`` (each frame
  of B its nearest frame of A, no constraint in time).
- The base (:func:`assemble`): A's channels at the aligned frames; the root rotation turned by a coded yaw
  (``turn``) or 0 (``zero``); the root position 0 (``zero``) or A's trajectory turned by the yaw and moved by
  a coded offset per window (``rigid``); rotations unwrapped in time, smoothed by a Gaussian of ``sigma``
  frames, then moved by whole turns towards B.
- Side information (:func:`side_bytes`) is estimated, not coded.

Coding (:func:`code`) is mocapz's correction layer as the quant codec runs it on its zero base; :func:`sanity`
compares the two, :func:`body_parts` sets body parts of a base to 0 where that codes smaller. A coding's record
is a dict (clip ``B``, partner ``A``, configuration, ``bytes``, ``side`` bytes, ``met``); :func:`cost`,
:func:`effects` and :func:`n_missed` read them.
"""

from __future__ import annotations

import math
import statistics
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_filter1d

import mocapz
from mocapz.codecs.correction.fit import Clip
from mocapz.codecs.correction.search import Base, search_bases
from mocapz.codecs.patterns.skeletal import levers
from mocapz.codecs.target import Target
from mocapz.format.container import Container
from mocapz.model.kinematics import axis_rotations, euler_angles, local_rotations
from mocapz.model.motion import Motion
from mocapz.model.skeleton import Skeleton

SPEEDS = (0.8, 0.9, 1.0, 1.12, 1.25)  #: time scales of A tried per window
YAW_BITS = 8  #: a yaw quantised to 360/256 degrees
XZ_STEP = 0.05  #: root offset step, file units (CMU: about 0.28 cm)
XZ_BYTES = 4  #: per window of a rigid root: x and z offsets, 2 bytes each
DTW_PENALTY = 0.05  #: extra cost of A's steps 0 and 2, a share of the median frame distance
SIDE_WINDOW = 60  #: frames per yaw (and rigid offset) for dtw and oracle
HEADER_BYTES = 4  #: every matched base: method, partner, counts
CHOICE_BYTES = 1  #: the configuration chosen among about 100 (and a body-part mask, when one is coded)

#: Body parts of the CMU skeleton: joints (all their channels), or the root's position or rotation alone.
PARTS: dict[str, tuple[str, ...]] = {
    "rootpos": ("Hips:pos",), "rootrot": ("Hips:rot",),
    "legL": ("LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"),
    "legR": ("RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"),
    "spine": ("LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head"),
    "armL": ("LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb"),
    "armR": ("RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1",
             "RThumb"),
}


class ClipData:
    """One clip: its motion, values ``(frames, columns)`` (float64), column groups and matching features.

    Attributes:
        heading: ``(frames,)`` the root's heading about Y, radians.
        root_rot: ``(frames, 3, 3)`` the root's local rotation.
        feat: ``(frames, 9 * joints + 1)`` the features (heading taken out of the root, root height last).
    """

    def __init__(self, name: str, motion: Motion) -> None:
        self.name = name
        self.motion = motion
        sk = self.sk = motion.skeleton
        self.values = np.asarray(motion.values, dtype=np.float64)
        self.n = self.values.shape[0]
        self.rot = sk.rotation_columns()
        start, chans = sk.channel_slices()[0].start, sk.channels[0]
        self.pos_cols = [start + chans.index(f"{a}position") for a in "XYZ"]
        self.root_order = sk.rotation_order[0]
        self.root_rot_cols = [start + chans.index(f"{a}rotation") for a in self.root_order]
        r = local_rotations(sk, self.values)  # (frames, joints, 3, 3)
        self.root_rot = r[:, 0].copy()
        forward = self.root_rot[:, :, 2]  # the root's z axis in the world
        self.heading = np.arctan2(forward[:, 0], forward[:, 2])
        r[:, 0] = axis_rotations(-self.heading, 1) @ self.root_rot
        w = levers(sk)
        feat = (r.reshape(self.n, sk.n_joints, 9) * w[None, :, None]).reshape(self.n, -1)
        self.feat = np.concatenate([feat, self.values[:, self.pos_cols[1:2]]], axis=1)


def same_skeleton(a: Skeleton, b: Skeleton) -> bool:
    """Joint names, channels, rest offsets and end sites all equal."""
    return (a.names == b.names and a.channels == b.channels and np.array_equal(a.offsets, b.offsets)
            and len(a.end_sites) == len(b.end_sites)
            and all(x[0] == y[0] and np.array_equal(x[1], y[1]) for x, y in zip(a.end_sites, b.end_sites, strict=True)))


def distances(b: ClipData, a: ClipData) -> np.ndarray:
    """``(frames of B, frames of A)``: squared feature distance of every pair of frames."""
    fb, fa = b.feat, a.feat
    c = (fb * fb).sum(1)[:, None] + (fa * fa).sum(1)[None, :] - 2.0 * fb @ fa.T
    return np.maximum(c, 0.0)


@dataclass
class Alignment:
    """A frame of A for each frame of B.

    Attributes:
        method: ``win60``, ``win120``, ``dtw`` or ``oracle``.
        frames: ``(frames of B,)`` the frame of A.
        window: ``(frames of B,)`` window id (alignment windows; :data:`SIDE_WINDOW` frames for dtw, oracle).
        yaw_group: ``(frames of B,)`` id of the yaw each frame takes (per window; per frame for the oracle).
        windows: the number of windows.
        path_bits: the dtw path's order-0 step entropy, bits (0 otherwise).
    """

    method: str
    frames: np.ndarray
    window: np.ndarray
    yaw_group: np.ndarray
    windows: int
    path_bits: float = 0.0


def window_align(c: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per window of ``size`` frames of B the offset o into A and speed s of :data:`SPEEDS` minimising
    ``sum_k c[t0 + k, o + round(s k)]``; returns the frame of A and the window id per frame of B."""
    n, m = c.shape
    a = np.zeros(n, dtype=np.int64)
    wid = np.zeros(n, dtype=np.int64)
    for w, t0 in enumerate(range(0, n, size)):
        k = np.arange(min(size, n - t0))
        best: tuple[float, int, np.ndarray | None] = (math.inf, 0, None)
        for s in SPEEDS:
            steps = np.round(s * k).astype(np.int64)
            span = int(steps[-1])
            if span >= m:
                continue
            cost = np.zeros(m - span)
            for kk, off in zip(k, steps, strict=True):
                cost += c[t0 + kk, off:off + m - span]
            o = int(np.argmin(cost))
            if cost[o] < best[0]:
                best = (float(cost[o]), o, steps)
        _, o, steps = best
        if steps is None:  # A shorter than the window at every speed: A from its start, its last frame held
            steps, o = np.minimum(k, m - 1), 0
        a[t0:t0 + k.size] = o + steps
        wid[t0:t0 + k.size] = w
    return a, wid


def dtw_align(c: np.ndarray) -> tuple[np.ndarray, float]:
    """Subsequence DTW: frame i of B takes frame a(i) of A, a(i) - a(i-1) in {0, 1, 2}, start and end free.
    Returns a ``(frames of B,)`` and the order-0 entropy of the steps, bits (the path's side information)."""
    n, m = c.shape
    pen = DTW_PENALTY * float(np.median(c))
    acc = c[0].copy()
    choice = np.zeros((n, m), dtype=np.int8)
    for i in range(1, n):
        c1 = np.full(m, np.inf)
        c1[1:] = acc[:-1]
        c2 = np.full(m, np.inf)
        c2[2:] = acc[:-2] + pen
        st = np.stack([acc + pen, c1, c2])
        ch = np.argmin(st, axis=0)
        choice[i] = ch
        acc = c[i] + st[ch, np.arange(m)]
    j = int(np.argmin(acc))
    a = np.zeros(n, dtype=np.int64)
    for i in range(n - 1, -1, -1):
        a[i] = j
        if i:
            j -= int(choice[i, j])
    _, cnt = np.unique(np.diff(a), return_counts=True)
    bits = float(-(cnt * np.log2(cnt / cnt.sum())).sum()) if cnt.size else 0.0
    return a, bits


def align(c: np.ndarray, method: str) -> Alignment:
    """The alignment of B to A by ``method`` from their frame distances ``c`` (:func:`distances`)."""
    n = c.shape[0]
    if method.startswith("win"):
        a, wid = window_align(c, int(method[3:]))
        return Alignment(method, a, wid, wid, int(wid.max()) + 1)
    wid = np.arange(n) // SIDE_WINDOW
    windows = int(wid.max()) + 1
    if method == "dtw":
        a, bits = dtw_align(c)
        return Alignment(method, a, wid, wid, windows, bits)
    if method == "oracle":
        return Alignment(method, np.argmin(c, axis=1), wid, np.arange(n), windows)
    raise ValueError(f"unknown alignment {method!r}")


def _circular_mean(x: np.ndarray) -> float:
    return float(np.arctan2(np.sin(x).mean(), np.cos(x).mean()))


def _quantised_yaw(t: float) -> float:
    q = 2 * math.pi / (1 << YAW_BITS)
    return round(t / q) * q


def assemble(b: ClipData, a: ClipData, al: Alignment, rootrot: str, rootpos: str, sigma: float) -> np.ndarray:
    """The base ``(frames of B, columns)`` for B from A's frames ``al.frames``. The encoder-side choices (the
    yaw per group, the rigid offsets per window) look at B: they are side information."""
    base = a.values[al.frames].copy()
    dpsi = b.heading - a.heading[al.frames]
    theta = np.array([_quantised_yaw(_circular_mean(dpsi[al.yaw_group == g]))
                      for g in range(int(al.yaw_group.max()) + 1)])
    th = theta[al.yaw_group]
    rc, pc = b.root_rot_cols, b.pos_cols
    if rootrot == "turn":
        base[:, rc] = np.degrees(euler_angles(axis_rotations(th, 1) @ a.root_rot[al.frames], b.root_order))
    else:
        base[:, rc] = 0.0
    if rootpos == "zero":
        base[:, pc] = 0.0
    else:
        p = a.values[al.frames][:, pc]
        cos, sin = np.cos(th), np.sin(th)
        x = cos * p[:, 0] + sin * p[:, 2]  # Ry(th) applied to (x, z)
        z = -sin * p[:, 0] + cos * p[:, 2]
        bx, bz = b.values[:, pc[0]], b.values[:, pc[2]]
        for g in range(al.windows):
            sel = al.window == g
            x[sel] += round(float((bx[sel] - x[sel]).mean()) / XZ_STEP) * XZ_STEP
            z[sel] += round(float((bz[sel] - z[sel]).mean()) / XZ_STEP) * XZ_STEP
        base[:, pc[0]], base[:, pc[1]], base[:, pc[2]] = x, p[:, 1], z
    base[:, b.rot] = np.degrees(np.unwrap(np.radians(base[:, b.rot]), axis=0))
    if sigma > 0:
        base = gaussian_filter1d(base, sigma, axis=0, mode="nearest")
    turns = np.round((b.values[:, b.rot] - base[:, b.rot]).mean(0) / 360.0)
    base[:, b.rot] += 360.0 * turns  # whole turns per channel towards B (the coder wraps residual angles)
    return base


def side_bytes(al: Alignment, frames_a: int, rootrot: str, rootpos: str) -> float:
    """Estimated side information of a matched base, bytes: per window log2(frames of A) bits for the offset
    and log2(5) for the speed (windows), the start and the path's step entropy (dtw), or log2(frames of A)
    per frame (oracle); 8 bits per yaw and 32 per rigid offset; :data:`HEADER_BYTES` + :data:`CHOICE_BYTES`."""
    lg = math.log2(max(frames_a, 2))
    yaw = YAW_BITS if rootrot == "turn" or rootpos == "rigid" else 0
    xz = 8 * XZ_BYTES if rootpos == "rigid" else 0
    if al.method.startswith("win"):
        bits = al.windows * (lg + math.log2(len(SPEEDS)) + yaw + xz)
    elif al.method == "dtw":
        bits = lg + al.path_bits + al.windows * (yaw + xz)
    else:
        bits = al.frames.size * (lg + yaw) + al.windows * xz
    return bits / 8.0 + HEADER_BYTES + CHOICE_BYTES


def part_columns(sk: Skeleton) -> dict[str, np.ndarray]:
    """The columns of each body part of :data:`PARTS` (joints the skeleton lacks left out)."""
    out = {}
    slices = sk.channel_slices()
    for part, joints in PARTS.items():
        cols = []
        for spec in joints:
            name, _, kind = spec.partition(":")
            if name not in sk.names:
                continue
            j = sk.index(name)
            cols += [slices[j].start + k for k, ch in enumerate(sk.channels[j])
                     if not kind or (kind == "pos") == ch.endswith("position")]
        out[part] = np.array(cols, dtype=np.int64)
    return out


def own_smoothed(b: ClipData, sigma: float) -> np.ndarray:
    """Diagnostic base ``(frames, columns)``, not realisable: B's own values, rotations unwrapped, smoothed in
    time by a Gaussian of ``sigma`` frames."""
    v = b.values.copy()
    v[:, b.rot] = np.degrees(np.unwrap(np.radians(v[:, b.rot]), axis=0))
    return gaussian_filter1d(v, sigma, axis=0, mode="nearest") if sigma > 0 else v


def wrapped_share(b: ClipData, base: np.ndarray) -> float:
    """The share of rotation residual samples (B minus base, wrapped to +-180 degrees) beyond 90 degrees."""
    r = (b.values[:, b.rot] - base[:, b.rot] + 180.0) % 360.0 - 180.0
    return float((np.abs(r) > 90).mean())


def code(clip: Clip, target: Target, base: np.ndarray) -> tuple[int, bool, float]:
    """The correction of ``clip`` on ``base`` ``(frames, columns)``: its sections' bytes, whether it meets the
    target, its max error (file units)."""
    _, cor = search_bases(clip, [Base(base, 0)], [0], target, effort="fast")
    return sum(len(v) for v in cor.sections.values()), bool(target.met(cor.errors)), float(cor.errors.max_error)


def body_parts(clip: Clip, target: Target, b: ClipData, rec: dict[str, Any], base: np.ndarray) -> list[dict[str, Any]]:
    """Greedy, part by part of :data:`PARTS`: the part's columns set to 0 in the base,
    kept at 0 when that codes smaller (and meets the target). One record per trial; ``parts`` names the parts
    that keep the matched base."""
    cols = part_columns(b.sk)
    on = dict.fromkeys(cols, True)
    cur, out = rec["bytes"], []
    for p in cols:
        trial = base.copy()
        for q in cols:
            if not on[q] or q == p:
                trial[:, cols[q]] = 0.0
        nb, met, err = code(clip, target, trial)
        kept = "+".join(q for q in cols if on[q] and q != p)
        out.append({**rec, "parts": kept, "bytes": nb, "side": rec["side"] + 1, "met": met, "max_error": err,
                    "wrapped": wrapped_share(b, trial)})
        if met and nb < cur:
            cur, on[p] = nb, False
    return out


def sanity(d: ClipData, clip: Clip, target: Target) -> dict[str, Any]:
    """The clip's single quant file against its correction on a zero base: bytes, and the ``c.*`` sections
    byte for byte (the file's ``c.head`` apart)."""
    data = mocapz.compress(d.motion, codec="quant")
    sections = Container.from_bytes(data).sections
    _, cor = search_bases(clip, [Base(clip.zero_base(), 0)], [0], target, effort="fast")
    zero = sum(len(v) for v in cor.sections.values())
    file_c = {k: v for k, v in sections.items() if k.startswith("c.") and k != "c.head"}
    return {"frames": d.n, "file": len(data), "file_c": sum(len(v) for v in file_c.values()),
            "c_head": len(sections.get("c.head", b"")), "zero": zero, "zero_met": bool(target.met(cor.errors)),
            "identical": file_c == cor.sections, "own": {}}


def subjects(names: list[str]) -> dict[str, list[str]]:
    """Clips grouped by CMU subject (the name's part before ``_``), in name order."""
    out: dict[str, list[str]] = defaultdict(list)
    for n in sorted(names):
        out[n.split("_")[0]].append(n)
    return dict(out)


def cost(r: dict[str, Any]) -> float:
    """A matched base's bytes: the correction plus the side information."""
    return r["bytes"] + r["side"]


def effects(codings: list[dict[str, Any]], zero: dict[str, int]) -> list[tuple[str, list[tuple[Any, float, int, int]]]]:
    """Per choice and value: the median of (corr + side) / zero-base corr over the codings (body-part trials
    and the oracle left out), how many beat the zero base, out of how many."""
    rows = [r for r in codings if not r["parts"] and r["method"] != "oracle"]
    out = []
    for fac in ("method", "sigma", "rootrot", "rootpos", "alpha"):
        cells = []
        for v in sorted({r[fac] for r in rows}):
            xs = [cost(r) / zero[r["B"]] for r in rows if r[fac] == v]
            cells.append((v, statistics.median(xs), sum(x < 1 for x in xs), len(xs)))
        out.append((fac, cells))
    return out


def n_missed(res: dict[str, Any]) -> int:
    """How many codings of the run (zero base, own motion, matched bases) missed their target."""
    own = [o["met"] for c in res["clips"].values() for o in c["own"].values()]
    return sum(not r["met"] for r in res["codings"]) + sum(not c["zero_met"] for c in res["clips"].values()) \
        + sum(not met for met in own)
