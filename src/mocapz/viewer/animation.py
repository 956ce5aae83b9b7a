"""Write the side-by-side animation: GIF (Pillow) or MP4 (imageio-ffmpeg), the clip at its real speed.

Frames come from :func:`mocapz.viewer.frame.render_frame`, sampled at the output frame rate; a GIF uses one
palette for every frame, an MP4 is H.264 through the ffmpeg binary of the optional package imageio-ffmpeg.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.errors import MocapzError, OptionError
from mocapz.io.common import atomic_write
from mocapz.viewer.data import ViewData
from mocapz.viewer.frame import SS, STRIP_H, error_rgb, error_strip, render_frame

MAX_GIF_FRAMES = 600
ANIMATION_SUFFIXES = (".gif", ".mp4")


def animation_frames(view: ViewData, fps: float) -> np.ndarray:
    """View frame indices sampled at ``fps`` over the clip."""
    if fps <= 0:
        raise OptionError("--fps must be positive")
    n = max(1, int(math.floor(view.n_frames / view.frame_rate * fps + 1e-9)))
    return np.minimum(np.rint(np.arange(n) / fps * view.frame_rate).astype(np.int64), view.n_frames - 1)


def _frames(view: ViewData, idx: np.ndarray, width: int, height: int | None, scale: float | None) -> Iterator[Any]:
    """Rendered frames for the view frame indices ``idx`` (the error strip is drawn once)."""
    strip = error_strip(view, width * SS, STRIP_H * SS) if view.decoded is not None else None
    for f in idx:
        yield render_frame(view, int(f), width, height, scale=scale, _strip=strip)


def _require_pillow() -> None:
    try:
        import PIL  # noqa: F401
    except ImportError:
        raise MocapzError("rendering animations needs Pillow (pip install 'mocapz[view]')") from None


def render_animation(view: ViewData, path: str | Path, fps: float | None = None, width: int = 960,
                     height: int | None = None, scale: float | None = None, force: bool = False) -> dict[str, Any]:
    """Write the side-by-side animation to ``path`` (``.gif``, or ``.mp4`` with imageio-ffmpeg).

    Args:
        fps: output frame rate (default 20 for GIF, 30 for MP4); the clip plays at its real speed.
        width, height: output size in pixels (height default: suited to the panes).
        scale: error shown fully red, file units (default: the view's colour scale or the clip's max error).
        force: overwrite an existing file.

    Returns:
        ``{"path", "frames", "fps", "width", "height", "bytes"}``.
    """
    _require_pillow()
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in ANIMATION_SUFFIXES:
        raise OptionError(f"{path}: animation must be .gif or .mp4, not {suffix or 'no extension'!r}")
    if width < 64 or width > 4096:
        raise OptionError(f"animation width {width} is out of range (64..4096)")
    fps = float(fps if fps is not None else (20 if suffix == ".gif" else 30))
    if suffix == ".mp4":  # H.264 in yuv420p needs even sizes
        width += width % 2
        height = None if height is None else height + height % 2
    idx = animation_frames(view, fps)
    if suffix == ".gif" and len(idx) > MAX_GIF_FRAMES:
        raise OptionError(f"{path}: {len(idx)} GIF frames is too many (at most {MAX_GIF_FRAMES}): show a part of "
                          f"the clip with --start / --end, lower --fps, or write an .mp4")
    if suffix == ".gif":
        info = _write_gif(view, path, idx, fps, width, height, scale, force)
    else:
        info = _write_mp4(view, path, idx, fps, width, height, scale, force)
    info.update(path=str(path), frames=int(len(idx)), fps=fps, bytes=path.stat().st_size)
    return info


def _write_gif(view: ViewData, path: Path, idx: np.ndarray, fps: float, width: int, height: int | None,
               scale: float | None, force: bool) -> dict[str, Any]:
    from PIL import Image

    # One palette for every frame (no flicker, better LZW), from a montage of frames across the clip.
    picks = sorted({int(idx[k]) for k in np.linspace(0, len(idx) - 1, min(6, len(idx))).round().astype(int)})
    samples = [render_frame(view, f, width, height, scale=scale) for f in picks]
    w, h = samples[0].size
    montage = Image.new("RGB", (w, h * len(samples)))
    for k, im in enumerate(samples):
        montage.paste(im, (0, k * h))
    palette = _gif_palette(montage)
    frames = (im.quantize(palette=palette, dither=Image.Dither.NONE) for im in _frames(view, idx, width, height, scale))
    first = next(frames)
    duration = max(20, int(round(1000.0 / fps / 10.0)) * 10)

    def write(tmp: Path) -> None:
        first.save(tmp, format="GIF", save_all=True, append_images=frames, duration=duration, loop=0,
                   optimize=False, disposal=1)

    atomic_write(path, write, force=force)
    return {"width": w, "height": h}


def _gif_palette(montage: Any) -> Any:
    """A palette image: 48 colours of the error ramp (kept exact) and 207 chosen from sample frames."""
    from PIL import Image

    ramp = [error_rgb(k / 47, 1.0) for k in range(48)]
    picked = montage.quantize(colors=207, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    colours = list(picked.getpalette() or [])[: 3 * 207]
    colours += [v for rgb in ramp for v in rgb]
    pal = Image.new("P", (1, 1))
    pal.putpalette(colours + [0] * (768 - len(colours)))
    return pal


def _write_mp4(view: ViewData, path: Path, idx: np.ndarray, fps: float, width: int, height: int | None,
               scale: float | None, force: bool) -> dict[str, Any]:
    """H.264 MP4 through the ffmpeg binary that the optional package imageio-ffmpeg ships."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise MocapzError("writing .mp4 needs the optional package imageio-ffmpeg (pip install 'mocapz[video]'); "
                          ".gif needs nothing more") from None
    size: dict[str, Any] = {}

    def write(tmp: Path) -> None:
        frames = _frames(view, idx, width, height, scale)
        first = next(frames)
        size.update(width=first.width, height=first.height)
        out = imageio_ffmpeg.write_frames(str(tmp), first.size, fps=fps, codec="libx264", quality=8,
                                          macro_block_size=2, ffmpeg_log_level="error", output_params=["-f", "mp4"])
        out.send(None)
        try:
            out.send(first.tobytes())
            for im in frames:
                out.send(im.tobytes())
        finally:
            out.close()

    try:
        atomic_write(path, write, force=force)
    except (OSError, RuntimeError) as exc:
        raise MocapzError(f"{path}: ffmpeg failed: {exc}") from None
    return size
