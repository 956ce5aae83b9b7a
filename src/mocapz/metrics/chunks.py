"""The frames the figures' work arrays take at a time: a long clip's ``(frames, points, 3)`` temporaries stay a
few megabytes (peak memory), with the numbers of the whole array at once."""

from __future__ import annotations

CHUNK_FRAMES = 1024  # frames at a time of the figures' (frames, points, 3) temporaries (peak memory)


def frame_chunks(frames: int, chunk: int = CHUNK_FRAMES) -> list[slice]:
    """Consecutive slices of at most ``chunk`` frames covering ``frames`` frames."""
    return [slice(s, min(s + chunk, frames)) for s in range(0, frames, chunk)]
