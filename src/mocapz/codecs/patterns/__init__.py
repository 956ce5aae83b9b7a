"""Pattern-indexing codec (Gu, Peng & Deng 2008): hierarchical body parts, adaptive segmentation,
normalisation, adaptive K-means pattern databases, pattern-index coding, boundary smoothing.

``encode(motion, **options) -> sections`` and ``decode(sections, header) -> motion``; options in
:mod:`.options`. Library mode (databases shared between clips) is :mod:`.library`.
"""

from __future__ import annotations

from mocapz.codecs import CodecInfo
from mocapz.codecs.correction.wrap import corrected, native_targets
from mocapz.codecs.patterns.decode import decode
from mocapz.codecs.patterns.encode import encode
from mocapz.codecs.patterns.options import OPTIONS

VERSION = 2  # 2: the correction layer (codecs/correction)

ENCODE, DECODE = corrected(encode, decode, "patterns", OPTIONS, native_targets)

INFO = CodecInfo(
    name="patterns",
    version=VERSION,
    kinds=("skeleton", "markers"),
    encode=ENCODE,
    decode=DECODE,
    options=OPTIONS,
    summary="markers and skeletal clips: Gu, Peng & Deng's body-part pattern databases (adaptive segmentation, "
            "K-means, index coding); library mode in compress-db",
)
