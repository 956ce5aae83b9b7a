"""PGA codec (Tournier et al. 2008): a pose model from Principal Geodesic Analysis of the inner joint
rotations, multiscale (lifting) coding of the root and end-effector trajectories, and decoding by
PGA-based inverse kinematics. Beyond the paper: quantisation and entropy coding of everything, coded
geodesic coordinates as the IK's warm start, outlier frames coded apart, and rate control.
"""

from __future__ import annotations

from mocapz.codecs import CodecInfo
from mocapz.codecs.pga.decode import decode
from mocapz.codecs.pga.options import OPTIONS
from mocapz.codecs.pga.ratecontrol import encode

VERSION = 2  # 2: the fast IK solver (iksolve); decoded values moved by ~1e-8 rad against version 1

INFO = CodecInfo(
    name="pga",
    version=VERSION,
    kinds=("skeleton",),
    encode=encode,
    decode=decode,
    options=OPTIONS,
    summary="skeletal clips: Tournier et al.'s PGA pose model, multiscale trajectories, PGA-based IK decoding",
)
