"""Motion editing with the PGA model (the paper's second use), on the bytes of a PGA ``.mcz``.

>>> data = mocapz.compress(motion, codec="pga")
>>> traj = effector_trajectories(data)            # {"LeftToeBase_End": (frames, 3), ...}
>>> traj["LeftToeBase_End"][100:140, 1] += 10 / motion.skeleton.unit_cm   # lift 10 cm (Y up)
>>> edited = edit(data, {"LeftToeBase_End": traj["LeftToeBase_End"]})
>>> baseline = edit(data, {})   # the same solve without the change, to compare with

The solving itself is :mod:`mocapz.codecs.pga.edit`; this module only opens the container.
"""

from __future__ import annotations

import numpy as np

from mocapz.api import read_container
from mocapz.codecs.pga import edit as pga_edit
from mocapz.errors import OptionError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import Motion


def _open(data: bytes) -> tuple[dict[str, bytes], ClipHeader]:
    box, header = read_container(data)
    if box.codec != "pga":
        raise OptionError(f"editing needs a PGA-compressed clip, this one was written by {box.codec!r}")
    return box.sections, header


def effector_trajectories(data: bytes) -> dict[str, np.ndarray]:
    """The coded global trajectories ``(frames, 3)`` (file units) of a PGA clip's end effectors, by name."""
    return pga_edit.effector_trajectories(*_open(data))


def edit(data: bytes, targets: dict[str, np.ndarray], iterations: int = 40, lam_prior: float = 1e-6) -> Motion:
    """Re-solve a PGA clip with end-effector trajectories replaced (see :func:`mocapz.codecs.pga.edit.edit`)."""
    sections, header = _open(data)
    return pga_edit.edit(sections, header, targets, iterations, lam_prior)
