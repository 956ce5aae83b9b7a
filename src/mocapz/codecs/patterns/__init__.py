"""Pattern-indexing codec (Gu, Peng & Deng 2008): hierarchical body parts, adaptive segmentation,
normalisation, adaptive K-means pattern databases, pattern-index coding, boundary smoothing.

``encode(motion, **options) -> sections`` and ``decode(sections, header) -> motion``; options in
:mod:`.options`. Library mode (databases shared between clips) is :mod:`.library`.
"""

from __future__ import annotations

from typing import Any

from mocapz.codecs import CodecInfo
from mocapz.codecs.correction.wrap import apply_window, corrected, given_settings, native_targets, strip_targets
from mocapz.codecs.patterns.decode import decode
from mocapz.codecs.patterns.encode import encode
from mocapz.codecs.patterns.options import OPTIONS
from mocapz.codecs.target import Target
from mocapz.model.motion import AnyMotion

VERSION = 3  # 2: the correction layer (codecs/correction); 3: its knots and details in two streams



def _base_options(motion: AnyMotion, options: dict[str, Any], target: Target) -> dict[str, Any]:
    """The model's own search for a distortion / ARMS target when the user fixed some of its settings (the
    search takes minutes on marker clips), else its default settings: the correction meets the targets."""
    if given_settings(options, OPTIONS):
        return native_targets(motion, options, target)
    return strip_targets(motion, options, target)


ENCODE, DECODE = corrected(encode, decode, "patterns", OPTIONS, _base_options)

INFO = CodecInfo(
    name="patterns",
    decode_window=apply_window,
    version=VERSION,
    kinds=("skeleton", "markers"),
    encode=ENCODE,
    decode=DECODE,
    options=OPTIONS,
    summary="markers and skeletal clips: Gu, Peng & Deng's body-part pattern databases (adaptive segmentation, "
            "K-means, index coding); library mode in compress-db",
)
