"""PGA codec (Tournier et al. 2008): a pose model from Principal Geodesic Analysis of the inner joint
rotations, multiscale (lifting) coding of the root and end-effector trajectories, and decoding by
PGA-based inverse kinematics. Beyond the paper: quantisation and entropy coding of everything, coded
geodesic coordinates as the IK's warm start, outlier frames coded apart, and rate control.
"""

from __future__ import annotations

from mocapz.codecs import CodecInfo
from mocapz.codecs.pga.decode import decode
from mocapz.codecs.pga.encode import encode

VERSION = 1

INFO = CodecInfo(
    name="pga",
    version=VERSION,
    kinds=("skeleton",),
    encode=encode,
    decode=decode,
    options={
        "geodesics": "number of principal geodesics k",
        "lod_root": "levels of detail dropped from the root trajectory",
        "lod_effectors": "levels of detail dropped from the end-effector trajectories",
        "effectors": "end-effector joint names (comma-separated)",
        "max_distortion": "target distortion_pct",
        "max_error": "target maximum position error",
        "bits": "bits of the principal directions",
    },
)
