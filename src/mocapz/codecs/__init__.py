"""Codec registry. A codec turns a motion into named byte sections and back.

Each codec is a subpackage with an ``encode`` module and a ``decode`` module; it is registered here by
name. The container stores the codec name and version, so a file says which decoder it needs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mocapz.errors import OptionError
from mocapz.model.motion import AnyMotion


@dataclass(frozen=True)
class CodecInfo:
    """One registered codec.

    Attributes:
        name: the ``--codec`` name.
        version: bumped whenever the byte format of its sections changes.
        kinds: ``"skeleton"`` and/or ``"markers"``: the data it accepts.
        encode: ``encode(motion, **options) -> dict[str, bytes]``.
        decode: ``decode(sections, layout) -> motion`` (``layout`` is the container's layout dict).
        options: option name -> short description, for ``--help`` and validation.
    """

    name: str
    version: int
    kinds: tuple[str, ...]
    encode: Callable[..., dict[str, bytes]]
    decode: Callable[[dict[str, bytes], dict[str, Any]], AnyMotion]
    options: dict[str, str]


_REGISTRY: dict[str, Callable[[], CodecInfo]] = {}


def register(name: str, loader: Callable[[], CodecInfo]) -> None:
    _REGISTRY[name] = loader


def get_codec(name: str) -> CodecInfo:
    if name not in _REGISTRY:
        raise OptionError(f"unknown codec {name!r} (available: {', '.join(sorted(_REGISTRY))})")
    return _REGISTRY[name]()


def codec_names() -> list[str]:
    return sorted(_REGISTRY)


def _lossless() -> CodecInfo:
    from mocapz.codecs.lossless import INFO

    return INFO


register("lossless", _lossless)


def _pga() -> CodecInfo:
    from mocapz.codecs.pga import INFO

    return INFO


def _patterns() -> CodecInfo:
    from mocapz.codecs.patterns import INFO

    return INFO


register("pga", _pga)
register("patterns", _patterns)
register("subsample", lambda: __import__("mocapz.codecs.baselines.subsample", fromlist=["INFO"]).INFO)
register("pca", lambda: __import__("mocapz.codecs.baselines.pca", fromlist=["INFO"]).INFO)
register("segpca", lambda: __import__("mocapz.codecs.baselines.segpca", fromlist=["INFO"]).INFO)
register("quant", lambda: __import__("mocapz.codecs.baselines.quant", fromlist=["INFO"]).INFO)
