"""Pattern-indexing codec (Gu, Peng & Deng 2008): hierarchical body parts, adaptive segmentation,
normalisation, adaptive K-means pattern databases, pattern-index coding, boundary smoothing.

``encode(motion, **options) -> sections`` and ``decode(sections, layout) -> motion``; options in
:mod:`.options`. Library mode (databases shared between clips) lives in :mod:`mocapz.library`.
"""

from __future__ import annotations

from .. import CodecInfo
from .decode import decode
from .encode import encode
from .options import OPTIONS

VERSION = 1

INFO = CodecInfo(
    name="patterns",
    version=VERSION,
    kinds=("skeleton", "markers"),
    encode=encode,
    decode=decode,
    options=OPTIONS,
)
