"""The PGA codec in a stream: the blocks between two key blocks share one pose model.

A single file stores its own PGA model (about 700 bytes, the first matrices of ``data``); a stream's block of about
1 s would pay it every second. In a stream (a block whose :class:`~mocapz.model.motion.BlockOf` cache has the
``"stream"`` dict, :class:`mocapz.StreamEncoder`), the model is fitted at every key block on the frames the stream
keeps as context (the last seconds and the block: :data:`mocapz.stream.HISTORY_S`), quantised once, and every block
until the next key codes its trajectories and coordinates against it, as a library's clips do
(:mod:`.library`): a block's sections are the model's ``m`` and ``p`` (the same bytes in every block of the
interval, so the stream writes them once, :func:`mocapz.format.blocks.thin`) and its own ``params``, ``data``
without the model, ``outl`` and the correction's ``c.*``. The correction meets the target on every block. A block
whose correction alone (a zero base, continuing the block before as a quant stream's blocks do) codes it smaller
than the model and its correction takes that, and holds no model sections (:func:`~.wrap.on_model`). A
block's IK takes the compiled kernels when numba is installed, whatever the block's length
(:func:`.ikjit.any_length`), in the encoder and in every decoder alike.
"""

from __future__ import annotations

from typing import Any

from mocapz.codecs.correction.context import block_of
from mocapz.codecs.correction.wrap import on_model
from mocapz.codecs.pga import ikjit
from mocapz.codecs.pga.library import _coder, _prepare, decode_member, fit_shared
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion

Sections = dict[str, bytes]
KEPT = "pga_model"  # the stream's kept model: (SharedModel, its sections)
HELD = "pga_held"  # the model sections the last block holds (None: it took the correction alone)


def in_stream(motion: AnyMotion) -> bool:
    """Whether ``motion`` is a stream's block (its encoder keeps what lasts the stream)."""
    ctx = block_of(motion)
    return ctx is not None and isinstance(ctx.cache.get("stream"), dict)


def encode_block(motion: AnyMotion, options: dict[str, Any]) -> Sections:
    """A stream block's sections: the interval's model (``m``, ``p``; fitted anew at a key block) and the block
    coded against it with the correction layer."""
    ctx = block_of(motion)
    assert ctx is not None
    kept = ctx.cache["stream"]
    with ikjit.any_length():
        if ctx.cache.get("key") or KEPT not in kept:
            model = fit_shared([_prepare(ctx.clip, options)], options)
            kept[KEPT] = (model, model.sections())
        model, shared = kept[KEPT]
        # the model's sections are free to a block when the block before holds them (written as marks), else
        # they count among the model base's bytes against the correction alone's
        free = kept.get(HELD) is shared
        own = _coder(_prepare(motion, options), model, shared, zero_base=True, counted=not free)[0](
            motion, **options)  # type: ignore[arg-type]
    # the correction alone where it codes the block smaller: the block holds no model (the next block on it
    # carries the interval's)
    on = on_model(own)
    kept[HELD] = shared if on else None
    return {**shared, **own} if on else own


def is_shared_block(sections: Sections) -> bool:
    """Whether a block's sections hold a stream's shared model."""
    return "m" in sections and "p" in sections


def decode_block(sections: Sections, header: ClipHeader) -> AnyMotion:
    """A stream block coded against its interval's model."""
    shared = {k: sections[k] for k in ("m", "p")}
    own = {k: v for k, v in sections.items() if k not in shared}
    with ikjit.any_length():
        return decode_member(shared, own, header)


__all__ = ["decode_block", "encode_block", "in_stream", "is_shared_block"]
