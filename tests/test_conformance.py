"""Conformance suite: the same checks run over EVERY registered codec (like numcodecs' common checks and
scikit-learn's estimator checks), so a new codec is held to the same contract as soon as it is registered.

For each codec, on a short skeletal clip and a short marker clip (where the codec takes that kind; a clean
OptionError where it does not):

1. round trip: same kind, shape, frame rate, names / labels and skeleton; exact values from the lossless
   codec, finite values with a sane error from lossy codecs; marker gaps come back where they were;
2. determinism: same bytes twice; the container names the codec and its version;
3. option validation driven by the declarations (range, type, choices, unknown names), case-insensitive
   codec names, the common targets in every lossy codec (met when the codec returns);
4. damaged content: every section truncated, emptied, zeroed, randomised, bit-flipped or dropped (re-sealed
   so the CRC holds) gives a MocapzError or a motion of the right shape, never another exception or a hang;
5. empty and tiny clips (0, 1, 2 frames) round-trip or give a clean MocapzError.
"""

from __future__ import annotations

import math
import signal
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz import FormatError, MarkerMotion, MocapzError, Motion, OptionError, TargetError
from mocapz.codecs import CodecInfo, all_codecs, codec_names, get_codec
from mocapz.codecs.options import KINDS as OPTION_KINDS
from mocapz.codecs.options import Option
from mocapz.format.container import Container
from mocapz.format.layout import decode_header
from mocapz.model.motion import AnyMotion

BVH = "cmu/bvh/09_06.bvh"  # 31 joints, 96 channels, 120 fps; frame 0 is cgspeed's T-pose
C3D = "cmu/c3d/01_01.c3d"  # 42 markers, mm, 120 fps; marker 41 (of 42) is missing in all of frames 0-59
KINDS = ("skeleton", "markers")
TARGETS = ("max_error", "max_distortion", "max_arms")

CODECS: list[CodecInfo] = all_codecs()
LOSSY = [c.name for c in CODECS if c.lossy]
CASES = [(c.name, k) for c in CODECS for k in KINDS if k in c.kinds]
LOSSY_CASES = [(n, k) for n, k in CASES if get_codec(n).lossy]
UNSUPPORTED = [(c.name, k) for c in CODECS for k in KINDS if k not in c.kinds]

# Default settings on the clips below, measured (distortion_pct): lossless 0; pga 0.52 / -; patterns 0.91 / 4.2;
# subsample 5.0 / 2.3; pca 15 / 20; segpca 5.8 / 7.2; quant 0.007 / 1.7 (skeleton / markers). PCA keeps 95 % of
# the variance by default, i.e. leaves about sqrt(5 %) = 22 % of the centred signal's norm out, so 20 % is its
# expected level. 35 % leaves headroom for retuned defaults, while a decoder that scrambles columns, drops a
# body part or mixes up units lands far above 100 %.
MAX_DEFAULT_DISTORTION_PCT = 35.0

# Generous targets every lossy codec must meet on both clips (each is well above what its default gives)...
GENEROUS_TARGETS: dict[str, dict[str, Any]] = {
    "max_error_50cm": {"max_error": "50cm"},
    "max_distortion_20pct": {"max_distortion": 20.0},
    "max_arms_10cm": {"max_arms": "10cm"},
}
# ...and a tight one each must either meet or refuse with a TargetError (never return a file that misses it).
TIGHT_TARGET: dict[str, Any] = {"max_error": "1cm", "max_distortion": 5.0, "max_arms": "5mm"}

DAMAGE_TIMEOUT_S = 10.0  # one decode of a damaged 80-frame file; valid files decode in under 0.1 s


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    """SVDs and K-means on one BLAS thread (shared 2-core machines crawl with oversubscribed BLAS pools)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


# ------------------------------------------------------------------------------------------------ clips
@cache
def clip(kind: str) -> AnyMotion:
    """The skeletal clip (first 80 frames of CMU 09_06) or the marker clip (first 60 frames of CMU 01_01).

    The marker clip's only real gap is one marker absent throughout; partial gaps are added so that gap
    handling is exercised at the clip's edges, inside a marker's track and across a frame.
    """
    if kind == "skeleton":
        m = mocapz.load(data_path(BVH))
        assert isinstance(m, Motion)
        return m.slice(0, 80)
    mk = mocapz.load(data_path(C3D))
    assert isinstance(mk, MarkerMotion)
    mk = mk.slice(0, 60)
    pos = mk.positions.copy()
    pos[10:20, 3] = np.nan  # a 10-frame gap in one track
    pos[[0, 59], 7] = np.nan  # first and last frame of another
    pos[30, :5] = np.nan  # five markers lost in one frame
    return mk.with_positions(pos)


@cache
def packed(codec: str, kind: str) -> bytes:
    """The clip compressed with the codec's default options."""
    return mocapz.compress(clip(kind), codec=codec)


@cache
def unpacked(codec: str, kind: str) -> AnyMotion:
    return mocapz.decompress(packed(codec, kind))


def unit_cm(motion: AnyMotion) -> float:
    u = motion.unit_cm
    assert u is not None, "test clips have a known length unit"
    return u


def missing(motion: AnyMotion) -> np.ndarray:
    """Where samples are missing: ``(frames, markers)`` for markers, all False for skeletons."""
    return motion.missing if isinstance(motion, MarkerMotion) else np.zeros(motion.values.shape, dtype=bool)


def assert_same_layout(original: AnyMotion, decoded: AnyMotion) -> None:
    """Same kind, value shape, frame rate, clip name and skeleton / marker set."""
    assert type(decoded) is type(original)
    assert decoded.kind == original.kind
    assert decoded.values.shape == original.values.shape
    assert decoded.frame_rate == original.frame_rate
    assert decoded.name == original.name
    if isinstance(original, MarkerMotion):
        assert isinstance(decoded, MarkerMotion)
        assert decoded.labels == original.labels
        assert decoded.units == original.units
        return
    assert isinstance(decoded, Motion)
    a, b = original.skeleton, decoded.skeleton
    assert b.names == a.names
    assert b.parents.tolist() == a.parents.tolist()
    assert np.array_equal(b.offsets, a.offsets)
    assert [tuple(c) for c in b.channels] == [tuple(c) for c in a.channels]
    assert b.rotation_order == a.rotation_order
    assert a.axis is not None and b.axis is not None and np.array_equal(b.axis, a.axis)
    assert [(j, n) for j, _, n in b.end_sites] == [(j, n) for j, _, n in a.end_sites]
    assert all(np.array_equal(o1, o2) for (_, o1, _), (_, o2, _) in zip(a.end_sites, b.end_sites, strict=True))
    assert (b.angle_unit, b.unit_cm) == (a.angle_unit, a.unit_cm)


def assert_values_conform(info: CodecInfo, original: AnyMotion, decoded: AnyMotion) -> None:
    """Lossless: bit-exact values and gaps. Lossy: gaps exactly where they were, finite values elsewhere."""
    gaps = missing(original)
    got = missing(decoded)
    assert np.array_equal(got, gaps), f"gaps moved: {int((got != gaps).sum())} samples differ"
    values = np.isfinite(decoded.values)
    if isinstance(decoded, MarkerMotion):
        values = values.all(axis=-1)
    assert values[~gaps].all(), "non-finite values where the original has samples"
    if not info.lossy:
        a, b = original.values[~gaps], decoded.values[~gaps]
        if original.decimals is not None:
            # Values known to d decimals are coded as integers round(v * 10**d), which have no negative zero:
            # a "-0.0000" of the BVH text comes back as 0.0 (equal values; the writers print 0 for both).
            a, b = a + 0.0, b + 0.0
        assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), "the lossless codec changed values"


# ------------------------------------------------------------------------------------------------ registry
def test_registry_lists_every_codec_once() -> None:
    names = [c.name for c in CODECS]
    assert sorted(names) == codec_names()
    assert len(set(names)) == len(names)
    assert {"lossless", "pga", "patterns", "subsample", "pca", "segpca", "quant"} <= set(names)


@pytest.mark.parametrize("codec", [c.name for c in CODECS])
def test_declarations_are_well_formed(codec: str) -> None:
    info = get_codec(codec)
    assert info.name == codec == codec.lower()
    assert isinstance(info.version, int) and 1 <= info.version <= 255  # one byte in the container
    assert info.kinds and set(info.kinds) <= set(KINDS)
    assert info.summary
    names = [o.name for o in info.options]
    assert len(set(names)) == len(names)
    for o in info.options:
        assert isinstance(o, Option) and o.kind in OPTION_KINDS and o.help
        assert o.kind != "choice" or o.choices
        if o.low is not None and o.high is not None:
            assert o.low <= o.high
    if info.lossy:  # the common targets, first
        assert tuple(names[:3]) == TARGETS
        assert [o.kind for o in info.options[:3]] == ["length", "percent", "length"]
    else:
        assert not set(TARGETS) & set(names)


# ------------------------------------------------------------------------------------------------ 1. round trip
@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_round_trip_keeps_the_layout(codec: str, kind: str) -> None:
    assert_same_layout(clip(kind), unpacked(codec, kind))


@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_round_trip_values(codec: str, kind: str) -> None:
    info = get_codec(codec)
    original, decoded = clip(kind), unpacked(codec, kind)
    assert_values_conform(info, original, decoded)
    report = mocapz.evaluate(original, decoded)
    if info.lossy:
        assert math.isfinite(report.max_err)
        assert report.distortion_pct < MAX_DEFAULT_DISTORTION_PCT
    else:
        assert (report.distortion_pct, report.max_err) == (0.0, 0.0)


@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_codec_decode_matches_decompress(codec: str, kind: str) -> None:
    """``CodecInfo.decode(sections, header)`` is what ``decompress`` runs, on the container's typed header."""
    box = Container.from_bytes(packed(codec, kind))
    header = decode_header(box.layout)
    assert (header.kind, header.frames, header.frame_rate) == (kind, clip(kind).n_frames, clip(kind).frame_rate)
    assert header.value_shape == clip(kind).values.shape
    direct = get_codec(codec).decode(box.sections, header)
    assert np.array_equal(direct.values, unpacked(codec, kind).values, equal_nan=True)


@pytest.mark.parametrize(("codec", "kind"), UNSUPPORTED)
def test_unsupported_kind_is_a_clean_option_error(codec: str, kind: str) -> None:
    with pytest.raises(OptionError, match=f"{codec}.*{kind}"):
        mocapz.compress(clip(kind), codec=codec)


# ------------------------------------------------------------------------------------------------ 2. determinism
@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_deterministic_and_labelled(codec: str, kind: str) -> None:
    info = get_codec(codec)
    data = mocapz.compress(clip(kind), codec=codec)
    assert data == packed(codec, kind), "compressing twice gave different bytes"
    box = Container.from_bytes(data)
    assert (box.codec, box.codec_version) == (info.name, info.version)
    again = mocapz.decompress(data)
    assert np.array_equal(again.values, unpacked(codec, kind).values, equal_nan=True)


# ------------------------------------------------------------------------------------------------ 3. options
def bad_values(o: Option) -> list[tuple[str, Any]]:
    """``(label, value)`` pairs the declaration ``o`` must refuse: out of range, wrong type, not a choice."""
    out: list[tuple[str, Any]] = []
    if o.kind in ("int", "float", "percent", "length"):
        out += [("bool", True), ("list", [1])]
        out += [("text", "lots")] if o.kind != "length" else [("text", "far"), ("unit", "3 parsecs")]
        if o.low is not None:
            below = o.low if o.low_open else o.low - 1
            out.append(("below_low", below))
        if o.high is not None:
            out.append(("above_high", o.high + 1))
    if o.kind == "int":
        out.append(("fraction", 2.5))
    if o.kind in ("float", "percent"):
        out += [("nan", math.nan), ("inf", math.inf)]
    if o.kind == "bool":
        out.append(("text", "maybe"))
    if o.kind == "choice":
        out.append(("not_a_choice", "no-such-choice"))
    if o.kind == "names":
        out += [("empty", ""), ("commas", " , ")]
    if o.kind == "file":
        out.append(("missing_file", "/nonexistent/conformance.json"))
    if o.kind == "weights":
        out += [("number", 42), ("missing_file", "/nonexistent/weights.json")]
    if o.kind == "indices":
        out += [("negative", [-1]), ("text", "a,b")]
    assert out, f"no bad value for option kind {o.kind!r}"
    return out


def good_value(o: Option) -> Any:
    """A value the declaration ``o`` must accept (a bound where there is one)."""
    if o.kind == "int":
        return int(o.low if o.low is not None else 1)
    if o.kind in ("float", "percent"):
        return o.high if o.high is not None else (o.low or 0.0) + 0.5
    return {"length": "2cm", "bool": "true", "choice": o.choices[0] if o.choices else "", "names": "a,b",
            "file": __file__, "weights": {"LFHD": 2.0}, "indices": [0, 3]}[o.kind]


BAD_OPTIONS = [pytest.param(c.name, o.name, v, id=f"{c.name}-{o.name}-{label}")
               for c in CODECS for o in c.options for label, v in bad_values(o)]


@pytest.mark.parametrize(("codec", "option", "value"), BAD_OPTIONS)
def test_bad_option_value_is_refused_by_name(codec: str, option: str, value: Any) -> None:
    info = get_codec(codec)
    with pytest.raises(OptionError, match=rf"\b{option}\b"):
        info.validate({option: value})
    with pytest.raises(OptionError, match=rf"\b{option}\b"):
        mocapz.compress(clip(info.kinds[0]), codec=codec, **{option: value})


@pytest.mark.parametrize("codec", [c.name for c in CODECS])
def test_declared_values_are_accepted(codec: str) -> None:
    info = get_codec(codec)
    defaults = info.validate({})
    assert defaults == {o.name: o.default for o in info.options if o.default is not None}
    for o in info.options:
        checked = info.validate({o.name: good_value(o)})
        assert o.name in checked, o.name
        assert info.validate({o.name: None}) == defaults  # None means not given


@pytest.mark.parametrize("codec", [c.name for c in CODECS])
def test_unknown_option_is_refused_by_name(codec: str) -> None:
    info = get_codec(codec)
    with pytest.raises(OptionError, match="no_such_option"):
        mocapz.compress(clip(info.kinds[0]), codec=codec, no_such_option=1)


@pytest.mark.parametrize("codec", [c.name for c in CODECS])
def test_options_are_checked_before_the_input_is_read(codec: str, tmp_path: Path) -> None:
    with pytest.raises(OptionError, match="no_such_option"):
        mocapz.compress(tmp_path / "absent.bvh", codec=codec, no_such_option=1)


@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_codec_names_are_case_insensitive(codec: str, kind: str) -> None:
    for spelling in (codec.upper(), f" {codec.title()} "):
        data = mocapz.compress(clip(kind), codec=spelling)
        assert data == packed(codec, kind), spelling
        assert Container.from_bytes(data).codec == codec


def test_unknown_codec_is_refused_by_name() -> None:
    with pytest.raises(OptionError, match="no-such-codec"):
        mocapz.compress(clip("skeleton"), codec="no-such-codec")


def assert_target_met(motion: AnyMotion, decoded: AnyMotion, target: dict[str, Any]) -> None:
    """The decoded clip meets every bound of ``target`` (lengths in cm or mm, distortion in %)."""
    report = mocapz.evaluate(motion, decoded)
    slack = 1 + 1e-9
    for name, value in target.items():
        if name == "max_distortion":
            assert report.distortion_pct <= value * slack, (name, report.distortion_pct)
            continue
        cm = float(value[:-2]) * (0.1 if value.endswith("mm") else 1.0)
        limit = cm / unit_cm(motion)  # file units
        got = report.max_err if name == "max_error" else report.arms
        assert got <= limit * slack, (name, got, limit)


@pytest.mark.parametrize("target", GENEROUS_TARGETS.values(), ids=GENEROUS_TARGETS.keys())
@pytest.mark.parametrize(("codec", "kind"), LOSSY_CASES)
def test_generous_target_is_met(codec: str, kind: str, target: dict[str, Any]) -> None:
    motion = clip(kind)
    decoded = mocapz.decompress(mocapz.compress(motion, codec=codec, **target))
    assert_same_layout(motion, decoded)
    assert_values_conform(get_codec(codec), motion, decoded)
    assert_target_met(motion, decoded, target)


@pytest.mark.slow
@pytest.mark.parametrize(("codec", "kind"), LOSSY_CASES)
def test_tight_target_is_met_or_refused(codec: str, kind: str) -> None:
    motion = clip(kind)
    try:
        data = mocapz.compress(motion, codec=codec, **TIGHT_TARGET)
    except TargetError:
        return
    assert_target_met(motion, mocapz.decompress(data), TIGHT_TARGET)


# ------------------------------------------------------------------------------------------------ 4. damage
def _seed(*parts: str) -> int:
    return zlib.crc32("/".join(parts).encode())


def flip_bit(data: bytes, rng: np.random.Generator) -> bytes:
    """One bit of ``data`` inverted (empty data unchanged)."""
    if not data:
        return data
    out = bytearray(data)
    out[int(rng.integers(len(out)))] ^= 1 << int(rng.integers(8))
    return bytes(out)


DAMAGES: dict[str, Callable[[bytes, np.random.Generator], bytes | None]] = {
    "truncated": lambda b, rng: b[: len(b) // 2],
    "emptied": lambda b, rng: b"",
    "zeroed": lambda b, rng: bytes(len(b)),
    "random": lambda b, rng: rng.integers(0, 256, len(b), dtype=np.uint8).tobytes(),
    "random_longer": lambda b, rng: rng.integers(0, 256, 2 * len(b) + 8, dtype=np.uint8).tobytes(),
    "bit_flipped": lambda b, rng: flip_bit(b, rng),
    "dropped": lambda b, rng: None,
}


class Hang(Exception):
    """A decode ran past DAMAGE_TIMEOUT_S."""


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    if not hasattr(signal, "setitimer"):  # pragma: no cover - not on Windows
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise Hang(f"no answer after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def damaged_outcome(codec: str, kind: str, section: str, damage: str) -> str | None:
    """None if decoding the clip's file with ``section`` damaged conforms, else what went wrong."""
    box = Container.from_bytes(packed(codec, kind))
    rng = np.random.default_rng(_seed(codec, kind, section, damage))
    sections = dict(box.sections)
    new = DAMAGES[damage](sections[section], rng)
    if new is None:
        del sections[section]
    else:
        sections[section] = new
    data = Container(box.codec, box.codec_version, box.layout, sections).to_bytes()
    try:
        with time_limit(DAMAGE_TIMEOUT_S), np.errstate(all="ignore"):
            decoded = mocapz.decompress(data)
    except (FormatError, MocapzError):
        return None
    except Exception as exc:  # the point: nothing else may escape
        return f"{type(exc).__name__}: {exc}"
    original = clip(kind)
    if decoded.kind != kind or decoded.values.shape != original.values.shape:
        return f"decoded {decoded.kind} of shape {decoded.values.shape}, expected {original.values.shape}"
    return None


# Cases that raise something else than a MocapzError today ("nothing crashes" issue):
# {(codec, kind, damage): reason}. None are known: decompress turns the decoders' ValueError, IndexError,
# KeyError, TypeError and OverflowError into a FormatError.
DAMAGE_XFAIL: dict[tuple[str, str, str], str] = {}


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("damage", DAMAGES)
@pytest.mark.parametrize(("codec", "kind"), CASES)
def test_damaged_sections_fail_cleanly(codec: str, kind: str, damage: str, request: pytest.FixtureRequest) -> None:
    reason = DAMAGE_XFAIL.get((codec, kind, damage))
    if reason:
        request.applymarker(pytest.mark.xfail(strict=True, reason=reason))
    sections = Container.from_bytes(packed(codec, kind)).sections
    assert sections, "a codec writes at least one section"
    failures = {s: out for s in sections if (out := damaged_outcome(codec, kind, s, damage)) is not None}
    assert not failures, f"{codec}/{kind}, sections {damage}: {failures}"


# ------------------------------------------------------------------------------------------------ 5. tiny clips
TINY = [pytest.param(c, k, n, id=f"{c}-{k}-{n}frames")
        for c, k in CASES for n in (0, 1, 2)]


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize(("codec", "kind", "frames"), TINY)
def test_tiny_clip_round_trips_or_fails_cleanly(codec: str, kind: str, frames: int) -> None:
    motion = clip(kind).slice(0, frames)
    try:
        decoded = mocapz.decompress(mocapz.compress(motion, codec=codec))
    except MocapzError:
        return
    assert_same_layout(motion, decoded)
    assert_values_conform(get_codec(codec), motion, decoded)


@pytest.mark.parametrize("name", codec_names())
def test_encoder_and_decoder_run_on_one_blas_thread(name: str) -> None:
    """Every registered codec's encoder and decoder run with BLAS on one thread (small matrices are slower spread
    over threads, far slower on a busy machine, and the sums of some routines change order with the thread
    count); the caller's setting is back once they return."""
    from threadpoolctl import threadpool_info

    from mocapz._blas import on_one_thread

    def blas_threads() -> list[int]:
        return [m["num_threads"] for m in threadpool_info() if m["user_api"] == "blas"]

    info = get_codec(name)
    assert callable(getattr(info.encode, "__wrapped__", None)) and callable(getattr(info.decode, "__wrapped__", None))
    before = blas_threads()
    assert on_one_thread(blas_threads)() == [1] * len(before)
    assert blas_threads() == before
