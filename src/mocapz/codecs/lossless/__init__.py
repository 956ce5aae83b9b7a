"""Lossless codec: exact values back, at the source's precision.

Values are turned into integers (the file's decimals, or the float bit patterns when the decimals are
unknown), predicted from the two previous frames (second differences) and from the channels of the same
joint already coded in the frame (integer linear prediction), and the residuals are range coded with
block-adaptive Laplace models (:mod:`mocapz.format.entropy`).
"""

from __future__ import annotations

from mocapz.codecs import CodecInfo
from mocapz.codecs.lossless.decode import decode
from mocapz.codecs.lossless.encode import encode

VERSION = 2

INFO = CodecInfo(
    name="lossless",
    version=VERSION,
    kinds=("skeleton", "markers"),
    encode=encode,
    decode=decode,
    options=(),
    summary="every file: the exact values back at the source's precision (integer prediction, range coding)",
    lossy=False,
    block_seconds=1.0,  # random access: +1.5 % on 06_13.bvh (docs/benchmarks/speed.md)
)
