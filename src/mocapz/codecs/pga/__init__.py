"""PGA codec (Tournier et al. 2008): a pose model from Principal Geodesic Analysis of the inner joint
rotations, multiscale (lifting) coding of the root and end-effector trajectories, and decoding by
PGA-based inverse kinematics. Beyond the paper: quantisation and entropy coding of everything, coded
geodesic coordinates as the IK's warm start, outlier frames coded apart, and rate control.
"""

from __future__ import annotations

from typing import Any

from mocapz.codecs import CodecInfo
from mocapz.codecs.correction.wrap import corrected, native_targets, strip_targets
from mocapz.codecs.pga.decode import decode
from mocapz.codecs.pga.options import OPTIONS
from mocapz.codecs.pga.ratecontrol import encode
from mocapz.codecs.target import Target
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion

VERSION = 4  # 2: the correction layer (codecs/correction); 3: the fast IK solver (iksolve), values ~1e-8 rad apart;
# 4: 2 IK iterations by default (was 6), steps taken only when they lower the cost beyond rounding, Euler
# angles by the closed form (codecs/pga/channels.euler_angles), the compiled IK (numba) when installed; the
# correction's lifting integers in one stream per part

SEARCH_FRAMES = 300  # longer clips: the model at its own settings (its search takes minutes), then the correction


def _base_options(motion: Motion, options: dict[str, Any], target: Target) -> dict[str, Any]:
    """PGA's own rate control for a distortion / ARMS target on short clips, its default settings else."""
    if motion.n_frames <= SEARCH_FRAMES:
        return native_targets(motion, options, target)
    return strip_targets(motion, options, target)


ENCODE, DECODE = corrected(encode, decode, "pga", OPTIONS, _base_options, zero_base=False)


def _encode(motion: Motion, **options: Any) -> dict[str, bytes]:
    """:data:`ENCODE`; a stream's block against the model its key block fitted (:mod:`.streaming`)."""
    from mocapz.codecs.pga import streaming  # noqa: PLC0415  (it builds on the library mode, which imports this)

    return streaming.encode_block(motion, options) if streaming.in_stream(motion) else ENCODE(motion, **options)


def _decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """:data:`DECODE`, or a stream's block coded against its interval's model."""
    from mocapz.codecs.pga import streaming  # noqa: PLC0415

    return streaming.decode_block(sections, header) if streaming.is_shared_block(sections) else DECODE(sections, header)


INFO = CodecInfo(
    name="pga",
    version=VERSION,
    kinds=("skeleton",),
    encode=_encode,
    decode=_decode,
    options=OPTIONS,
    summary="skeletal clips: Tournier et al.'s PGA pose model, multiscale trajectories, PGA-based IK decoding",
)
