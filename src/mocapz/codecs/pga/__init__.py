"""PGA codec (Tournier et al. 2008): a pose model from Principal Geodesic Analysis of the inner joint
rotations, multiscale (lifting) coding of the root and end-effector trajectories, and decoding by
PGA-based inverse kinematics. Beyond the paper: quantisation and entropy coding of everything, coded
geodesic coordinates as the IK's warm start, outlier frames coded apart, and rate control.
"""

from __future__ import annotations

from mocapz.codecs import CodecInfo
from mocapz.codecs.correction.wrap import corrected, native_targets
from mocapz.codecs.pga.decode import decode
from mocapz.codecs.pga.options import OPTIONS
from mocapz.codecs.pga.ratecontrol import encode

VERSION = 2  # 2: the correction layer (codecs/correction)

ENCODE, DECODE = corrected(encode, decode, "pga", OPTIONS, native_targets, zero_base=False)

INFO = CodecInfo(
    name="pga",
    version=VERSION,
    kinds=("skeleton",),
    encode=ENCODE,
    decode=DECODE,
    options=OPTIONS,
    summary="skeletal clips: Tournier et al.'s PGA pose model, multiscale trajectories, PGA-based IK decoding",
)
