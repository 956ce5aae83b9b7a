"""The command line's streams: ``mocapz compress -`` on a BVH written to a pipe as it is captured codes and
writes each block as soon as it is full; ``mocapz decompress FILE -o - --format bvh`` writes the BVH rows block
by block as they are decoded."""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Any, BinaryIO

import click
import numpy as np

from mocapz.cli.common import Say
from mocapz.cli.outputs import is_stdout
from mocapz.errors import MocapzError


def is_bvh_stream(stdin: BinaryIO, fmt_name: str | None) -> bool:
    """True when standard input is BVH text (``--format bvh``, or it starts with HIERARCHY)."""
    if fmt_name is not None:
        return fmt_name.lower() == "bvh"
    peek = getattr(stdin, "peek", None)
    head = peek(64) if peek is not None else b""
    return head.lstrip()[:9].upper() == b"HIERARCHY"


def compress_bvh_stream(stdin: BinaryIO, out: Path, codec: str, options: dict[str, Any], block: str | None,
                        force: bool, name: str, say: Say) -> dict[str, Any]:
    """Code a BVH read from ``stdin`` block by block; each block's bytes go to ``out`` as soon as they are
    ready (a file: through a temporary file renamed when the stream ends; ``-``: standard output)."""
    from mocapz.io import bvh_stream
    from mocapz.io.common import atomic_write
    from mocapz.stream import StreamEncoder

    template, lines = bvh_stream.read_head(stdin, name)
    t0 = time.perf_counter()
    state = {"frames": 0, "bytes": 0}

    def run(sink: BinaryIO) -> None:
        enc: StreamEncoder | None = None
        first: list[np.ndarray] = []
        for rows in bvh_stream.rows(stdin, template.skeleton.n_channels, name, lines):
            state["frames"] += len(rows)
            if enc is None:  # the first second of rows gives the decimals the text is written with
                first.append(rows)
                if sum(len(r) for r in first) < template.frame_rate:
                    continue
                enc = _encoder(template, first, codec, block, options)
                rows = np.concatenate(first)
            data = enc.write(rows)
            if data:
                sink.write(data)
                sink.flush()
                state["bytes"] += len(data)
        if enc is None:
            enc = _encoder(template, first, codec, block, options)
            if first:
                data = enc.write(np.concatenate(first))
                sink.write(data)
                state["bytes"] += len(data)
        data = enc.close()
        sink.write(data)
        sink.flush()
        state["bytes"] += len(data)

    if is_stdout(out):
        run(click.get_binary_stream("stdout"))
    else:
        atomic_write(out, lambda tmp: _to_file(tmp, run), force=force)
    elapsed = time.perf_counter() - t0
    raw = state["frames"] * template.skeleton.n_channels * 4
    say.info(f"{name} -> {out}: streamed {state['frames']} frames in blocks, {state['bytes']} bytes, ratio "
             f"{raw / max(state['bytes'], 1):.4g} to float32; {codec}, {elapsed:.2f} s")
    return {"input": name, "output": str(out), "codec": codec, "frames": state["frames"],
            "compressed_bytes": state["bytes"], "streamed": True}


def _encoder(template: Any, first: list[np.ndarray], codec: str, block: str | None, options: dict[str, Any]) -> Any:
    from mocapz.io.bvh_stream import with_decimals
    from mocapz.stream import StreamEncoder

    rows = np.concatenate(first) if first else template.channels
    return StreamEncoder(with_decimals(template, rows), codec, block, **options)


def _to_file(tmp: Path, run: Any) -> None:
    with open(tmp, "wb") as f:
        run(f)


def decompress_bvh_to_stdout(data: bytes, name: str, frames: slice | None) -> int:
    """Write the BVH of a ``.mcz`` to standard output block by block; returns the frames written."""
    from mocapz.api import iter_decompress
    from mocapz.io.bvh import bvh_decimals, bvh_head
    from mocapz.io.bvh_stream import write_rows

    sink = io.TextIOWrapper(click.get_binary_stream("stdout"), encoding="utf-8", newline="\n",
                            write_through=True)
    written = 0
    try:
        for k, (total, motion) in enumerate(iter_decompress(data, name, frames=frames)):
            if motion.kind != "skeleton":
                raise MocapzError(f"{name}: marker data cannot be written as BVH (use --format c3d or trc)")
            if k == 0:
                sink.write(bvh_head(motion, total))
            write_rows(sink, motion.channels, bvh_decimals(motion))
            written += motion.n_frames
    finally:
        sink.flush()
        sink.detach()
    return written
