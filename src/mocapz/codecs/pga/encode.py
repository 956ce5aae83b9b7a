"""PGA encoder for fixed settings: the per-clip analysis (:func:`prepare`, reused by rate control), then
pose model, multiscale trajectories, quantisation and entropy coding (:func:`encode_prepared`)."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mocapz.codecs.pga import lifting
from mocapz.codecs.pga.clip import Clip, analyse, targets_in_root_frame
from mocapz.codecs.pga.effectors import effector_points
from mocapz.codecs.pga.ik import make_problem
from mocapz.codecs.pga.joints import check_skeleton, inner_joints, skeleton_scale
from mocapz.codecs.pga.model import PGAModel, coordinates, fit_pga
from mocapz.codecs.pga.outliers import detect_outliers, encode_outliers, kept_frames
from mocapz.codecs.pga.packing import once, pack_streams
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.pga.quantise import model_matrices, quantise_model
from mocapz.format.entropy import encode_int_matrix
from mocapz.model.kinematics import forward_positions, local_rotations
from mocapz.model.motion import Motion


@dataclass
class Prepared:
    """Per-clip analysis reused across the settings tried by rate control (F = kept frames, e = effectors;
    file units)."""

    motion: Motion
    outliers: list[int]
    kept: np.ndarray  # (F,) frame indices
    clip: Clip
    effectors: np.ndarray  # (e,) FK point indices
    eff_global: np.ndarray  # (F, e, 3)
    eff_local: np.ndarray  # (F, e, 3) in the root frame
    full_model: PGAModel
    ref_cache: dict[int, np.ndarray] = field(default_factory=dict)  # original positions, for rate control
    memo: dict[Hashable, Any] = field(default_factory=dict)  # rate control's streams (:func:`.packing.once`)
    shared: tuple[np.ndarray, PGAModel] | None = None  # a library's quantised model (integers, model) to code
    # against instead of quantising ``full_model`` (its k, basis bits and mean step are the settings')


def prepare(motion: Motion, effectors: list[int] | None = None, outliers: list[int] | None = None) -> Prepared:
    """Analyse a clip: outlier frames (found when ``outliers`` is None), end effectors (FK point indices;
    found from the tree when not given), the clip's streams and the full PGA model of its kept frames."""
    sk = motion.skeleton
    check_skeleton(sk)
    every = local_rotations(sk, motion.channels) if outliers is None else None  # each frame's on its own
    out = detect_outliers(motion, local=every) if outliers is None else outliers
    kept = kept_frames(motion.n_frames, out)
    ch = motion.channels[kept]
    clip = analyse(sk, ch, None if every is None else every[kept])
    eff = effector_points(sk, effectors)
    pos = forward_positions(sk, ch)
    inner = inner_joints(sk)
    model = fit_pga(clip.local_rot[:, inner], inner) if len(kept) else None
    local = targets_in_root_frame(pos[:, eff], clip.root_pos, clip.root_rot)
    return Prepared(motion, list(out), kept, clip, eff, pos[:, eff], local, model)  # type: ignore[arg-type]


def encode_prepared(p: Prepared, s: PGASettings, memo: dict[Hashable, Any] | None = None) -> dict[str, bytes]:
    """Sections for fixed settings (``s.outliers`` / ``s.effectors`` are filled in from ``p``). ``memo``: a rate
    search's (:func:`.packing.once`): each stream's integers, reconstruction and bytes kept by the settings it
    is a function of (the same bytes)."""
    s = s.replace(outliers=list(p.outliers)).roundtrip()
    sections: dict[str, bytes] = {"params": s.to_bytes()}
    n = len(p.kept)
    if n:
        s.validate(p.full_model.basis.shape[0], n)
        model = (s.k, s.basis_bits, s.mean_step)
        ints, model_q = p.shared if p.shared is not None else \
            once(memo, ("model", *model), lambda: quantise_model(p.full_model, *model))
        inner = model_q.joints
        clip = p.clip

        def rn(key: tuple[Any, ...], x: Callable[[], np.ndarray], step: float, lod: int
               ) -> tuple[np.ndarray, np.ndarray]:
            return once(memo, key, lambda: lifting.encode_rn(x(), step, lod))

        head, loadings = once(memo, ("model matrices", *model), lambda: model_matrices(ints, len(inner), s.k))
        root, turn = ("root", s.pos_step, s.lod_root), ("root rotations", s.rot_step, s.lod_root)
        mats = [(("head", *model), head), (("loadings", *model), loadings),
                (root, rn(root, lambda: clip.root_pos, s.pos_step, s.lod_root)[0]),
                (turn, once(memo, turn, lambda: lifting.encode_so3(clip.root_rot, s.rot_step, s.lod_root))[0])]
        other = ("other", s.pos_step)
        other_q, other_rec = rn(other, lambda: clip.other_pos, s.pos_step, 0)
        coords = ("coordinates", *model, s.coord_step, s.lod_coords)
        coords_q = coords_rec = None
        if s.use_coords:
            coords_q, coords_rec = rn(coords, lambda: coordinates(model_q, clip.local_rot[:, inner]), s.coord_step,
                                      s.lod_coords)
        if s.eff_mode == 2:
            mats.append((("no effectors",), np.zeros((1, 0), dtype=np.int64)))
        elif s.eff_mode == 1 and coords_rec is not None:
            # residual of the true root-frame effector positions against those the coded pose gives
            def coded(rec: np.ndarray = coords_rec) -> np.ndarray:  # the effectors of the coded pose
                sk = p.motion.skeleton
                problem = make_problem(sk, model_q, p.effectors, other_rec,
                                       once(memo, ("skeleton scale",), lambda: skeleton_scale(sk)))
                return problem.forward(rec)[0]

            moved = other[1:] if clip.other_pos.shape[1] else ()  # the other position channels, where coded

            def resid() -> np.ndarray:
                pose = once(memo, ("coded pose's effectors", *coords[1:], *moved), coded)
                return (p.eff_local - pose).reshape(n, -1)

            key = ("effector residual", *coords[1:], s.pos_step, s.lod_effectors)
            mats.append((key, rn(key, resid, s.pos_step, s.lod_effectors)[0]))
        else:
            key = ("effectors", s.pos_step, s.lod_effectors)
            mats.append((key, rn(key, lambda: p.eff_global.reshape(n, -1), s.pos_step, s.lod_effectors)[0]))
        if coords_q is not None:
            mats.append((coords, coords_q))
        if clip.other_pos.shape[1]:
            mats.append((other, other_q))
        sections["data"] = pack_streams([once(memo, ("bytes", *key), lambda m=m: encode_int_matrix(m))
                                         for key, m in mats])
    if p.outliers:
        sections["outl"] = encode_outliers(p.motion, p.outliers)
    return sections
