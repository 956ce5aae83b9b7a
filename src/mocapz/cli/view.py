"""``mocapz view``: see an original and a decoded motion together (HTML player, GIF or MP4).

Registered in :mod:`mocapz.cli.main` with ``cli.add_command(view)``.
"""

from __future__ import annotations

from pathlib import Path

import click

from mocapz.cli.common import Say, message_flags
from mocapz.errors import MocapzError, OptionError

PAGE_SUFFIXES = (".html", ".htm")


@click.command(name="view")
@click.argument("original", type=click.Path(path_type=Path))
@click.argument("decoded", type=click.Path(path_type=Path), required=False)
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="HTML page to write: one self-contained file that works offline")
@click.option("--gif", "animation", type=click.Path(path_type=Path), default=None,
              help="also (or instead) render the side-by-side animation: .gif, or .mp4 (needs imageio-ffmpeg)")
@click.option("--fps", type=float, default=None, help="animation frame rate (default 20 for .gif, 30 for .mp4)")
@click.option("--width", type=int, default=960, show_default=True, help="animation width in pixels")
@click.option("--start", type=float, default=None, help="show the clip from this time (seconds)")
@click.option("--end", type=float, default=None, help="show the clip up to this time (seconds)")
@click.option("--scale", "color_scale", default=None,
              help="error shown fully red: file units or with a unit (2cm, 5mm); default: the clip's max error")
@click.option("--asf", type=click.Path(path_type=Path), default=None, help="skeleton for an .amc ORIGINAL")
@click.option("-f", "--force", is_flag=True, help="overwrite existing outputs")
@message_flags
def view(original: Path, decoded: Path | None, output: Path | None, animation: Path | None, fps: float | None,
         width: int, start: float | None, end: float | None, color_scale: str | None, asf: Path | None,
         force: bool, quiet: bool, verbose: bool) -> None:
    """Show ORIGINAL and DECODED (a motion file or a .mcz) side by side, overlaid, errors in colour.

    ORIGINAL is a motion file (.bvh, .amc, .c3d, .trc) or a .mcz; DECODED, optional, is compared with it.
    Write an HTML page with -o (play, scrub, orbit the camera, error strip) and / or an animation with --gif.
    """
    from mocapz.model.units import length_in_file_units
    from mocapz.viewer import load_motion, prepare_view, render_animation, write_page

    if output is None and animation is None:
        raise click.UsageError("nothing to write: give -o PAGE.html and / or --gif OUT.gif")
    if output is not None and output.suffix.lower() not in PAGE_SUFFIXES:
        raise OptionError(f"{output}: the page must be an .html file")
    if animation is not None and animation.suffix.lower() not in (".gif", ".mp4"):
        raise OptionError(f"{animation}: the animation must be a .gif or .mp4 file")
    for p in (output, animation):  # refuse before the (slow) work, not after it
        if p is not None and p.exists() and not force:
            raise MocapzError(f"{p}: output exists (use -f to overwrite)")
    say = Say(quiet, verbose)
    orig, _ = load_motion(original, asf)
    dec, compression = (None, {}) if decoded is None else load_motion(decoded)
    unit_cm = orig.skeleton.unit_cm if hasattr(orig, "skeleton") else orig.unit_cm
    scale = None if color_scale is None else length_in_file_units(color_scale, unit_cm, "--scale")
    if scale is not None and scale <= 0:
        raise OptionError("--scale must be positive")
    try:
        with say.progress("preparing the view"):
            v = prepare_view(orig, dec, compression=compression, start=start, end=end, color_scale=scale)
    except OptionError:
        raise
    except MocapzError as exc:
        raise exc.at(decoded) from None
    if output is not None:
        size = write_page(v, output, force=force)
        say.info(f"{output}: {size:,} bytes, {v.n_frames} frames, {v.n_points} points"
                 + (f" (every {v.step}th frame)" if v.step > 1 else ""))
    if animation is not None:
        full = prepare_view(orig, dec, compression=compression, start=start, end=end, color_scale=scale,
                            budget=None) if v.step > 1 else v
        with say.progress(f"rendering {animation.name}"):
            info = render_animation(full, animation, fps=fps, width=width, scale=scale, force=force)
        say.info(f"{animation}: {info['bytes']:,} bytes, {info['frames']} frames at {info['fps']:g} fps, "
                   f"{info['width']}x{info['height']}")
