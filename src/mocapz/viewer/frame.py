"""Draw one frame of the side-by-side animation with Pillow, without a browser.

Frames are drawn at twice the output size and reduced (anti-aliasing): original, decoded (points coloured by
error, green to red) and an overlay, over a ground grid, with the clip's figures on top and the error over time
below. The camera follows the body from the page's default three-quarter side view.
:mod:`mocapz.viewer.animation` puts the frames together into a GIF or MP4.
"""

from __future__ import annotations

import colorsys
import math
from functools import lru_cache
from typing import Any

import numpy as np

from mocapz.errors import OptionError
from mocapz.viewer.data import ViewData, default_yaw

SS = 2  # supersampling factor
BG = (21, 24, 29)
GRID = (44, 50, 60)
SHADOW = (12, 14, 17)
ORIG = (160, 182, 212)
GHOST = (92, 99, 112)
DISPLACEMENT = (255, 90, 90)
TEXT = (207, 214, 224)
DIM = (138, 148, 163)
HEAD_H = 26  # pixels above the panes (name, figures, legend)
STRIP_H = 54  # pixels of the error strip below


def error_rgb(e: float, scale: float) -> tuple[int, int, int]:
    """Green (no error) to red (``scale`` and above); grey for a missing sample. Same ramp as the page."""
    if not e >= 0:
        return (90, 90, 90)
    r = min(e / scale, 1.0) if scale > 0 else 0.0
    red, green, blue = colorsys.hls_to_rgb(120 * (1 - r) / 360, 0.5 + 0.05 * (1 - r), 0.85)
    return (round(255 * red), round(255 * green), round(255 * blue))


@lru_cache(maxsize=8)
def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError, ImportError):  # Pillow without FreeType: the small bitmap font
        return ImageFont.load_default()


class _Camera:
    """Perspective camera orbiting ``target`` at ``yaw`` / ``pitch`` (radians), Z up, as in the page."""

    def __init__(self, target: np.ndarray, yaw: float, pitch: float, dist: float, width: float, height: float,
                 near: float) -> None:
        cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
        self.eye = target + dist * np.array([cp * cy, cp * sy, sp])
        self.fw = np.array([-cp * cy, -cp * sy, -sp])
        self.rt = np.array([-sy, cy, 0.0])
        self.up = np.cross(self.rt, self.fw)
        self.focal = 0.5 * height / math.tan(math.radians(20.0))
        self.cx, self.cy, self.near, self.dist = width / 2, height / 2, near, dist

    def to_cam(self, pts: np.ndarray) -> np.ndarray:
        d = np.asarray(pts, dtype=np.float64) - self.eye
        return np.stack([d @ self.rt, d @ self.up, d @ self.fw], axis=-1)

    def screen(self, c: np.ndarray) -> np.ndarray:
        z = np.maximum(c[..., 2], self.near)
        return np.stack([self.cx + c[..., 0] * self.focal / z, self.cy - c[..., 1] * self.focal / z], axis=-1)

    def segment(self, a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float] | None:
        """Screen end points of a camera-space segment clipped at the near plane, or None if behind."""
        if a[2] < self.near and b[2] < self.near:
            return None
        if a[2] < self.near:
            a = a + (self.near - a[2]) / (b[2] - a[2]) * (b - a)
        elif b[2] < self.near:
            b = b + (self.near - b[2]) / (a[2] - b[2]) * (a - b)
        p, q = self.screen(a), self.screen(b)
        return (float(p[0]), float(p[1]), float(q[0]), float(q[1]))


def _persp(cam: _Camera, z: float) -> float:
    return min(2.2, max(0.45, cam.dist / max(z, 1e-9)))


def _draw_grid(draw: Any, cam: _Camera, view: ViewData, target: np.ndarray, x0: int, x1: int) -> None:
    """Ground grid lines (one pixel, aliased) of the pane between columns ``x0`` and ``x1``."""
    g, n = view.grid, 8
    cx, cy = round(target[0] / g) * g, round(target[1] / g) * g
    for i in range(-n, n + 1):
        for a, b in (((cx + i * g, cy - n * g), (cx + i * g, cy + n * g)),
                     ((cx - n * g, cy + i * g), (cx + n * g, cy + i * g))):
            ends = cam.to_cam(np.array([[a[0], a[1], view.floor], [b[0], b[1], view.floor]]))
            s = cam.segment(ends[0], ends[1])
            if s:
                seg = _clip_x(s, 0, x1 - x0 - 1)
                if seg:
                    draw.line((seg[0] + x0, seg[1], seg[2] + x0, seg[3]), fill=GRID, width=1)


def _clip_x(s: tuple[float, float, float, float], lo: float, hi: float) -> tuple[float, float, float, float] | None:
    """A screen segment clipped to the columns ``lo..hi`` (panes share one image)."""
    x1, y1, x2, y2 = s
    if x1 > x2:
        x1, y1, x2, y2 = x2, y2, x1, y1
    if x2 < lo or x1 > hi:
        return None
    if x2 - x1 > 1e-9:
        if x1 < lo:
            y1, x1 = y1 + (lo - x1) / (x2 - x1) * (y2 - y1), lo
        if x2 > hi:
            y2, x2 = y1 + (hi - x1) / (x2 - x1) * (y2 - y1), hi
    return (x1, y1, x2, y2)


def _draw_figure(draw: Any, cam: _Camera, view: ViewData, pts: np.ndarray, f: int, ox: int,
                 color: tuple[int, int, int] | None, width: float, radius: float, scale: float,
                 shadow: bool = True) -> None:
    """Bones and points of one pose, far to near; ``color=None`` colours them by error."""
    markers = view.kind == "markers"
    ok = np.isfinite(pts).all(axis=1)
    if shadow:
        flat = pts.copy()
        flat[:, 2] = view.floor
        fc = cam.to_cam(np.nan_to_num(flat))
        for i, j in view.bones:
            if ok[i] and ok[j]:
                s = cam.segment(fc[i], fc[j])
                if s:
                    draw.line((s[0] + ox, s[1], s[2] + ox, s[3]), fill=SHADOW,
                              width=round((1.5 if markers else 4) * SS))
    c = cam.to_cam(np.nan_to_num(pts))
    err = view.errors[f] if view.errors is not None else np.zeros(len(pts))
    items: list[tuple[float, int, int, int]] = []
    for i, j in view.bones:
        if ok[i] and ok[j] and (c[i, 2] > cam.near or c[j, 2] > cam.near):
            items.append((0.5 * (c[i, 2] + c[j, 2]), 0, int(i), int(j)))
    for p in np.flatnonzero(ok & (c[:, 2] > cam.near)):
        items.append((float(c[p, 2]), 1, int(p), int(p)))
    items.sort(key=lambda t: (-t[0], t[1], t[2]))
    for z, kind, i, j in items:
        k = _persp(cam, z)
        if kind == 0:
            col = color or error_rgb(0.5 * (err[i] + err[j]), scale)
            if markers:
                col = tuple(round(0.35 * v + 0.65 * b) for v, b in zip(col, BG, strict=True))
            s = cam.segment(c[i], c[j])
            if s:
                draw.line((s[0] + ox, s[1], s[2] + ox, s[3]), fill=col, width=max(1, round(width * SS * k)))
        else:
            x, y = cam.screen(c[i])
            r = radius * SS * k
            draw.ellipse((x + ox - r, y - r, x + ox + r, y + r), fill=color or error_rgb(err[i], scale))


def _header(view: ViewData) -> str:
    keep = ("codec", "ratio", "distortion", "max error", "ARMS")
    figs = [f"{k} {v}" for k, v in view.figures if k in keep]
    return view.name + ("   " + " \u00b7 ".join(figs) if figs else "")


def error_strip(view: ViewData, w: int, h: int) -> Any:
    """The error-over-time strip, ``w`` x ``h`` at the supersampled size, without the play head."""
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (w, h), BG)
    draw = ImageDraw.Draw(img)
    if view.decoded is None:
        return img
    fmax, fmean = view.frame_error_stats()
    ymax = float(fmax.max()) if fmax.size and fmax.max() > 0 else 1.0
    left, right, top, base = 8 * SS, w - 8 * SS, 16 * SS, h - 4 * SS
    n = view.n_frames
    xs = left + (right - left) * (np.arange(n) + 0.5) / n
    ymean = base - np.minimum(fmean, ymax) / ymax * (base - top)
    ymx = base - np.minimum(fmax, ymax) / ymax * (base - top)
    poly = [(float(xs[0]), float(base))] + list(zip(xs.tolist(), ymean.tolist(), strict=True)) + [
        (float(xs[-1]), float(base))]
    draw.polygon(poly, fill=(140, 100, 50))
    if n > 1:
        draw.line(list(zip(xs.tolist(), ymx.tolist(), strict=True)), fill=(255, 80, 80), width=SS)
    label = f"error over time: max (red) up to {_len(ymax, view)}, mean (orange)"
    draw.text((left, 2 * SS), label, fill=DIM, font=_font(11 * SS))
    return img


def _len(v: float, view: ViewData) -> str:
    return f"{v * view.unit_scale:.3g} {view.unit}"


def _ramp(draw: Any, x: int, y: int, w: int, h: int, scale: float) -> None:
    for k in range(w):
        draw.line((x + k, y, x + k, y + h), fill=error_rgb(scale * k / max(w - 1, 1), scale))


def render_frame(view: ViewData, f: int, width: int = 960, height: int | None = None, *,
                 scale: float | None = None, yaw: float | None = None, _strip: Any = None) -> Any:
    """One animation frame as a PIL RGB image ``width`` x ``height`` (default: a height that suits the panes).

    Everything is drawn at twice the size and reduced (anti-aliasing), except the ground grid: drawn at the
    output size with hard one-pixel lines (it moves with the camera; smooth lines would make GIFs several times
    larger), it fills the background pixels.
    """
    from PIL import Image, ImageDraw

    panes = ["original", "decoded", "overlay"] if view.decoded is not None else ["original"]
    if height is None:
        height = int(round(width * (0.42 if len(panes) == 3 else 1.0)))
        height += height % 2
    head, strip_h = HEAD_H, (STRIP_H if view.decoded is not None else 0)
    view_h = height - head - strip_h
    if view_h < 40 or width < 64:
        raise OptionError(f"animation size {width}x{height} is too small")
    W, H, VH = width * SS, height * SS, view_h * SS
    scale = scale if scale is not None else (view.color_scale or view.error_max or 1e-12)
    layer = Image.new("RGB", (W, H), BG)
    draw = ImageDraw.Draw(layer)
    target = view.center[f]
    near = 0.02 * view.height
    yaw = default_yaw(view) if yaw is None else yaw
    dist = 2.6 * view.height
    pane_img = Image.new("RGB", (W, VH), BG)
    pdraw = ImageDraw.Draw(pane_img)
    grid_img = Image.new("RGB", (width, view_h), BG)
    gdraw = ImageDraw.Draw(grid_img)
    for k, name in enumerate(panes):
        x0, x1 = round(k * W / len(panes)), round((k + 1) * W / len(panes))
        g0, g1 = round(k * width / len(panes)), round((k + 1) * width / len(panes))
        _draw_grid(gdraw, _Camera(target, yaw, 0.22, dist, g1 - g0, view_h, near), view, target, g0, g1)
        cam = _Camera(target, yaw, 0.22, dist, x1 - x0, VH, near)
        a = view.original[f]
        thick = view.kind == "skeleton"
        if name == "original":
            _draw_figure(pdraw, cam, view, a, f, x0, ORIG, 3.2 if thick else 1, 3, scale)
        elif name == "decoded":
            assert view.decoded is not None
            _draw_figure(pdraw, cam, view, view.decoded[f], f, x0, None, 3.2 if thick else 1, 3, scale)
        else:
            assert view.decoded is not None
            _draw_figure(pdraw, cam, view, a, f, x0, GHOST, 7 if thick else 1, 5, scale)
            b = view.decoded[f]
            ca, cb = cam.to_cam(np.nan_to_num(a)), cam.to_cam(np.nan_to_num(b))
            err = view.errors[f] if view.errors is not None else np.zeros(len(a))
            for p in np.flatnonzero(np.isfinite(err) & (err > 0.05 * scale)):
                s = cam.segment(ca[p], cb[p])
                if s:
                    pdraw.line((s[0] + x0, s[1], s[2] + x0, s[3]), fill=DISPLACEMENT, width=SS)
            _draw_figure(pdraw, cam, view, b, f, x0, None, 2.2 if thick else 1, 2.4, scale, shadow=False)
        label = {"original": "original", "decoded": view.decoded_label, "overlay": "overlay (original in grey)"}[name]
        pdraw.text((x0 + 8 * SS, 6 * SS), label, fill=TEXT, font=_font(12 * SS))
        if k:
            gdraw.line((g0, 0, g0, view_h), fill=(44, 50, 60), width=1)
    layer.paste(pane_img, (0, head * SS))
    # header: name, figures, colour legend; time; error strip with the play head
    font = _font(12 * SS)
    draw.text((8 * SS, 6 * SS), _header(view), fill=TEXT, font=font)
    t = (view.first_frame + f * view.step) / (view.frame_rate * view.step)
    tlabel = f"{t:6.2f} s"
    if view.decoded is not None:
        rw, top = 90 * SS, f">= {_len(scale, view)}"
        rx = W - rw - 14 * SS - int(draw.textlength(top, font=font))
        _ramp(draw, rx, 10 * SS, rw, 8 * SS, scale)
        draw.text((rx - 12 * SS, 5 * SS), "0", fill=DIM, font=font)
        draw.text((rx + rw + 6 * SS, 5 * SS), top, fill=DIM, font=font)
        strip = _strip if _strip is not None else error_strip(view, W, strip_h * SS)
        layer.paste(strip, (0, H - strip_h * SS))
        x = 8 * SS + (W - 16 * SS) * (f + 0.5) / view.n_frames
        draw.rectangle((x - SS, H - strip_h * SS + 15 * SS, x + SS, H), fill=(255, 255, 255))
        draw.text((W - 8 * SS - int(draw.textlength(tlabel, font=font)), H - strip_h * SS + 2 * SS), tlabel,
                  fill=TEXT, font=font)
    else:
        draw.text((W - 8 * SS - int(draw.textlength(tlabel, font=font)), 6 * SS), tlabel, fill=TEXT, font=font)
    out = np.asarray(layer.reduce(SS)).copy()
    panes_px = out[head:head + view_h]
    empty = (panes_px == np.array(BG, dtype=np.uint8)).all(axis=-1)
    panes_px[empty] = np.asarray(grid_img)[empty]  # the grid shows where nothing else is drawn
    return Image.fromarray(out)
