"""Motion editing with the PGA model (the paper's second use).

A PGA-compressed clip is re-solved with some end-effector trajectories replaced: the IK finds, frame by
frame, the pose of the clip's own pose space that puts the effectors where asked, so the edited motion
keeps the style of the original.

The functions here work on a PGA clip's sections and header; :mod:`mocapz.edit` opens ``.mcz`` bytes:

>>> data = mocapz.compress(motion, codec="pga")
>>> traj = effector_trajectories(data)            # {"LeftToeBase_End": (frames, 3), ...}
>>> traj["LeftToeBase_End"][100:140, 1] += 10 / motion.skeleton.unit_cm   # lift 10 cm (Y up)
>>> edited = edit(data, {"LeftToeBase_End": traj["LeftToeBase_End"]})
>>> baseline = edit(data, {})   # the same solve without the change, to compare with
"""

from __future__ import annotations

import numpy as np

from mocapz.codecs.pga.decode import decode_channels, decode_streams
from mocapz.codecs.pga.effectors import effector_points
from mocapz.codecs.pga.outliers import kept_frames
from mocapz.codecs.pga.params import PGASettings
from mocapz.errors import OptionError
from mocapz.model.header import ClipHeader
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import Motion


def _open(sections: dict[str, bytes], header: ClipHeader) -> tuple[PGASettings, np.ndarray]:
    if header.skeleton is None:
        raise OptionError("editing needs a skeletal clip")
    s = PGASettings.from_bytes(sections["params"])
    eff = effector_points(header.skeleton, s.effectors)
    return s, eff


def effector_trajectories(sections: dict[str, bytes], header: ClipHeader) -> dict[str, np.ndarray]:
    """The coded global trajectories ``(frames, 3)`` (file units) of the clip's end effectors, by name:
    the IK's targets, the natural thing to edit. Frames coded apart (outliers) hold their FK positions."""
    s, eff = _open(sections, header)
    skeleton = header.skeleton
    assert skeleton is not None
    frames = header.frames
    kept = kept_frames(frames, s.outliers)
    d = decode_streams(skeleton, s, sections, len(kept))
    coded = d.root_pos[:, None] + np.einsum("fij,fej->fei", d.root_rot, d.targets)
    pos = forward_kinematics(skeleton, decode_channels(skeleton, s, sections, frames))[0][:, eff]
    pos[kept] = coded
    names = skeleton.point_names
    return {names[e]: pos[:, i].copy() for i, e in enumerate(eff)}


def edit(sections: dict[str, bytes], header: ClipHeader, targets: dict[str, np.ndarray], iterations: int = 40,
         lam_prior: float = 1e-6) -> Motion:
    """Re-solve a PGA clip with end-effector trajectories replaced.

    Args:
        sections, header: a clip written by the PGA codec.
        targets: effector name -> new global trajectory ``(frames, 3)`` in file units (all frames of the
            clip; frames coded apart as outliers are kept as they were).
        iterations: LM iterations (more than for plain decoding: the edit moves far from the warm start).
        lam_prior: weight keeping the poses near the coded ones (small, so the targets are reached).

    Returns:
        The edited motion, same skeleton and frame count.
    """
    s, eff = _open(sections, header)
    skeleton = header.skeleton
    assert skeleton is not None
    frames = header.frames
    names = skeleton.point_names
    slots = {names[e]: i for i, e in enumerate(eff)}
    kept = kept_frames(frames, s.outliers)
    replace: dict[int, np.ndarray] = {}
    for name, traj in targets.items():
        if name not in slots:
            raise OptionError(f"{name!r} is not an end effector of this clip (effectors: {', '.join(slots)})")
        traj = np.asarray(traj, dtype=np.float64)
        if traj.shape != (frames, 3) or not np.isfinite(traj).all():
            raise OptionError(f"trajectory for {name!r} must be finite with shape ({frames}, 3), got {traj.shape}")
        replace[slots[name]] = traj[kept]
    s2 = s.replace(iterations=iterations, lam_prior=lam_prior)
    motion = header.motion(decode_channels(skeleton, s2, sections, frames, edit=replace))
    assert isinstance(motion, Motion)
    return motion
