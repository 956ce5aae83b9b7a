"""Global PCA baseline (the pattern-indexing paper's baseline): one linear subspace for the whole clip.

Encoder: the value matrix (:mod:`.common`) is put in common length units (:func:`column_scale`: rotation
channels as radians times the skeleton's mean bone length, so a unit of every column moves a body point
by about one file length unit), centred on its per-column mean, and projected on its first ``K``
principal directions (SVD). Stored as **float32**, no entropy coding (as the papers' PCA baselines):
the mean ``(columns,)``, the directions ``(K, columns)`` and the coefficients ``(frames, K)``.

Options: ``variance``: fraction of the (scaled) variance to keep, ``0 < v <= 1`` (default 0.95), which
chooses ``K``; or ``components``: ``K`` itself (takes precedence). ``variance=1`` keeps every component:
exact up to float32.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.codecs import CodecInfo
from mocapz.codecs.baselines.common import (
    f32_array,
    f32_bytes,
    finish,
    gaps_bytes,
    gaps_from,
    layout_columns,
    read_uvarints,
    uvarints,
    values_of,
)
from mocapz.codecs.correction.wrap import apply_window, corrected
from mocapz.codecs.options import Option
from mocapz.codecs.ratesearch import check_target, coarsest_meeting
from mocapz.codecs.target import TARGET_OPTIONS, Target
from mocapz.errors import FormatError
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, Motion

VERSION = 3  # 2: the correction layer (codecs/correction); 3: its knots and details in two streams
DEFAULT_VARIANCE = 0.95
OPTIONS: tuple[Option, ...] = TARGET_OPTIONS + (
    Option("variance", "float", "fraction of the variance kept", low=0.0, high=1.0, low_open=True,
           default=DEFAULT_VARIANCE),
    Option("components", "int", "number of principal components K (overrides variance)", low=1, high=1_000_000,
           default_text="from --variance; searched with a target"),
)


def column_scale(header: ClipHeader) -> np.ndarray:
    """Per-column factor ``(columns,)`` putting values in length units before PCA.

    Rotation channels: radians per angle unit times the mean non-zero bone length (offsets and end
    sites) of the skeleton; position channels and marker coordinates: 1.
    """
    cols, rot, _ = layout_columns(header)
    scale = np.ones(cols)
    sk = header.skeleton
    if sk is not None and rot.any():
        offs = [np.asarray(o, dtype=np.float64) for o in sk.offsets]
        offs += [np.asarray(o, dtype=np.float64) for _, o, _ in sk.end_sites]
        lengths = np.linalg.norm(np.array(offs).reshape(-1, 3), axis=1)
        lengths = lengths[lengths > 1e-9]
        bone = float(lengths.mean()) if lengths.size else 1.0
        per_unit = np.pi / 180.0 if sk.angle_unit == "deg" else 1.0
        scale[rot] = per_unit * bone
    return scale


def components_for(singular: np.ndarray, variance: float) -> int:
    """Smallest K whose first K squared singular values hold ``variance`` of their sum (at least 1)."""
    energy = singular.astype(np.float64) ** 2
    total = energy.sum()
    if total <= 0:
        return 1
    if variance >= 1.0:
        return int(len(singular))
    k = int(np.searchsorted(np.cumsum(energy) / total, variance - 1e-12) + 1)
    return max(1, min(k, len(singular)))


def fit(y: np.ndarray, variance: float, components: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """PCA of ``y`` ``(frames, columns)``: float32-exact mean ``(columns,)``, basis ``(K, columns)`` and
    coefficients ``(frames, K)`` (computed against the float32-rounded mean and basis)."""
    mean = y.mean(axis=0) if len(y) else np.zeros(y.shape[1])
    mean = mean.astype(np.float32).astype(np.float64)
    centred = y - mean
    if min(centred.shape) == 0:
        return mean, np.zeros((0, y.shape[1])), np.zeros((len(y), 0))
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    k = min(components, len(s)) if components is not None else components_for(s, variance)
    basis = vt[:k].astype(np.float32).astype(np.float64)
    # least-squares coefficients against the rounded basis (stays optimal though it is not exactly orthonormal)
    coef = np.linalg.lstsq(basis.T, centred.T, rcond=None)[0].T if k else np.zeros((len(y), 0))
    return mean, basis, coef


def scale_of(motion: AnyMotion) -> np.ndarray:

    if isinstance(motion, Motion):
        return column_scale(ClipHeader.of(motion))
    return np.ones(3 * motion.n_markers)


def encode(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    """Sections: ``head`` (K), ``mean``, ``basis``, ``coef`` (float32), ``gaps`` (markers with gaps)."""
    target = Target.from_options(options, motion.unit_cm)
    variance, k = options["variance"], options.get("components")
    if not target.active:
        return encode_components(motion, variance, k)
    if k is not None:
        return check_target(motion, target, encode_components(motion, variance, k), decode, "pca")
    cols = max(1, motion.values[:1].size)
    return coarsest_meeting(motion, target, range(cols, 0, -1), lambda c: encode_components(motion, 1.0, c),
                            decode, "pca")


def encode_components(motion: AnyMotion, variance: float, k: int | None) -> dict[str, bytes]:
    """Sections of a PCA keeping ``k`` components (None: those explaining ``variance``)."""
    v = values_of(motion)
    scale = scale_of(motion)
    mean, basis, coef = fit(v.x * scale, variance, k)
    sections = {"head": uvarints(basis.shape[0]), "mean": f32_bytes(mean), "basis": f32_bytes(basis),
                "coef": f32_bytes(coef)}
    if v.gaps is not None:
        sections["gaps"] = gaps_bytes(v.gaps)
    return sections


def decode(sections: dict[str, bytes], header: ClipHeader) -> AnyMotion:
    """Inverse of :func:`encode`: ``coef @ basis + mean``, unscaled."""
    frames = header.frames
    cols, _, _ = layout_columns(header)
    try:
        (k,), _ = read_uvarints(sections["head"], 1)
        mean = f32_array(sections["mean"], (cols,))
        basis = f32_array(sections["basis"], (k, cols))
        coef = f32_array(sections["coef"], (frames, k))
    except KeyError as exc:
        raise FormatError(None, f"corrupted pca stream (missing section {exc})") from None
    y = coef @ basis + mean
    return finish(header, y / column_scale(header), gaps_from(sections, header), round_decimals=True)


ENCODE, DECODE = corrected(encode, decode, "pca", OPTIONS)
INFO = CodecInfo(name="pca", version=VERSION, kinds=("skeleton", "markers"), encode=ENCODE, decode=DECODE,
                 options=OPTIONS, decode_window=apply_window,
                 summary="baseline: one PCA of the whole clip (the pattern paper's Fig. 9)")
