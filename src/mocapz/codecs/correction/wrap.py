"""The correction layer around a lossy codec's encoder and decoder: every target met on every file.

:func:`corrected` turns a codec's ``encode`` / ``decode`` into ones that

1. resolve the target (the user's, or the default one: max error 1 cm on every point, feet held);
2. encode the clip with the codec's own model (its own or the user's settings; pga and patterns may run
   their own search for a distortion / ARMS target, see ``base_options``; a model missing that falls back
   to its settings), decode it, and code the residual with :func:`~mocapz.codecs.correction.search.search`
   so that every bound holds on the decoded result; the same is tried on a zero base (the correction
   alone) and the smaller file is kept (the zero base first where it has no bytes of its own: the model is
   then encoded only as far as its own bytes stay under that file's, :mod:`mocapz.codecs.budget`);
3. refuse only a max-error target tighter than the source's own decimals.

Sections: the model's own (untouched), plus ``c.head`` (layout version, base kind, lifting levels),
``c.codes``, ``c.levels``, ``c.res`` and, on a zero base with marker gaps, ``c.gaps``. The decoder applies the
correction when ``c.head`` is present; files without it decode as the plain codec did.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from mocapz.codecs import budget
from mocapz.codecs.budget import section_bytes
from mocapz.codecs.correction import bounds, context, lifting, window
from mocapz.codecs.correction.fit import Clip, value_matrix
from mocapz.codecs.correction.search import Base, Maker, search_bases
from mocapz.codecs.gaps import pack_mask, unpack_mask
from mocapz.codecs.options import Length, Option
from mocapz.codecs.target import CORRECTION_NAMES, DEFAULT_EFFORT, TARGET_NAMES, Target
from mocapz.errors import FormatError, TargetError
from mocapz.format.entropy import decode_int_matrix, read_uvarint, unpack_uint64, write_uvarint
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion

Sections = dict[str, bytes]
Encoder = Callable[..., Sections]
Decoder = Callable[[Sections, ClipHeader], AnyMotion]
WindowDecoder = Callable[[Sections, ClipHeader, int, int, "dict[str, Any] | None"], AnyMotion | None]

DEFAULT_ERROR_CM = 1.0  # the default target (codecs.target.DEFAULT_TARGET_TEXT); 1/170 of the body height
# when the length unit is unknown
FORMAT = 2  # 1: every lifting level within the whole tolerance; 2: a shrink factor per level (c.head)
SEEKABLE = 3  # 2's integers with the streams laid out for random access (clips of window.SEEK_MIN frames and more)
CONTINUED = 4  # 2's with the frame before the clip as its first knot (a stream's block after the one before it)
ACROSS = 5  # 4's with each level's first detail predicted across the edge from the frames before (context.prefix)
BASE_NONE, BASE_MODEL = 0, 1
ROWS = 512  # rows per chunk of the wrap-around pass
HALVES = 2.0 ** (-np.arange(61, dtype=np.float64) / 2.0)  # every level's share of a tolerance (the same numbers)


def resolve_target(motion: AnyMotion, options: dict[str, Any]) -> Target:
    """The user's target in file units, or the default one (:data:`~mocapz.codecs.target.DEFAULT_TARGET_TEXT`)."""
    target = Target.from_options(options, motion.unit_cm)
    if target.active:
        return target
    return Target(max_error=default_error(motion))


def default_error(motion: AnyMotion) -> float:
    """1 cm in file units, or 1/170 of the body height when the unit is unknown."""
    if motion.unit_cm:
        return DEFAULT_ERROR_CM / motion.unit_cm
    clip = Clip(motion, hold_feet=False)
    return clip.body / 170.0


def strip_targets(motion: AnyMotion, options: dict[str, Any], target: Target) -> dict[str, Any]:
    """The options without the targets: the model with its own settings (for models whose rate control cannot
    aim at a max error, or is slow)."""
    return {k: v for k, v in options.items() if k not in TARGET_NAMES and k not in CORRECTION_NAMES}


def native_targets(motion: AnyMotion, options: dict[str, Any], target: Target) -> dict[str, Any]:
    """The options with the distortion and ARMS targets as given and no max error (for models whose rate
    control aims at those two; the correction adds the max error and the feet)."""
    out = strip_targets(motion, options, target)
    if target.max_distortion is not None:
        out["max_distortion"] = target.max_distortion
    if target.max_arms is not None:
        out["max_arms"] = Length(target.max_arms)
    return out


def given_settings(options: dict[str, Any], declared: tuple[Option, ...]) -> bool:
    """True when the user fixed a model setting (an option other than the targets, unlike its default)."""
    return any(o.name not in TARGET_NAMES and o.name not in CORRECTION_NAMES and options.get(o.name) is not None
               and options.get(o.name) != o.default for o in declared)


def corrected(encode: Encoder, decode: Decoder, codec: str, declared: tuple[Option, ...],
              base_options: Callable[[AnyMotion, dict[str, Any], Target], dict[str, Any]] | None = None,
              zero_base: bool = True, model_base: bool = True) -> tuple[Encoder, Decoder]:
    """The codec's encoder and decoder with the correction layer (see the module docstring).

    Args:
        encode, decode: the model's.
        codec: its name (messages).
        declared: its option declarations (settings the user fixes are kept as given, and the model is used).
        base_options: ``(motion, options, target) -> options`` the model is encoded with (default: its own
            settings, no target: a search of the model's settings costs more time than the correction does).
        zero_base: whether the correction alone (no model) may be chosen when it is smaller.
        model_base: whether the model is tried as the base when the user fixed none of its settings (False: a
            model the correction alone always beats, e.g. a uniform quantiser, is used only with given settings).
    """
    def enc(motion: AnyMotion, **options: Any) -> Sections:
        if motion.n_frames == 0 or motion.values.size == 0:  # nothing to be wrong about
            return encode(motion, **strip_targets(motion, options, Target()))
        target = resolve_target(motion, options)
        clip = Clip(motion, bool(options.get("hold_feet", True)))
        _refuse_below_precision(clip, target, codec)
        header = ClipHeader.of(motion)
        fixed = given_settings(options, declared)
        make = base_options or strip_targets
        tried: list[tuple[int, Sections, Base]] = []  # the bases: kind, their sections, their values and bytes
        zero = {"c.gaps": pack_mask(motion.missing)} if isinstance(motion, MarkerMotion) \
            and motion.missing.any() else {}
        effort = options.get("effort") or DEFAULT_EFFORT
        if model_base and zero_base and not fixed and (not zero or effort == "fast"):
            # the zero base is searched first (it has no bytes of its own, or at effort fast the order changes
            # nothing); the model is encoded only where it may be the smaller, given up once its bytes reach the
            # correction alone's (the same file)
            made: Sections = {}
            tried.append((BASE_MODEL, made, Base(None, 1, _maker(encode, decode, motion,
                                                                  make(motion, options, target), header, made))))
        else:
            try:
                if model_base or fixed or not zero_base:
                    base_sections = encode(motion, **make(motion, options, target))
                    tried.append((BASE_MODEL, base_sections, _made(base_sections, decode, header)))
            except TargetError:
                if fixed or not zero_base:
                    base_sections = encode(motion, **strip_targets(motion, options, target))
                    tried.append((BASE_MODEL, base_sections, _made(base_sections, decode, header)))
        if zero_base and not fixed:
            tried.append((BASE_NONE, zero, Base(clip.zero_base(), _size(zero))))
        best, cor = search_bases(clip, [t[2] for t in tried], [0] * len(tried), target, effort=effort)
        kind, base_sections, base = tried[best]
        if not target.met(cor.errors):
            raise TargetError(f"{motion.metadata.get('path', motion.name)}: the {codec} codec with its correction "
                              f"misses the target ({target.describe()}): it reaches distortion "
                              f"{cor.errors.distortion_pct:.4g} %, max error {cor.errors.max_error:.4g} file units "
                              "(the lossless codec gives the values back exactly)")
        context.spend(clip.whole, cor.added, cor.skated, cor.tail)  # a block: what it used of the clip's allowances
        # as the fit laid the streams out
        pre = clip.prefix_of(base.values)
        fmt = SEEKABLE if window.seekable(motion.n_frames) else FORMAT if pre is None \
            else ACROSS if pre.ndim == 2 else CONTINUED
        if pre is not None:
            clip.whole.cache["continued"] = True  # type: ignore[union-attr]  # the stream marks the block
        if clip.whole is not None and zero_base and not fixed and not window.seekable(motion.n_frames):
            clip.whole.cache["continuable"] = True  # the next block may continue this one (it may take a zero base)
        head = write_uvarint(fmt) + write_uvarint(kind) + write_uvarint(cor.depth) \
            + write_uvarint(shrink_code(clip.shrink))
        return {**base_sections, "c.head": head, **cor.sections}

    def dec(sections: Sections, header: ClipHeader) -> AnyMotion:
        if "c.head" not in sections:
            return decode(sections, header)
        return apply(sections, header, decode)

    return enc, dec


def _size(sections: Sections) -> int:
    return section_bytes(sections.values())


def _made(sections: Sections, decode: Decoder, header: ClipHeader) -> Base:
    """A model base already encoded: its decoded values and its own bytes."""
    return Base(value_matrix(decode(sections, header)), _size(sections))


def _maker(encode: Encoder, decode: Decoder, motion: AnyMotion, options: dict[str, Any], header: ClipHeader,
           made: Sections) -> Maker:
    """``make(cap)`` of a model base encoded when first needed (:class:`.search.Base`): its own bytes and decoded
    values, its sections left in ``made``; given up once its sections reach ``cap`` bytes (values None), not
    tried where its own rate control misses its target (the correction alone is)."""
    def make(cap: float) -> tuple[float, np.ndarray | None]:
        try:
            with budget.capped(cap):
                sections = encode(motion, **options)
        except budget.OverBudget as over:
            return over.spent, None
        except TargetError:
            return math.inf, None
        size = _size(sections)
        if size >= cap:
            return size, None
        made.update(sections)
        return size, value_matrix(decode(sections, header))

    return make


def _refuse_below_precision(clip: Clip, target: Target, codec: str) -> None:
    floor = clip.precision_floor()
    if target.max_error is not None and target.max_error < floor:
        raise TargetError(f"{clip.motion.metadata.get('path', clip.motion.name)}: max error "
                          f"{target.max_error:.4g} file units is below the source's own precision (its decimals "
                          f"allow errors up to {floor:.4g}); the {codec} codec reaches {floor:.4g} and above, the "
                          "lossless codec gives the values back exactly")


def apply(sections: Sections, header: ClipHeader, decode: Decoder) -> AnyMotion:
    """Decode the model (or a zero base) and add the coded correction."""
    try:
        fmt, kind, levels, code = _head(sections["c.head"])
        groups = group_of(header)
        frames, cols = header.frames, groups.size
        codes = _codes(sections["c.codes"], cols)
        # every stream's shape is checked against the header before a frames x columns array is made
        n_groups = int(groups.max(initial=-1)) + 1
        prefix = None if fmt not in (CONTINUED, ACROSS) else _prefix(header, kind, fmt == ACROSS)
        if fmt == SEEKABLE:
            lev = window.read_levels(sections["c.levels"], frames, n_groups)[1]
            q = window.read_res(sections["c.res"], frames, cols, levels)
        else:
            dlev = decode_int_matrix(sections["c.levels"], (frames, n_groups))
            q = lifting.read(sections["c.res"], frames, cols, levels, prefix, groups)
            lev = np.cumsum(dlev, axis=0)
            if lev.size and (lev.min() < 0 or lev.max() > 60):
                raise FormatError(None, "corrupted correction levels")
        if kind == BASE_MODEL:
            base_motion = decode({k: v for k, v in sections.items() if not k.startswith("c.")}, header)
        else:
            base_motion = zero_motion(header, sections.get("c.gaps"))
    except KeyError as exc:
        raise FormatError(None, f"corrupted correction (missing section {exc})") from None
    # 2 ** (-level / 2) from a table of the levels' values (the same numbers, without a power per value)
    halves = 2.0 ** (-np.arange(int(lev.max(initial=0)) + 1, dtype=np.float64) / 2.0)
    # tol = tol_of(codes)[None, :] * halves[lev][:, groups], read from the table by the compiled kernel
    y = lifting.decode_table(q, bounds.tol_of(codes), halves, lev, groups, levels, code / 100.0, prefix)
    return _add(base_motion, y, header)


def _prefix(header: ClipHeader, kind: int, ghosts: bool) -> np.ndarray:
    """A continued block's first knot, and with ``ghosts`` its levels' ghosts (:func:`.context.prefix`), from the
    decoded frames before it."""
    before = header.before
    if kind != BASE_NONE:
        raise FormatError(None, "corrupted correction header (a continued block on a model base)")
    if before is None:
        raise FormatError(None, "a block that continues the block before it, decoded without it")
    before = np.atleast_2d(np.asarray(before, dtype=np.float64))
    if before.shape[1] != header.n_columns:
        raise FormatError(None, f"the frame before the block has {before.shape[1]} values, not {header.n_columns}")
    return context.prefix(before if ghosts else before[-1], header.rotation_mask, header.period, ghosts)


def apply_window(sections: Sections, header: ClipHeader, start: int, stop: int,
                 base_window: WindowDecoder | None = None, memo: dict[str, Any] | None = None) -> AnyMotion | None:
    """Frames ``[start, stop)`` of a clip coded with the seekable layout, decoding only the chunks they need (the
    values of a full decode, to the bit), or None where the whole clip must be decoded (another layout, a model
    base without ``base_window`` or one it cannot window, a zero-base window the correction leaves at zero:
    whether the motion keeps the source's decimals and quantum depends on the whole clip).

    ``base_window(sections, header, start, stop, memo)``: the model's own frames ``[start, stop)`` (or None) from its
    sections (those of the correction left out), for a file on a model base. ``memo``: a dict kept by the caller
    for these very sections (a reader's), where the first window leaves what every window reads (the header,
    the tolerances, what :class:`.window.Running` keeps) and later ones find it."""
    if "c.head" not in sections:
        return None
    try:
        fmt, kind, levels, code = _head(sections["c.head"])
        if fmt != SEEKABLE:
            return None
        base = None
        if kind == BASE_MODEL:
            if base_window is not None:
                base = base_window({k: v for k, v in sections.items() if not k.startswith("c.")}, header, start,
                                   stop, memo)
            if base is None:
                return None
        kept = None if memo is None else memo.get("correction")
        if kept is None:
            groups = group_of(header)
            tol_col = bounds.tol_of(_codes(sections["c.codes"], groups.size))
            running = None if memo is None else window.open_running(sections["c.res"], sections["c.levels"], groups,
                                                                      header.frames, levels)
            kept = (groups, tol_col, running, header.rotation_mask)
            if memo is not None:
                memo["correction"] = kept
        groups, tol_col, running, rot = kept
        y = window.decode_window(sections["c.res"], sections["c.levels"], tol_col, HALVES, groups, header.frames,
                                 levels, code / 100.0, start, stop, running)
        part = replace(header, frames=stop - start)
        gaps = sections.get("c.gaps")
        mask = None if gaps is None else unpack_mask(gaps, (header.frames, len(header.labels)))[start:stop]
    except KeyError as exc:
        raise FormatError(None, f"corrupted correction (missing section {exc})") from None
    if base is not None:
        return _add(base, y, part, rot)
    if not y.any():
        return None  # the full decode's motion tells whether its values keep the source's decimals and quantum
    return _add(None if header.skeleton is not None else zero_motion(part, None, mask), y, part, rot)


def on_model(sections: Sections) -> bool:
    """Whether a corrected encoding's sections add the correction to the codec's model (else to a zero base: the
    correction alone, the model's sections unused)."""
    return _head(sections["c.head"])[1] == BASE_MODEL


def _head(head: bytes) -> tuple[int, int, int, int]:
    """``c.head``'s format, base kind, lifting levels and shrink code (hundredths)."""
    fmt, pos = read_uvarint(head, 0)
    kind, pos = read_uvarint(head, pos)
    levels, pos = read_uvarint(head, pos)
    code, pos = read_uvarint(head, pos) if fmt >= 2 else (100, pos)
    if fmt > ACROSS:
        raise FormatError(None, f"correction format {fmt} is newer than this mocapz reads (up to {ACROSS})")
    if fmt < 1 or kind not in (BASE_NONE, BASE_MODEL) or levels > 16 or not 1 <= code <= 100 or pos != len(head):
        raise FormatError(None, "corrupted correction header")
    return fmt, kind, levels, code


def _codes(data: bytes, cols: int) -> np.ndarray:
    codes = unpack_uint64(data, cols)
    if np.any(codes > bounds.FREE):
        raise FormatError(None, "corrupted correction codes")
    return codes


def _add(base_motion: AnyMotion | None, y: np.ndarray, header: ClipHeader, rot: np.ndarray | None = None
         ) -> AnyMotion:
    """The base motion plus the decoded correction ``y`` ``(frames, columns)`` (rotations wrapped into their
    period where the correction moved them). ``None``: a skeleton's zeros (the motion ``zero_motion(header)``
    would make, not made: the same sum and motion); ``rot``: ``header.rotation_mask`` where the caller has it."""
    if base_motion is not None and not y.any():
        return base_motion
    if base_motion is None or isinstance(base_motion, Motion):
        base = None if base_motion is None else value_matrix(base_motion)
        rot = header.rotation_mask if rot is None else rot
        period = header.period
        half = period / 2
        # base + y, then mod(o + half, period) - half where the correction moved a value (only there: a float
        # mod is slow; mod(w, period) is w itself for w in [0, period), fmod being exact, so only the others take
        # it), by chunks of rows, in place in y (no fresh frames x columns arrays)
        for a in range(0, y.shape[0], ROWS):
            o = y[a:a + ROWS]
            moved = (o != 0) & rot
            np.add(0.0 if base is None else base[a:a + ROWS], o, out=o)
            w = o + half
            outside = moved & ~((w >= 0.0) & (w < period))  # NaN counts as outside
            np.subtract(w, half, out=o, where=moved)
            if outside.any():
                o[outside] = np.mod(w[outside], period) - half
        if base_motion is None:
            assert header.skeleton is not None
            return Motion(skeleton=header.skeleton, channels=y, frame_rate=float(header.frame_rate), name=header.name,
                          source_format=header.source_format, metadata=dict(header.metadata))
        return base_motion.with_channels(y)
    assert base_motion is not None
    out = value_matrix(base_motion) + y
    return base_motion.with_positions(out.reshape(base_motion.positions.shape))


def shrink_code(shrink: float) -> int:
    """The ``c.head`` code of a lifting shrink factor (hundredths)."""
    code = int(round(shrink * 100))
    if abs(code - shrink * 100) > 1e-9 or not 1 <= code <= 100:
        raise ValueError(f"shrink {shrink} is not a whole number of hundredths in (0, 1]")
    return code


def group_of(header: ClipHeader) -> np.ndarray:
    """``(columns,)`` the group (joint, marker) of every value column."""
    if header.skeleton is not None:
        return np.repeat(np.arange(header.skeleton.n_joints, dtype=np.int64),
                         [len(c) for c in header.skeleton.channels])
    return np.repeat(np.arange(len(header.labels)), 3)


def zero_motion(header: ClipHeader, gaps: bytes | None, mask: np.ndarray | None = None) -> AnyMotion:
    """A motion of zeros (NaN on the stored gaps, or where ``mask`` ``(frames, markers)`` is set) to add the
    correction to."""
    if header.skeleton is not None:
        return header.motion(np.zeros((header.frames, header.n_columns)))
    pos = np.zeros(header.value_shape)
    if gaps is not None:
        mask = unpack_mask(gaps, (header.frames, len(header.labels)))
    if mask is not None:
        pos[mask] = math.nan
    return header.motion(pos)
