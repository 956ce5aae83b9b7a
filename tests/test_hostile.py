"""Hostile ``.mcz`` files: a valid container and checksum around damaged content (a writer bug, a crafted
file). A seeded fuzzer over every registered codec and over the layout header.

Whatever the damage, ``mocapz.decompress`` gives a motion of the shape the layout announces, or a
:class:`mocapz.FormatError` raised by the code that read the bad bytes: never another exception, never
the API's catch-all ("the ... decoder failed", which is kept for real bugs), never a MemoryError (the
decodes run under an address-space cap of 256 MiB above what the process already uses) and never a decode
that runs for seconds.
"""

from __future__ import annotations

import json
import signal
import threading
import warnings
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import cache
from typing import Any

import numpy as np
import pytest
import zstandard
from conftest import data_path

import mocapz
from mocapz import FormatError
from mocapz.codecs import all_codecs
from mocapz.format.container import Container
from mocapz.format.layout import _DICT, decode_header, decode_layout

KINDS = ("skeleton", "markers")
#: every registered codec with every kind of data it takes
PAIRS = [(info.name, kind) for info in all_codecs() for kind in KINDS if kind in info.kinds]
MEMORY_HEADROOM = 1 << 28  # bytes of address space a decode may add
TIME_LIMIT = 5.0  # seconds one decode may take
HUGE = (1 << 16, 1 << 24, 1 << 28, 1 << 31, 1 << 40, (1 << 63) - 1, 1 << 70)
#: values put where the layout has something else (wrong types, huge, negative, not finite)
HOSTILE: tuple[Any, ...] = (None, True, -1, 0, 2**31, 10**30, -(10**30), 1.5, float("nan"), float("inf"), "x", "",
                            [], [[]], [None], [[1, 2]], {}, {"a": 1})


# ------------------------------------------------------------------------------------------ fixtures
@cache
def _clip(kind: str) -> mocapz.Motion | mocapz.MarkerMotion:
    """40 frames of CMU 09_06 (BVH skeleton) or of 01_01 (C3D markers, with gaps)."""
    path = "cmu/bvh/09_06.bvh" if kind == "skeleton" else "cmu/c3d/01_01.c3d"
    return mocapz.load(data_path(path)).slice(0, 40)


@cache
def _file(codec: str, kind: str) -> bytes:
    """A small valid ``.mcz`` of :func:`_clip` (default options)."""
    return mocapz.compress(_clip(kind), codec=codec)


def _files(kind: str) -> list[bytes]:
    """The valid file of every codec taking ``kind`` data."""
    return [_file(c, k) for c, k in PAIRS if k == kind]


def _uvarint(value: int) -> bytes:
    """LEB128, written apart from mocapz.format.entropy (any size: the 10-byte ones are hostile too)."""
    out = bytearray()
    while True:
        b, value = value & 0x7F, value >> 7
        out.append(b | (0x80 if value else 0))
        if not value:
            return bytes(out)


# ------------------------------------------------------------------------------------ the referee
class _TooSlow(BaseException):
    """Raised by the alarm; not an Exception, so that no ``except Exception`` in a decoder can hide it."""


@contextmanager
def _limits() -> Iterator[None]:
    """Address space capped at what the process uses plus MEMORY_HEADROOM; SIGALRM after TIME_LIMIT (where the
    platform and thread allow); numpy's floating-point warnings silenced (damaged values may overflow)."""
    restore: list[Callable[[], None]] = []
    try:
        import resource

        with open("/proc/self/status") as f:
            vm = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:"))
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        cap = vm + MEMORY_HEADROOM if hard == resource.RLIM_INFINITY else min(hard, vm + MEMORY_HEADROOM)
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
        restore.append(lambda: resource.setrlimit(resource.RLIMIT_AS, (soft, hard)))
    except (ImportError, OSError, StopIteration, ValueError):  # pragma: no cover - not Linux
        pass
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            yield
        finally:
            for undo in restore:
                undo()


def _alarm(_signum: int, _frame: object) -> None:
    raise _TooSlow


def _verdict(data: bytes) -> str | None:
    """None when ``decompress(data)`` behaves (a decoder's own FormatError, or a motion of the shape its layout
    announces); else what went wrong."""
    timed = hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
    if timed:
        previous = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT)
    try:
        motion = mocapz.decompress(data)
    except FormatError as exc:
        return f"catch-all: {exc.problem[:150]}" if "decoder failed" in exc.problem else None
    except _TooSlow:
        return f"decode took over {TIME_LIMIT} s"
    except Exception as exc:  # noqa: BLE001 - the point of the test
        return f"{type(exc).__name__}: {str(exc)[:150]}"
    finally:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
    header = decode_header(Container.from_bytes(data).layout)
    if motion.kind != header.kind or motion.values.shape != header.value_shape:
        return f"decoded {motion.kind} {motion.values.shape}, the layout says {header.kind} {header.value_shape}"
    return None


def _referee(cases: Iterator[tuple[str, bytes]]) -> tuple[int, dict[str, str]]:
    """Run every case under :func:`_limits`; the number of cases and the misbehaving ones."""
    bad: dict[str, str] = {}
    count = 0
    with _limits():
        for name, data in cases:
            count += 1
            if (r := _verdict(data)) is not None:
                bad[name] = r
    return count, bad


def _report(bad: dict[str, str]) -> str:
    return f"{len(bad)} hostile files misbehave:\n" + "\n".join(f"  {k}: {v}" for k, v in list(bad.items())[:40])


# ----------------------------------------------------------------------------------- damaged sections
def _damage(payload: bytes, rng: np.random.Generator, others: list[bytes]) -> Iterator[tuple[str, bytes]]:
    """Ways to damage one section's payload (all seeded by ``rng``)."""
    n = len(payload)

    def rnd(k: int) -> bytes:
        return rng.integers(0, 256, k, dtype=np.uint8).tobytes()

    yield "empty", b""
    yield "first byte only", payload[:1]
    yield "first half", payload[: n // 2]
    yield "last byte cut", payload[:-1]
    yield "zeroed", bytes(n)
    yield "all 0xff", b"\xff" * n
    yield "random", rnd(n)
    yield "random 5 bytes", rnd(5)
    yield "appended bytes", payload + rnd(7)
    places = range(n) if n <= 40 else [*range(6), *sorted(rng.choice(range(6, n), 6, replace=False).tolist())]
    for p in places:  # a huge number where a varint (count, shape, length) may be: all sizes near the start
        for v in HUGE if p < 6 else HUGE[2::3]:
            yield f"varint {v:#x} at {p}", payload[:p] + _uvarint(v) + payload[p + 1 :]
    for _ in range(8):
        i, bit = int(rng.integers(max(n, 1))), int(rng.integers(8))
        if n:
            yield f"bit {bit} of byte {i} flipped", payload[:i] + bytes([payload[i] ^ (1 << bit)]) + payload[i + 1 :]
    for _ in range(6):
        i, v = int(rng.integers(max(n, 1))), int(rng.choice([0x00, 0x01, 0x02, 0x7F, 0x80, 0xFF]))
        if n:
            yield f"byte {i} set to {v:#x}", payload[:i] + bytes([v]) + payload[i + 1 :]
    for j in rng.choice(len(others), size=min(2, len(others)), replace=False):
        yield f"replaced by section #{j}", others[int(j)]


def _section_cases(codec: str, kind: str) -> Iterator[tuple[str, bytes]]:
    """Every section of the codec's file missing, then damaged in every way of :func:`_damage`."""
    box = Container.from_bytes(_file(codec, kind))
    payloads = list(box.sections.values())
    for key, payload in box.sections.items():
        rng = np.random.default_rng(zlib.crc32(f"{codec}/{kind}/{key}".encode()))
        missing = {k: v for k, v in box.sections.items() if k != key}
        yield f"{key}: missing", Container(box.codec, box.codec_version, box.layout, missing).to_bytes()
        for how, bad in _damage(payload, rng, payloads):
            sections = dict(box.sections, **{key: bad})
            yield f"{key}: {how}", Container(box.codec, box.codec_version, box.layout, sections).to_bytes()


@pytest.mark.parametrize(("codec", "kind"), PAIRS)
def test_damaged_sections(codec: str, kind: str) -> None:
    _file(codec, kind)  # made before the limits apply
    count, bad = _referee(_section_cases(codec, kind))
    assert count > 100
    assert not bad, _report(bad)


#: exact extras; analogs and tracks rounded to a precision (their stepped word matrices); extras in 3 blocks
EXTRAS_CASES = ({}, {"analog_precision": 0.01, "track_precision": "angles=0.01,forces=0.1,moments=10,powers=0.01"},
                {"block": 20})


def c3d_file(options: dict[str, Any]) -> bytes:
    """20 frames (60 in blocks) of the Plug-in-Gait trial, lossless, with the extras ``options`` ask for."""
    pig = mocapz.load(data_path("other/markers/btkdata/c3d_samples/PiG_Motion-FlatFoot-Full.c3d"))
    return mocapz.compress(pig.slice(0, 60 if "block" in options else 20), codec="lossless", **options)


def _c3d_cases(options: dict[str, Any]) -> Iterator[tuple[str, bytes]]:
    """The ``c3d.*`` sections (parameters, residual words, model-output tracks, analogs, missing samples) of
    :func:`c3d_file`, each missing, then damaged in every way of :func:`_damage`."""
    box = Container.from_bytes(c3d_file(options))
    mine = [k for k in box.sections if k.startswith("c3d.")]
    assert len(mine) == (14 if "block" in options else 5)
    if "analog_precision" in options:  # the stepped form is what is damaged (20 frames: one block)
        assert box.sections["c3d.trk"][0] == box.sections["c3d.ana"][0] == 0x40
    payloads = list(box.sections.values())
    for key in mine:
        rng = np.random.default_rng(zlib.crc32(f"c3d/{key}".encode()))
        missing = {k: v for k, v in box.sections.items() if k != key}
        yield f"{key}: missing", Container(box.codec, box.codec_version, box.layout, missing).to_bytes()
        for how, bad in _damage(box.sections[key], rng, payloads):
            yield f"{key}: {how}", Container(box.codec, box.codec_version, box.layout,
                                             dict(box.sections, **{key: bad})).to_bytes()


@pytest.mark.parametrize("options", EXTRAS_CASES, ids=("exact", "precision", "blocks"))
def test_damaged_c3d_sections(options: dict[str, Any]) -> None:
    """Damaged C3D extras give a FormatError or extras that describe the decoded clip and write a file."""
    from mocapz.io.c3d_raw import c3d_bytes

    count, bad = _referee(_c3d_cases(options))
    assert count > 100
    assert not bad, _report(bad)
    with _limits():
        for name, data in _c3d_cases(options):
            try:
                motion = mocapz.decompress(data)
            except FormatError:
                continue
            extras = motion.metadata["c3d"]
            assert extras.matches(motion.n_frames, motion.n_markers), name
            c3d_bytes(motion.positions, extras)


# ------------------------------------------------------------------------------------- damaged layout
def _raw_layout(layout: bytes) -> tuple[dict[str, Any], bytes]:
    """The layout's JSON as written (offsets possibly in the numeric block) and its numeric block."""
    n, pos, shift = 0, 0, 0
    while True:
        b = layout[pos]
        n |= (b & 0x7F) << shift
        pos, shift = pos + 1, shift + 7
        if b < 0x80:
            break
    text = zstandard.ZstdDecompressor(dict_data=_DICT).decompress(layout[pos : pos + n])
    return json.loads(text), layout[pos + n :]


def _sealed(data: bytes, d: dict[str, Any], block: bytes = b"") -> bytes:
    """``data`` with its layout replaced by the JSON ``d`` and numeric ``block`` (valid zstd and checksum)."""
    box = Container.from_bytes(data)
    z = zstandard.ZstdCompressor(dict_data=_DICT).compress(json.dumps(d).encode())
    return Container(box.codec, box.codec_version, _uvarint(len(z)) + z + block, box.sections).to_bytes()


def _hostile_edits(d: dict[str, Any]) -> Iterator[tuple[str, Callable[[dict[str, Any]], None]]]:
    """Edits of a layout dict: every key deleted or given a hostile value; list items and nested items too."""
    def put(path: tuple[Any, ...], value: Any) -> Callable[[dict[str, Any]], None]:
        def edit(x: dict[str, Any]) -> None:
            for p in path[:-1]:
                x = x[p]
            x[path[-1]] = value
        return edit

    def drop(key: str) -> Callable[[dict[str, Any]], None]:
        return lambda x: x.pop(key)

    for key in [*d, "axis", "extra", "num_dec"]:
        if key in d:
            yield f"{key} deleted", drop(key)
        for v in HOSTILE:
            yield f"{key}={v!r}", put((key,), v)
        value = d.get(key)
        if isinstance(value, list) and value:
            for i in (0, -1):
                for v in HOSTILE:
                    yield f"{key}[{i}]={v!r}", put((key, i), v)
            if isinstance(value[0], list) and value[0]:
                for j in range(len(value[0])):
                    for v in HOSTILE:
                        yield f"{key}[0][{j}]={v!r}", put((key, 0, j), v)


def _layout_cases(kind: str) -> Iterator[tuple[str, bytes]]:
    """Hostile values in the layout JSON, both as the writer stores it (offsets in the numeric block) and with
    the offsets in the JSON; damaged numeric blocks. Each case on the file of the next codec in turn."""
    files = _files(kind)
    i = 0
    for as_written in (True, False):
        d0, block = _raw_layout(Container.from_bytes(files[0]).layout)
        if not as_written:
            d0, block = decode_layout(Container.from_bytes(files[0]).layout), b""
        for name, edit in _hostile_edits(d0):
            d = json.loads(json.dumps(d0))
            edit(d)
            i += 1
            yield f"{'' if as_written else 'offsets in JSON, '}{name}", _sealed(files[i % len(files)], d, block)
    d0, block = _raw_layout(Container.from_bytes(files[0]).layout)
    if block:
        rng = np.random.default_rng(11)
        blocks = {"block empty": b"", "block cut": block[:-1], "block appended": block + b"\x00",
                  "block zeroed": bytes(len(block)),
                  "block random": rng.integers(0, 256, len(block), np.uint8).tobytes()}
        blocks |= {f"block varint {v:#x} at {p}": block[:p] + _uvarint(v) + block[p + 1 :]
                   for v in HUGE for p in (0, len(block) // 2, len(block) - 1)}
        for name, b in blocks.items():
            i += 1
            yield name, _sealed(files[i % len(files)], d0, b)


@pytest.mark.parametrize("kind", KINDS)
def test_damaged_layout(kind: str) -> None:
    _files(kind)  # the valid files are made before the limits apply (encoders import scipy.cluster, numba...)
    count, bad = _referee(_layout_cases(kind))
    assert count > 200
    assert not bad, _report(bad)


def _inconsistent_edits(d: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any]]]:
    """Layouts of valid types that disagree with the sections (counts, shapes, tree, units)."""
    for frames in (0, 1, 2, 3, 39, 41, 80, 1000, 10**6, 10**7):
        yield f"frames={frames}", {"frames": frames}
    yield "frame_rate=1e-300", {"frame_rate": 1e-300}
    yield "frame_rate=1e300", {"frame_rate": 1e300}
    if d["kind"] == "markers":
        labels = d["labels"]
        for name, new in (("one marker fewer", labels[:-1]), ("one marker more", [*labels, "EXTRA"]),
                          ("one marker", labels[:1]), ("no markers", []), ("labels doubled", labels * 2)):
            yield name, {"labels": new}
        yield "decimals=-1", {"decimals": -1}
        yield "decimals=400", {"decimals": 400}
        yield "units=furlongs", {"units": "furlongs"}
        return
    n, chans = len(d["names"]), d["channels"]
    yield "one joint fewer", {k: d[k][:-1] for k in ("names", "parents", "channels", "orders", "offsets")} | {
        "end_sites": [e for e in d["end_sites"] if e[0] < n - 1]}
    yield "root without channels", {"channels": ["", *chans[1:]]}
    yield "no channels at all", {"channels": [""] * n}
    yield "root rotations only", {"channels": ["ZrotYrotXrot", *chans[1:]], "orders": ["ZYX", *d["orders"][1:]]}
    yield "a joint with one channel more", {"channels": [chans[0], chans[1] + "Xpos", *chans[2:]]}
    yield "a joint with a channel fewer", {"channels": [chans[0], chans[1][:8], *chans[2:]]}
    yield "orders empty", {"orders": [""] * n}
    yield "orders all XYZ", {"orders": ["XYZ"] * n}
    yield "orders XYZW", {"orders": ["XYZW"] * n}
    yield "orders XXX", {"orders": ["XXX"] * n}
    yield "flat tree", {"parents": [-1] + [0] * (n - 1)}
    yield "chain tree", {"parents": list(range(-1, n - 1))}
    yield "two roots", {"parents": [-1, -1, *d["parents"][2:]]}
    yield "no end sites", {"end_sites": []}
    yield "end sites all on the root", {"end_sites": [[0, *e[1:]] for e in d["end_sites"]]}
    yield "offsets zero", {"offsets": [[0, 0, 0]] * n}
    yield "offsets huge", {"offsets": [[1e300, -1e300, 1e300]] * n}
    yield "angle_unit rad", {"angle_unit": "rad"}
    yield "angle_unit gon", {"angle_unit": "gon"}
    yield "unit_cm 0", {"unit_cm": 0}
    yield "unit_cm -1", {"unit_cm": -1}
    yield "unit_cm null", {"unit_cm": None}
    yield "decimals all 15", {"decimals": [15] * len(d["decimals"])}
    yield "decimals short", {"decimals": d["decimals"][:-1]}
    yield "axis not rotations", {"axis": [0.0] * (9 * n)}
    yield "axis identity", {"axis": np.tile(np.eye(3).ravel(), n).tolist()}


def _inconsistent_cases(codec: str, kind: str) -> Iterator[tuple[str, bytes]]:
    data = _file(codec, kind)
    d0 = decode_layout(Container.from_bytes(data).layout)
    for name, change in _inconsistent_edits(d0):
        yield name, _sealed(data, json.loads(json.dumps(d0)) | change)


@pytest.mark.parametrize(("codec", "kind"), PAIRS)
def test_layout_disagreeing_with_sections(codec: str, kind: str) -> None:
    count, bad = _referee(_inconsistent_cases(codec, kind))
    assert count > 10
    assert not bad, _report(bad)
