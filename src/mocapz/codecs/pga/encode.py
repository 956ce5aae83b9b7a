"""PGA encoder: pose model, multiscale trajectories, quantisation and entropy coding."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocapz.codecs.pga import lifting, so3
from mocapz.codecs.pga.decode import make_problem
from mocapz.codecs.pga.effectors import find_effectors
from mocapz.codecs.pga.model import PGAModel, fit_pga
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.pga.pipeline import (
    Clip,
    analyse,
    check_skeleton,
    coordinates,
    inner_joints,
    model_matrices,
    pack_matrices,
    quantise_model,
    targets_in_root_frame,
)
from mocapz.format.entropy import pack_uint64, zigzag
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import Motion


def detect_outliers(motion: Motion, factor: float = 15.0) -> list[int]:
    """Frames that are isolated spikes in pose space (e.g. the T-pose cgspeed files add as frame 1).

    With ``step(a, b)`` the geodesic distance between the inner-joint poses of frames ``a`` and ``b`` and
    ``s`` its median over consecutive frames: an inner frame ``t`` is an outlier when ``step(t-1, t)`` and
    ``step(t, t+1)`` both exceed ``factor * s`` while ``step(t-1, t+1)`` does not (its neighbours agree
    with each other: a spike, not a fast move); the first (last) frame when its step to the next
    (previous) exceeds ``factor * s`` and that frame's own next step is ordinary (under ``3 s``).
    """
    if motion.n_frames < 8:
        return []
    sk = motion.skeleton
    inner = inner_joints(sk)
    from mocapz.model.kinematics import local_rotations

    rot = local_rotations(sk, motion.channels)[:, inner]
    n = len(rot)

    def dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.linalg.norm(so3.log(np.swapaxes(a, -1, -2) @ b).reshape(len(a), -1), axis=1)

    step = dist(rot[:-1], rot[1:])
    skip = dist(rot[:-2], rot[2:])
    s = max(float(np.median(step)), 1e-9)
    out = []
    if step[0] > factor * s and step[1] < 3 * s:
        out.append(0)
    big = step > factor * s
    inner_t = np.flatnonzero(big[:-1] & big[1:] & (skip < factor * s)) + 1
    out += [int(t) for t in inner_t]
    if step[-1] > factor * s and step[-2] < 3 * s:
        out.append(n - 1)
    return sorted(set(out))


@dataclass
class Prepared:
    """Per-clip analysis reused across the settings tried by rate control."""

    motion: Motion
    outliers: list[int]
    kept: np.ndarray
    clip: Clip
    effectors: np.ndarray
    eff_global: np.ndarray  # (F, e, 3)
    eff_local: np.ndarray  # (F, e, 3) in the root frame
    full_model: PGAModel
    ref_cache: dict[int, np.ndarray] = field(default_factory=dict)  # original positions, for rate control


def prepare(motion: Motion, effectors: list[int] | None = None, outliers: list[int] | None = None) -> Prepared:
    sk = motion.skeleton
    check_skeleton(sk)
    out = detect_outliers(motion) if outliers is None else outliers
    kept = np.setdiff1d(np.arange(motion.n_frames), np.asarray(out, dtype=np.int64))
    ch = motion.channels[kept]
    clip = analyse(sk, ch)
    eff = np.asarray(effectors, dtype=np.int64) if effectors else find_effectors(sk)
    pos = forward_kinematics(sk, ch)[0]
    inner = inner_joints(sk)
    model = fit_pga(clip.local_rot[:, inner], inner) if len(kept) else None
    local = targets_in_root_frame(pos[:, eff], clip.root_pos, clip.root_rot)
    return Prepared(motion, list(out), kept, clip, eff, pos[:, eff], local, model)  # type: ignore[arg-type]


def encode_prepared(p: Prepared, s: PGASettings) -> dict[str, bytes]:
    """Sections for fixed settings (``s.outliers`` / ``s.effectors`` are filled in from ``p``)."""
    s = s.replace(outliers=list(p.outliers)).roundtrip()
    sections: dict[str, bytes] = {"params": s.to_bytes()}
    n = len(p.kept)
    if n:
        s.validate(p.full_model.basis.shape[0], n)
        ints, model_q = quantise_model(p.full_model, s.k, s.basis_bits, s.mean_step)
        inner = model_q.joints
        mats = model_matrices(ints, len(model_q.joints), s.k)
        mats.append(lifting.encode_rn(p.clip.root_pos, s.pos_step, s.lod_root)[0])
        mats.append(lifting.encode_so3(p.clip.root_rot, s.rot_step, s.lod_root)[0])
        other_q, other_rec = lifting.encode_rn(p.clip.other_pos, s.pos_step, 0)
        coords_q = coords_rec = None
        if s.use_coords:
            x = coordinates(model_q, p.clip.local_rot[:, inner])
            coords_q, coords_rec = lifting.encode_rn(x, s.coord_step, s.lod_coords)
        if s.eff_mode == 2:
            mats.append(np.zeros((1, 0), dtype=np.int64))
        elif s.eff_mode == 1 and coords_rec is not None:
            # residual of the true root-frame effector positions against those the coded pose gives
            problem = make_problem(p.motion.skeleton, model_q, p.effectors, other_rec)
            resid = p.eff_local - problem.forward(coords_rec)[0]
            mats.append(lifting.encode_rn(resid.reshape(n, -1), s.pos_step, s.lod_effectors)[0])
        else:
            mats.append(lifting.encode_rn(p.eff_global.reshape(n, -1), s.pos_step, s.lod_effectors)[0])
        if coords_q is not None:
            mats.append(coords_q)
        if p.clip.other_pos.shape[1]:
            mats.append(other_q)
        sections["data"] = pack_matrices(mats)
    if p.outliers:
        sections["outl"] = encode_outliers(p.motion, p.outliers)
    return sections


def encode_outliers(motion: Motion, frames: list[int]) -> bytes:
    """Outlier frames' channels exactly at the source's precision: integers at the largest decimal count of
    any column (4 when unknown), which represents every column exactly."""
    dec = int(min(motion.decimals.max(), 9)) if motion.decimals is not None and motion.decimals.size else 4
    vals = np.round(motion.channels[frames] * 10.0**dec).astype(np.int64)
    return pack_uint64(zigzag(np.concatenate([[dec], vals.ravel()])))
