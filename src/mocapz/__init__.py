"""mocapz: compression of human motion-capture data.

>>> import mocapz
>>> motion = mocapz.load("walk.bvh")
>>> data = mocapz.compress(motion, codec="lossless")
>>> back = mocapz.decompress(data)
>>> mocapz.evaluate(motion, back).distortion_pct
0.0
"""

from __future__ import annotations

__version__ = "0.1.0"

from mocapz._blas import pin_openblas_kernels  # noqa: E402

pin_openblas_kernels()  # before NumPy is imported: the same bytes on every x86-64 machine

from mocapz.api import compress, decompress  # noqa: E402
from mocapz.errors import FormatError, MocapzError, OptionError, TargetError  # noqa: E402
from mocapz.io import load, save  # noqa: E402
from mocapz.libraries import (  # noqa: E402
    append_library,
    compress_library,
    extract_clip,
    list_clips,
    read_clip,
    verify_library,
)
from mocapz.metrics.figures import evaluate  # noqa: E402
from mocapz.model.motion import MarkerMotion, Motion  # noqa: E402
from mocapz.model.skeleton import Skeleton  # noqa: E402
from mocapz.reader import Reader, open  # noqa: E402, A004
from mocapz.stream import StreamDecoder, StreamEncoder  # noqa: E402

__all__ = [
    "FormatError", "MarkerMotion", "MocapzError", "Motion", "OptionError", "Reader", "Skeleton", "StreamDecoder",
    "StreamEncoder", "TargetError", "__version__", "append_library", "compress", "compress_library", "decompress",
    "evaluate", "extract_clip", "list_clips", "load", "open", "read_clip", "save", "verify_library",
]
