"""``mocapz view`` and ``mocapz.metrics.plots``: the self-contained HTML player (checked in real headless Chromium),
GIF / MP4 animations and the error plots.

The browser test drives Debian's ``chromium`` through the DevTools protocol over a pipe (no port, no network):
it loads the page from a file, checks the page draws (non-blank canvases, measured by the page itself from
``getImageData``), that the frame counter advances on play, that dragging orbits the camera, that no script
error occurs, and takes a screenshot. It skips, saying so, only where no Chromium is installed
(``bash .ci/install-chromium.sh`` installs it).
"""

from __future__ import annotations

import base64
import json
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path
from PIL import Image

import mocapz
from mocapz.cli.view import view as view_command
from mocapz.errors import FormatError, MocapzError, OptionError
from mocapz.io import load
from mocapz.metrics.plots import plot_errors
from mocapz.model.motion import MarkerMotion
from mocapz.viewer import build_page, prepare_view, render_animation, render_frame, write_page
from mocapz.viewer.page import page_data

pytestmark = pytest.mark.slow  # subprocesses and a browser: make test, not make test-fast

RUN = "cmu/bvh/09_06.bvh"
MOCAPZ = shutil.which("mocapz", path=str(Path(sys.executable).parent)) or str(Path(sys.executable).parent / "mocapz")


@pytest.fixture(scope="module")
def run_motion() -> mocapz.Motion:
    return load(data_path(RUN))


@pytest.fixture(scope="module")
def pga_mcz(run_motion: mocapz.Motion, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """09_06 through the lossy PGA codec, as a .mcz file."""
    p = tmp_path_factory.mktemp("view") / "run.pga.mcz"
    p.write_bytes(mocapz.compress(run_motion, codec="pga"))
    return p


@pytest.fixture(scope="module")
def run_view(run_motion: mocapz.Motion, pga_mcz: Path) -> Any:
    data = pga_mcz.read_bytes()
    return prepare_view(run_motion, mocapz.decompress(data), compression={"compressed_bytes": len(data),
                                                                          "codec": "pga"})


def markers_with_gaps(frames: int = 240, markers: int = 12, labels: list[str] | None = None) -> MarkerMotion:
    """A synthetic marker cloud walking along X (mm, Z up) with a gap in two markers."""
    rng = np.random.default_rng(7)
    t = np.arange(frames) / 120.0
    base = rng.uniform([-200, -150, 0], [200, 150, 1700], size=(markers, 3))
    pos = base[None] + np.stack([1000 * t, np.zeros_like(t), 30 * np.sin(8 * t)], axis=1)[:, None]
    pos[50:80, 3] = np.nan
    pos[100:110, 7] = np.nan
    return MarkerMotion(labels=labels or [f"M{i}" for i in range(markers)], positions=pos, frame_rate=120.0,
                        units="mm", name="synthetic")


def embedded_json(html: str) -> dict[str, Any]:
    m = re.search(r'<script id="mocapz-data" type="application/json">(.*?)</script>', html, re.S)
    assert m, "data block missing"
    return json.loads(m.group(1))


def decode_positions(d: dict[str, Any], key: str) -> np.ndarray:
    q = np.frombuffer(base64.b64decode(d[key]), dtype="<i2").reshape(d["frames"], d["points"], 3).astype(float)
    lo, step = np.array(d["quant"]["lo"]), np.array(d["quant"]["step"])
    return np.where(q == -32768, np.nan, lo + (q + 32767) * step)


# ------------------------------------------------------------------------------------------------- page
def test_page_is_self_contained_deterministic_and_faithful(run_view: Any) -> None:
    html = build_page(run_view)
    assert html == build_page(run_view), "same input must give the same bytes"
    low = html.lower()
    for bad in ("http://", "https://", "<link", "@import", "url(", " src=", "<iframe", "fetch(", "xmlhttprequest"):
        assert bad not in low, f"page references something outside itself: {bad!r}"
    assert len(html) < 400_000
    d = embedded_json(html)
    assert d["frames"] == 142 and d["points"] == 38 and d["step"] == 1
    assert len(d["bones"]) == 2 * 37
    figures = dict(d["figures"])
    assert figures["codec"] == "pga" and figures["ratio"].endswith(": 1") and figures["max error"].endswith(" cm")
    assert "foot skate 0.1 s" in figures and figures["jitter"].endswith(" %")  # a run: no planted 0.1 s
    # positions round trip within the int16 quantisation step, errors within 1/254 of the clip maximum
    step = np.array(d["quant"]["step"])
    assert np.all(np.abs(decode_positions(d, "original") - run_view.original) <= step)
    assert np.all(np.abs(decode_positions(d, "decoded") - run_view.decoded) <= step)
    assert step.max() < 0.01 * run_view.height / 100  # well under a millimetre for a human clip
    e = np.frombuffer(base64.b64decode(d["errors"]), dtype=np.uint8).reshape(142, 38) / 254 * d["err_max"]
    assert np.allclose(e, run_view.errors, atol=d["err_max"] / 254)
    assert d["err_max"] == pytest.approx(run_view.stats["max_err"], rel=1e-6)
    # BVH is Y-up: the viewer's Z is the file's Y
    assert np.allclose(run_view.original[..., 2], run_view_positions_y(run_view), atol=1e-9)


def run_view_positions_y(view: Any) -> np.ndarray:
    return load(data_path(RUN)).positions()[..., 1]


def test_page_escapes_names_and_keeps_gaps(tmp_path: Path) -> None:
    labels = ["a</script><script>alert(1)</script>", "http://example.org/x", "c<!--"] + [f"M{i}" for i in range(9)]
    orig = markers_with_gaps(labels=labels)
    dec = orig.with_positions(orig.positions + np.random.default_rng(1).normal(0, 2.0, orig.positions.shape))
    v = prepare_view(orig, dec)
    html = build_page(v)
    assert html.count("</script>") == 2 and "http://" not in html and "<!--" not in html
    d = embedded_json(html)
    assert d["names"][:3] == labels[:3] and d["kind"] == "markers"
    a = decode_positions(d, "original")
    assert np.isnan(a[50:80, 3]).all() and np.isfinite(a[:50, 3]).all()
    e = np.frombuffer(base64.b64decode(d["errors"]), dtype=np.uint8).reshape(d["frames"], d["points"])
    assert (e[50:80, 3] == 255).all() and (e[:50, 3] < 255).all()
    assert any("missing" in n for n in d["notes"])
    assert figures_units(d) == "cm"


def figures_units(d: dict[str, Any]) -> str:
    return dict(d["figures"])["max error"].split()[-1]


def test_long_clip_is_decimated_with_a_note() -> None:
    orig = markers_with_gaps(frames=3000)
    dec = orig.with_positions(orig.positions + 1.0)
    dec.positions[1234, 5, 0] += 50.0  # one spike that a decimated page must still show
    v = prepare_view(orig, dec, budget=3000)
    assert v.step == 12 and v.n_frames == 250 and v.frame_rate == pytest.approx(10.0)
    assert any("every 12th frame" in n for n in v.notes)
    assert v.error_max == pytest.approx(np.linalg.norm([51.0, 1.0, 1.0]), rel=1e-6)
    assert v.errors is not None and np.nanargmax(v.errors[:, 5]) == 1234 // 12


def test_time_range_and_single_motion(run_motion: mocapz.Motion) -> None:
    v = prepare_view(run_motion, start=0.5, end=1.0)
    assert v.decoded is None and v.errors is None and v.first_frame == 60 and v.n_frames == 60
    d = page_data(v)
    assert d["decoded"] is None and d["errors"] is None and dict(d["figures"]).keys() == {"frames"}
    with pytest.raises(OptionError):
        prepare_view(run_motion, start=3.0)


def test_write_page_refuses_to_overwrite(run_view: Any, tmp_path: Path) -> None:
    p = tmp_path / "page.html"
    size = write_page(run_view, p)
    assert p.stat().st_size == size
    with pytest.raises(MocapzError, match="exists"):
        write_page(run_view, p)
    write_page(run_view, p, force=True)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["page.html"]


# ------------------------------------------------------------------------------------------- animation
def test_gif_animation(run_view: Any, tmp_path: Path) -> None:
    out = tmp_path / "run.gif"
    info = render_animation(run_view, out, fps=10, width=480)
    assert info["frames"] == 11 and out.stat().st_size == info["bytes"]
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == 11 and im.size == (480, info["height"])
        im.seek(0)
        first = np.asarray(im.convert("RGB")).astype(int)
        im.seek(6)
        later = np.asarray(im.convert("RGB")).astype(int)
    assert first.std() > 5 and np.abs(first - later).sum() > 0, "frames must show the motion"
    # the decoded pane holds error colours (green..red): some strongly green pixels
    mid = first[:, 160:320]
    assert ((mid[..., 1] > 150) & (mid[..., 0] < 160) & (mid[..., 2] < 120)).sum() > 20
    again = tmp_path / "again.gif"
    render_animation(run_view, again, fps=10, width=480)
    assert again.read_bytes() == out.read_bytes(), "same input must give the same bytes"
    with pytest.raises(OptionError):
        render_animation(run_view, tmp_path / "x.webm")


def test_render_frame_markers_without_decoded() -> None:
    v = prepare_view(markers_with_gaps())
    im = render_frame(v, 60, width=320)
    assert im.size == (320, 320) and np.asarray(im).std() > 3


def test_mp4_animation(run_view: Any, tmp_path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg", reason="optional extra 'video' (imageio-ffmpeg) not installed")
    out = tmp_path / "run.mp4"
    info = render_animation(run_view, out, fps=15, width=401)
    assert info["width"] == 402 and out.read_bytes()[4:8] == b"ftyp"


# ------------------------------------------------------------------------------------------------- plots
def test_plot_errors(run_motion: mocapz.Motion, pga_mcz: Path, tmp_path: Path) -> None:
    dec = mocapz.decompress(pga_mcz.read_bytes())
    out = tmp_path / "errors.png"
    assert plot_errors(run_motion, dec, out, compressed_bytes=pga_mcz.stat().st_size) == out
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size[0] >= 900 and im.size[1] >= 700
        assert np.asarray(im.convert("L")).std() > 10
    with pytest.raises(MocapzError, match="exists"):
        plot_errors(run_motion, dec, out)
    with pytest.raises(OptionError):
        plot_errors(run_motion, dec, tmp_path / "errors.jpg")
    orig = markers_with_gaps()
    plot_errors(orig, orig.with_positions(orig.positions + 1.0), tmp_path / "markers.svg")
    assert (tmp_path / "markers.svg").read_text().lstrip().startswith("<?xml")
    with pytest.raises(MocapzError):
        plot_errors(run_motion, orig, tmp_path / "mixed.png")


# --------------------------------------------------------------------------------------------------- CLI
def invoke(*args: object) -> Any:
    """Run the view command in-process; mocapz errors propagate as exceptions (as the CLI entry point sees them)."""
    return view_command.main([str(a) for a in args], standalone_mode=False)


def test_view_command(pga_mcz: Path, tmp_path: Path) -> None:
    page, gif = tmp_path / "p.html", tmp_path / "p.gif"
    res = CliRunner().invoke(view_command, [str(data_path(RUN)), str(pga_mcz), "-o", str(page), "--gif", str(gif),
                                            "--fps", "5", "--width", "320", "--scale", "2cm"])
    assert res.exit_code == 0, res.output
    assert "p.html" in res.output and "p.gif" in res.output
    d = embedded_json(page.read_text())
    assert d["scales"][0][0] == "2 cm (chosen)" and d["scales"][0][1] == pytest.approx(2 / (2.54 / 0.45), rel=1e-6)
    with pytest.raises(MocapzError, match="exists"):
        invoke(data_path(RUN), pga_mcz, "-o", page)
    with pytest.raises(FormatError, match="no such file"):
        invoke(tmp_path / "missing.bvh", "-o", tmp_path / "m.html")
    with pytest.raises(MocapzError, match="02_01.bvh"):
        invoke(data_path(RUN), data_path("cmu/bvh/02_01.bvh"), "-o", tmp_path / "m.html")
    with pytest.raises(OptionError):
        invoke(data_path(RUN), "-o", tmp_path / "m.txt")
    bad = tmp_path / "bad.mcz"
    bad.write_bytes(b"not a container")
    with pytest.raises(FormatError, match="bad.mcz"):
        invoke(data_path(RUN), bad, "-o", tmp_path / "m.html")
    res = CliRunner().invoke(view_command, [str(data_path(RUN))])
    assert res.exit_code == 2 and "nothing to write" in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.mcz", "p.gif", "p.html"]


def test_view_is_a_mocapz_command(pga_mcz: Path, tmp_path: Path) -> None:
    """``mocapz view`` through the installed console script (wired in mocapz.cli.main)."""
    res = subprocess.run([MOCAPZ, "view", str(data_path(RUN)), str(pga_mcz), "-o", str(tmp_path / "v.html")],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    res = subprocess.run([MOCAPZ, "view", str(data_path(RUN)), str(pga_mcz), "-o", str(tmp_path / "v.html")],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 1 and len(res.stderr.splitlines()) == 1 and "exists" in res.stderr


# --------------------------------------------------------------------------------------- headless Chromium
def find_chromium() -> str | None:
    env = os.environ.get("MOCAPZ_CHROMIUM")
    if env:
        return env
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class Browser:
    """Headless Chromium driven through the DevTools protocol over a pipe (fds 3 and 4): no port, no network."""

    def __init__(self, exe: str, size: tuple[int, int] = (1400, 1000)) -> None:
        self.profile = tempfile.mkdtemp(prefix="mocapz-chromium-")
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()

        def wire() -> None:  # in the child: the protocol pipe on fds 3 (commands) and 4 (replies)
            a, b = os.dup(to_child), os.dup(from_child)
            os.dup2(a, 3)
            os.dup2(b, 4)

        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-default-apps", "--disable-extensions", "--mute-audio", "--no-default-browser-check",
                f"--user-data-dir={self.profile}", "--remote-debugging-pipe", f"--window-size={size[0]},{size[1]}",
                "about:blank"]
        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=wire, stdin=subprocess.DEVNULL,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(to_child)
        os.close(from_child)
        self._id, self._buf, self.events = 0, b"", []

    def send(self, method: str, params: dict[str, Any] | None = None, session: str | None = None,
             timeout: float = 30.0) -> dict[str, Any]:
        self._id += 1
        msg: dict[str, Any] = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" not in self._buf:
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([self._r], [], [], left)[0]:
                    raise TimeoutError(f"Chromium did not answer {method} within {timeout} s")
                chunk = os.read(self._r, 1 << 20)
                if not chunk:
                    raise RuntimeError("Chromium closed the DevTools pipe")
                self._buf += chunk
            raw, self._buf = self._buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            self.events.append(reply)

    def open(self, url: str) -> str:
        """Open ``url`` in a new tab; return the session id attached to it."""
        target = self.send("Target.createTarget", {"url": url})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.send("Runtime.enable", {}, session)
        return session

    def js(self, session: str, expression: str) -> Any:
        res = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session)
        if "exceptionDetails" in res:
            raise AssertionError(f"script error: {res['exceptionDetails']}")
        return res["result"].get("value")

    def wait_for(self, session: str, expression: str, timeout: float = 15.0) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            v = self.js(session, expression)
            if v:
                return v
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {expression}")

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=5)
        except (OSError, RuntimeError, TimeoutError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)  # our own process group only
            self.proc.wait(timeout=10)
        os.close(self._w)
        os.close(self._r)
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def browser() -> Any:
    exe = find_chromium()
    if exe is None:
        pytest.skip("no Chromium installed: the browser test of `mocapz view` needs Debian's chromium package "
                    "(bash .ci/install-chromium.sh), or MOCAPZ_CHROMIUM=/path/to/chrome")
    b = Browser(exe)
    yield b
    b.close()


STATE = "JSON.stringify(window.mocapzViewer.state())"


def test_page_draws_and_plays_in_chromium(browser: Browser, run_view: Any, tmp_path: Path) -> None:
    page = tmp_path / "run.html"
    write_page(run_view, page)
    s = browser.open(page.as_uri())
    browser.wait_for(s, "document.body && document.body.dataset.ready === '1'")
    st = json.loads(browser.js(s, STATE))
    assert st["frames"] == 142 and st["frame"] == 0 and not st["playing"] and st["hasDecoded"]
    assert st["viewInk"] > 0.01, f"3D view looks blank: {st}"
    assert st["stripInk"] > 0.05, f"error strip looks blank: {st}"
    # play (at 0.1x: the 1.2 s clip takes 12 s to loop, even on a loaded machine): the counter advances
    browser.js(s, "const sp = document.getElementById('speed'); sp.value = '0.1';"
                  "sp.dispatchEvent(new Event('change'))")
    browser.js(s, "document.getElementById('play').click()")
    seen = browser.wait_for(s, "Number(document.body.dataset.frame) > 10 && Number(document.body.dataset.frame)")
    st = json.loads(browser.js(s, STATE))
    assert st["playing"] and seen > 10
    assert re.match(r"frame \d+ / 142", browser.js(s, "document.getElementById('counter').textContent"))
    browser.js(s, "document.getElementById('play').click()")
    browser.js(s, "window.mocapzViewer.seek(70)")
    assert json.loads(browser.js(s, STATE))["frame"] == 70
    browser.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": "ArrowRight", "code": "ArrowRight",
                                            "windowsVirtualKeyCode": 39}, s)
    browser.wait_for(s, "window.mocapzViewer.state().frame === 71")
    # orbit: drag on the canvas with real input events
    yaw = json.loads(browser.js(s, STATE))["yaw"]
    for kind, x in (("mousePressed", 300), ("mouseMoved", 360), ("mouseMoved", 420), ("mouseReleased", 420)):
        browser.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": 300, "button": "left",
                                                  "buttons": 0 if kind == "mouseReleased" else 1, "clickCount": 1}, s)
    browser.wait_for(s, f"window.mocapzViewer.state().yaw !== {yaw}")
    time.sleep(0.2)
    shot = tmp_path / "run.png"
    shot.write_bytes(base64.b64decode(browser.send("Page.captureScreenshot", {"format": "png"}, s)["data"]))
    with Image.open(shot) as im:
        px = np.asarray(im.convert("RGB")).astype(int)
    assert im.size[0] >= 1000 and px.std() > 10
    # strongly green (low-error) skeleton pixels somewhere in the decoded pane
    assert ((px[..., 1] > 150) & (px[..., 0] < 150) & (px[..., 2] < 120)).sum() > 100
    errors = [e for e in browser.events if e.get("method") == "Runtime.exceptionThrown"]
    assert not errors, errors


def test_marker_page_without_decoded_in_chromium(browser: Browser, tmp_path: Path) -> None:
    page = tmp_path / "markers.html"
    write_page(prepare_view(markers_with_gaps()), page)
    s = browser.open(page.as_uri() + "#play")
    browser.wait_for(s, "document.body && document.body.dataset.ready === '1'")
    browser.wait_for(s, "Number(document.body.dataset.frame) > 5")
    st = json.loads(browser.js(s, STATE))
    assert st["mode"] == "original" and not st["hasDecoded"] and st["viewInk"] > 0.005
    shot = tmp_path / "markers.png"
    shot.write_bytes(base64.b64decode(browser.send("Page.captureScreenshot", {"format": "png"}, s)["data"]))
    assert shot.stat().st_size > 10_000
    assert not [e for e in browser.events if e.get("method") == "Runtime.exceptionThrown"]
