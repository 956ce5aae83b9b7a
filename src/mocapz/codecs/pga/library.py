"""Library mode of the PGA codec: one pose model (mean and basis) per group of clips, shared.

A single ``.mcz`` stores its own PGA model (the first two matrices of its ``data`` section: the header
column of moving-joint flags, mean and standard deviations, then the loadings; about 700 bytes on a CMU
clip). In a library the model is fitted once on the kept frames of all the group's clips (the intrinsic
mean and principal geodesics of their inner-joint rotations), quantised once, and stored in the group's
shared sections; every clip codes its trajectories and geodesic coordinates against it, and its own
``data`` section is the single-clip one without the two model matrices. The number of geodesics follows
the single-clip rule (``--variance`` of the group's pose variance, at most 20) unless ``--geodesics`` is
given; ``--bits`` fixes the loadings' grid. Each clip then gets the correction layer, so that its target
holds as when it is compressed alone.

Shared sections: ``m`` (the two model matrices, packed as in ``data``) and ``p`` (uvarint k, uvarint basis
bits, float64 mean step). A clip's own sections: ``params``, ``data`` (without the model), ``outl`` and the
correction's ``c.*``, as in a single file; or, when that is smaller, the sections of the clip's single file
(its own model) and the empty flag section ``own``; a group whose model would cost more than it saves keeps
none (no ``m``, ``p``: every clip with its own). New clips of the group (``--append``) are coded against the
stored model, the other clips untouched.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from mocapz.codecs.correction.wrap import corrected
from mocapz.codecs.library import LibraryMode, Sections, Work, layout_key
from mocapz.codecs.pga.codec import DECODE, ENCODE, VERSION, _base_options
from mocapz.codecs.pga.decode import decode as decode_single
from mocapz.codecs.pga.decode import with_turns
from mocapz.codecs.pga.effectors import find_effectors
from mocapz.codecs.pga.encode import Prepared, encode_prepared, prepare
from mocapz.codecs.pga.joints import check_skeleton, inner_joints
from mocapz.codecs.pga.model import PGAModel, fit_pga, k_for_variance
from mocapz.codecs.pga.options import DEFAULT, DEFAULT_VARIANCE, OPTIONS, fixed_settings
from mocapz.codecs.pga.packing import pack_matrices, unpack_matrices
from mocapz.codecs.pga.quantise import dequantise_model, model_from_matrices, model_matrices, quantise_model
from mocapz.codecs.pga.ratecontrol import default_settings, search
from mocapz.codecs.target import Target
from mocapz.errors import FormatError, OptionError
from mocapz.format.entropy import read_uvarint, write_uvarint
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion

MODEL_MATRICES = 2  # header column and loadings: the first matrices of a single clip's ``data``
MAX_K = 20  # the single-clip default's cap
FIT_FRAMES = 30_000  # a group's pose model is fitted on at most this many frames (about 4 minutes at 120 fps)
HOLD_FRAMES = 12_000  # frames of analysed clips kept from the fit to the coding (the others analysed again)
OWN = "own"  # flag section: the clip is coded with its own model (a single file's sections)


@dataclass
class SharedModel:
    """A group's quantised pose model.

    Attributes:
        ints: ``(n + 3n + k + 3mk, 1)`` its integers (:func:`~mocapz.codecs.pga.quantise.quantise_model`).
        model: the model the decoder rebuilds from them (``k`` directions, radians).
        k: number of principal geodesics.
        basis_bits: grid of the loadings (step ``2**-basis_bits`` rad).
        mean_step: grid step of the mean's rotation vectors (rad).
    """

    ints: np.ndarray
    model: PGAModel
    k: int
    basis_bits: int
    mean_step: float

    def sections(self) -> Sections:
        """The group's shared sections ``m`` and ``p``."""
        mats = model_matrices(self.ints, len(self.model.joints), self.k)
        params = write_uvarint(self.k) + write_uvarint(self.basis_bits) + struct.pack("<d", self.mean_step)
        return {"m": pack_matrices(mats), "p": params}

    @classmethod
    def from_sections(cls, shared: Mapping[str, bytes], joints: np.ndarray) -> SharedModel:
        """The model stored in a group's shared sections, for a skeleton whose inner joints are ``joints``."""
        p = shared["p"]
        k, pos = read_uvarint(p, 0)
        bits, pos = read_uvarint(p, pos)
        if len(p) != pos + 8 or not 1 <= k <= 3 * len(joints) or not 2 <= bits <= 24:
            raise FormatError(None, "corrupted PGA library model (parameters)")
        (step,) = struct.unpack("<d", p[pos:])
        if not np.isfinite(step) or step <= 0:
            raise FormatError(None, "corrupted PGA library model (mean step)")
        head, loadings = unpack_matrices(shared["m"], MODEL_MATRICES)
        ints = model_from_matrices(head, loadings)
        return cls(ints, dequantise_model(ints, joints, k, bits, step), k, bits, step)


def fit_shared(preps: list[Prepared], options: dict[str, Any]) -> SharedModel:
    """Fit and quantise the pose model of a group of prepared clips (same skeleton layout)."""
    inner = inner_joints(preps[0].motion.skeleton)
    return fit_rotations([p.clip.local_rot[:, inner] for p in preps if len(p.kept)], inner, options)


def fit_rotations(rots: list[np.ndarray], inner: np.ndarray, options: dict[str, Any]) -> SharedModel:
    """Fit and quantise the pose model of a group's inner-joint rotations (per clip ``(frames, n, 3, 3)``:
    its kept frames, or every s-th of them: :func:`encode_group`)."""
    rot = np.concatenate(rots) if rots else np.zeros((0, len(inner), 3, 3))
    del rots[:]  # the clips' arrays are not kept beside their concatenation (peak memory)
    if not len(rot):
        raise OptionError("compress-db --codec pga: the clips have no frames to fit a pose model on")
    model = fit_pga(rot, inner)
    del rot
    dim = model.basis.shape[1]
    k = options.get("geodesics")
    if k is None:
        k = min(k_for_variance(model, float(options.get("variance") or DEFAULT_VARIANCE)), MAX_K, dim)
    elif k > dim:
        raise OptionError(f"geodesics must be between 1 and {dim} (the pose dimension), got {k}")
    bits = int(options.get("bits") or DEFAULT.basis_bits)
    ints, model_q = quantise_model(model, int(k), bits, DEFAULT.mean_step)
    return SharedModel(ints, model_q, int(k), bits, DEFAULT.mean_step)


def _prepare(motion: Motion, options: dict[str, Any]) -> Prepared:
    if not isinstance(motion, Motion):
        raise OptionError("the pga codec does not take markers data (it takes skeleton data)")
    check_skeleton(motion.skeleton)
    names = options.get("effectors")
    effectors = list(find_effectors(motion.skeleton, names)) if names else None
    outl = options.get("outliers")
    return prepare(motion, effectors, None if outl is None else list(outl))


def encode_member(p: Prepared, shared: SharedModel, options: dict[str, Any]) -> Sections:
    """The model's sections of one clip coded against the shared model (``data`` without the model).

    ``options``: the pga options the model is coded with (a distortion / ARMS target is searched with the
    shared model's k, bits and mean step fixed).
    """
    fixed = fixed_settings(options)
    fixed.update(k=shared.k, basis_bits=shared.basis_bits, mean_step=shared.mean_step)
    if p.effectors is not None and options.get("effectors"):
        fixed["effectors"] = [int(e) for e in p.effectors]
    p.shared = (shared.ints, shared.model)
    target = Target.from_options(options, p.motion.skeleton.unit_cm)
    if target.active and p.full_model is not None:
        sections = search(p, fixed, target)[0]
    else:
        sections = encode_prepared(p, default_settings(p, fixed, options))
    sections = with_turns(p.motion.skeleton, sections, p.motion.n_frames)
    if "data" in sections:
        data, pos = sections["data"], 0
        for _ in range(MODEL_MATRICES):
            n, pos = read_uvarint(data, pos)
            pos += n
        sections["data"] = data[pos:]
    return sections


def _joined(shared: Mapping[str, bytes], own: Sections) -> Sections:
    """A clip's own sections with the shared model put back in front of its ``data``."""
    if "data" not in own:
        return own
    return {**own, "data": shared["m"] + own["data"]}


def _coder(p: Prepared, model: SharedModel, shared: Mapping[str, bytes], zero_base: bool = False,
           counted: bool = False) -> Any:
    """The correction layer's encoder and decoder of a clip coded against the shared ``model``; ``zero_base``: the
    correction alone may be chosen where it is smaller (a stream's block), the model's base then ``counted`` with
    the shared sections among its own (where the block would write them: the block before does not hold them)."""
    def base(motion: AnyMotion, **options: Any) -> Sections:
        own = encode_member(p, model, options)
        return {**shared, **own} if counted else own

    def dec(sections: Sections, header: ClipHeader) -> AnyMotion:
        return decode_single(_joined(shared, {k: v for k, v in sections.items() if k not in shared}), header)

    return corrected(base, dec, "pga", OPTIONS, _base_options, zero_base=zero_base)


def _both(p: Prepared, model: SharedModel, shared: Mapping[str, bytes], options: dict[str, Any]
          ) -> tuple[Sections, Sections]:
    """The clip coded against the shared model, and with its own model (its single file's sections and the
    flag section ``own``); both with the correction layer."""
    return _coder(p, model, shared)[0](p.motion, **options), {**ENCODE(p.motion, **options), OWN: b""}


def _size(sections: Sections) -> int:
    return sum(len(k) + 2 + len(v) for k, v in sections.items())


def encode_into(shared: Mapping[str, bytes], motions: list[AnyMotion], options: dict[str, Any], work: Work
                ) -> list[Sections]:
    """New clips coded against a group's stored model (or their own, when smaller; targets met by the
    correction layer)."""
    model = None
    if "m" in shared:  # else the group keeps no model (its clips' own were smaller)
        model = SharedModel.from_sections(shared, inner_joints(motions[0].skeleton))  # type: ignore[union-attr]
    out = []
    job = partial(_member, model, dict(shared), options)
    for m, pair in zip(motions, work.each(job, ((m, None) for m in motions)), strict=True):
        out.append(pair[1] if model is None else min(pair, key=_size))
        work.done(m.n_frames)
    return out


def _member(model: SharedModel | None, shared: Sections, options: dict[str, Any],
            item: tuple[Motion, Prepared | None]) -> tuple[Sections, Sections]:
    """One clip's two codings (:func:`_both`; with no model, its own twice), from its analysis when given
    (a picklable job)."""
    motion, p = item
    if model is None:
        own = {**ENCODE(motion, **options), OWN: b""}
        return own, own
    return _both(p if p is not None else _prepare(motion, options), model, shared, options)


def encode_group(motions: list[AnyMotion], options: dict[str, Any], work: Work
                 ) -> tuple[Sections, list[Sections], dict[str, Any]]:
    """A group's shared model, its clips' own sections and its index entry (k, bits).

    Memory stays bounded whatever the group's length: the model is fitted on at most :data:`FIT_FRAMES`
    frames (every ``s``-th kept frame of the group, in clip order, when it has more; all of them otherwise),
    and a clip's analysis (:func:`~mocapz.codecs.pga.encode.prepare`) is kept from the fit to the coding only
    while the kept ones hold at most :data:`HOLD_FRAMES` frames (the others are analysed again: the same
    result, so the same bytes)."""
    stride = max(1, -(-sum(m.n_frames for m in motions) // FIT_FRAMES))
    rots: list[np.ndarray] = []
    held: dict[int, Prepared] = {}
    taken = 0  # kept frames of the group so far: where the sample goes on in the next clip
    for i, m in enumerate(motions):
        p = _prepare(m, options)  # type: ignore[arg-type]
        if len(p.kept):
            inner = inner_joints(p.motion.skeleton)
            rots.append(p.clip.local_rot[(-taken) % stride::stride, inner])
            taken += len(p.kept)
        if sum(len(h.kept) for h in held.values()) + len(p.kept) <= HOLD_FRAMES:
            held[i] = p
        del p
    model = fit_rotations(rots, inner_joints(motions[0].skeleton), options)  # type: ignore[union-attr]
    shared = model.sections()
    pairs = []
    items = ((m, held.pop(i, None)) for i, m in enumerate(motions))  # an analysis let go once sent
    for m, pair in zip(motions, work.each(partial(_member, model, shared, options), items), strict=True):
        pairs.append(pair)
        work.done(m.n_frames)
    own = [min(pair, key=_size) for pair in pairs]
    if sum(map(_size, own)) + _size(shared) >= sum(_size(pair[1]) for pair in pairs):
        # the model is worth less than it costs: no shared model, every clip with its own
        return {}, [pair[1] for pair in pairs], {"geodesics": None, "bits": None}
    return shared, own, {"geodesics": model.k, "bits": model.basis_bits}


def decode_member(shared: Mapping[str, bytes], own: Sections, header: ClipHeader) -> AnyMotion:
    """One clip from its group's shared model and its own sections (correction applied); a clip with the
    ``own`` flag section is a single file's sections (its own model)."""
    if OWN in own:
        return DECODE({k: v for k, v in own.items() if k != OWN}, header)

    def dec(sections: Sections, h: ClipHeader) -> AnyMotion:
        return decode_single(_joined(shared, sections), h)

    return corrected(lambda motion, **o: {}, dec, "pga", OPTIONS, zero_base=False)[1](own, header)


MODE = LibraryMode("pga", VERSION, encode_group, encode_into, decode_member, layout_key)
