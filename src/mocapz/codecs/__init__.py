"""Codec registry. A codec turns a motion into named byte sections and back.

Each codec is a subpackage (or a module) with an encoder and a decoder side by side, described by a
:class:`CodecInfo` and registered here by name; names are case-insensitive. The container stores the codec
name and version, so a file says which decoder it needs. A codec never parses files or reads the container:
its encoder gets a motion and checked options (:mod:`mocapz.codecs.options`), its decoder the sections and
a typed :class:`~mocapz.model.header.ClipHeader`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from mocapz._blas import on_one_thread
from mocapz.codecs.options import Option, validate
from mocapz.errors import OptionError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion


@dataclass(frozen=True)
class CodecInfo:
    """One registered codec.

    Attributes:
        name: the ``--codec`` name.
        version: bumped whenever the byte format of its sections changes.
        kinds: ``"skeleton"`` and/or ``"markers"``: the data it accepts.
        encode: ``encode(motion, **options) -> dict[str, bytes]``, options checked by :meth:`validate`.
        decode: ``decode(sections, header) -> motion``.
        options: the option declarations (the common targets first in every lossy codec).
        summary: one line on what the codec is for (help, docs).
        lossy: False only for codecs that give the values back exactly.
        block_seconds: the default length of the independent blocks a clip is coded in (random access,
            :mod:`mocapz.blocking`); 0: the whole clip in one block.
        decode_window: ``decode_window(sections, header, start, stop, memo=None) -> motion or None``: frames
            ``[start, stop)`` of a clip in one block, decoding only what they need (the values of a full decode),
            or None where this file needs the full decode; ``memo``: a dict the caller keeps for these sections
            (a reader's), where the codec may leave what every window of them reads.
    """

    name: str
    version: int
    kinds: tuple[str, ...]
    encode: Callable[..., dict[str, bytes]]
    decode: Callable[[dict[str, bytes], ClipHeader], AnyMotion]
    options: tuple[Option, ...]
    summary: str = ""
    lossy: bool = True
    block_seconds: float = 0.0
    decode_window: Callable[..., AnyMotion | None] | None = None

    def validate(self, options: dict[str, Any]) -> dict[str, Any]:
        """Checked options (raises OptionError naming the option and what it accepts)."""
        return validate(self.name, self.options, options)

    def option(self, name: str) -> Option:
        return next(o for o in self.options if o.name == name)


_REGISTRY: dict[str, Callable[[], CodecInfo]] = {}


def register(name: str, loader: Callable[[], CodecInfo]) -> None:
    _REGISTRY[name.lower()] = loader


def get_codec(name: str) -> CodecInfo:
    """The codec registered as ``name`` (any case)."""
    key = str(name).strip().lower()
    if key not in _REGISTRY:
        raise OptionError(f"unknown codec {name!r} (available: {', '.join(sorted(_REGISTRY))})")
    return _REGISTRY[key]()


def codec_names() -> list[str]:
    return sorted(_REGISTRY)


def all_codecs() -> list[CodecInfo]:
    """Every registered codec, in registration order (lossless, pga, patterns, then the baselines)."""
    return [loader() for loader in _REGISTRY.values()]


def _loader(module: str) -> Callable[[], CodecInfo]:
    loaded: list[CodecInfo] = []

    def load() -> CodecInfo:
        """The module's codec, its encoder and decoders run with one BLAS thread (:func:`mocapz._blas.one_thread`)."""
        if not loaded:
            info: CodecInfo = importlib.import_module(module).INFO
            window = None if info.decode_window is None else on_one_thread(info.decode_window)
            loaded.append(replace(info, encode=on_one_thread(info.encode), decode=on_one_thread(info.decode),
                                  decode_window=window))
        return loaded[0]

    return load


for _name, _module in (("lossless", "mocapz.codecs.lossless"), ("pga", "mocapz.codecs.pga"),
                       ("patterns", "mocapz.codecs.patterns"), ("subsample", "mocapz.codecs.baselines.subsample"),
                       ("pca", "mocapz.codecs.baselines.pca"), ("segpca", "mocapz.codecs.baselines.segpca"),
                       ("quant", "mocapz.codecs.baselines.quant")):
    register(_name, _loader(_module))
