"""PGA codec (Tournier et al. 2008): a pose model from Principal Geodesic Analysis of the inner joint
rotations, multiscale (lifting) coding of the root and end-effector trajectories, and decoding by
PGA-based inverse kinematics. Beyond the paper: quantisation and entropy coding of everything, coded
geodesic coordinates as the IK's warm start, outlier frames coded apart, and rate control.
"""

from __future__ import annotations

from typing import Any

from mocapz.codecs import CodecInfo
from mocapz.codecs.correction.wrap import apply_window
from mocapz.codecs.pga import streaming
from mocapz.codecs.pga.codec import DECODE, ENCODE, VERSION, _base_options
from mocapz.codecs.pga.decode import decode_window
from mocapz.codecs.pga.options import OPTIONS
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion

__all__ = ["DECODE", "ENCODE", "INFO", "VERSION", "_base_options"]


def _encode(motion: Motion, **options: Any) -> dict[str, bytes]:
    """:data:`ENCODE`; a stream's block against the model its key block fitted (:mod:`.streaming`)."""
    return streaming.encode_block(motion, options) if streaming.in_stream(motion) else ENCODE(motion, **options)


def _decode_window(sections: dict[str, bytes], header: ClipHeader, start: int, stop: int,
                   memo: dict[str, Any] | None = None) -> AnyMotion | None:
    """Frames ``[start, stop)`` of a file in one block: the correction's seekable streams windowed, the model's
    IK solved on those frames only (:func:`.decode.decode_window`)."""
    if streaming.is_shared_block(sections):
        return None
    return apply_window(sections, header, start, stop, base_window=decode_window, memo=memo)


def _decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """:data:`DECODE`, or a stream's block coded against its interval's model."""
    return streaming.decode_block(sections, header) if streaming.is_shared_block(sections) else DECODE(sections, header)


INFO = CodecInfo(
    name="pga",
    version=VERSION,
    kinds=("skeleton",),
    encode=_encode,
    decode=_decode,
    options=OPTIONS,
    decode_window=_decode_window,
    summary="skeletal clips: Tournier et al.'s PGA pose model, multiscale trajectories, PGA-based IK decoding",
)
