"""See original and decoded motion together: a self-contained HTML player and GIF / MP4 animations.

>>> from mocapz.viewer import prepare_view, write_page, render_animation
>>> view = prepare_view(original, decoded, compression={"compressed_bytes": 2795, "codec": "pga"})
>>> write_page(view, "page.html")
>>> render_animation(view, "clip.gif")
"""

from __future__ import annotations

from mocapz.viewer.animation import render_animation
from mocapz.viewer.data import ViewData, load_motion, prepare_view
from mocapz.viewer.frame import render_frame
from mocapz.viewer.page import build_page, write_page

__all__ = ["ViewData", "build_page", "load_motion", "prepare_view", "render_animation", "render_frame", "write_page"]
