"""Pattern encoder for one clip: options -> settings (searched for a target) -> container sections."""

from __future__ import annotations

from typing import Any

import numpy as np

from mocapz.codecs.patterns.bodies import CodedClips, code_clips
from mocapz.codecs.patterns.decode import decode
from mocapz.codecs.patterns.options import settings_from
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.patterns.prepare import Prepared, prepare
from mocapz.codecs.patterns.rate import search
from mocapz.codecs.target import ErrorMetric, Target
from mocapz.model.header import ClipHeader
from mocapz.model.motion import AnyMotion, MarkerMotion


def encode(motion: AnyMotion, **options: Any) -> dict[str, bytes]:
    """Encode a motion with the pattern codec; returns the container sections.

    See :mod:`.options` for the options. With ``max_arms`` or ``max_distortion`` the encoder searches its
    thresholds and quantisation for the smallest output meeting the target, checked by decoding.
    """
    settings = settings_from(options)
    prep = prepare(motion, options.get("hierarchy"), options.get("weights"))
    target = target_from(motion, options)
    if motion.n_frames == 0:
        return {"h": prep.hier.to_bytes()}
    if target is None:
        return sections_of(code_once(motion, prep, settings), prep)
    fixed = {k for k in ("tolerance", "bits") if options.get(k) is not None}

    def run(s: Settings) -> tuple[list[np.ndarray], dict[str, bytes], int]:
        coded = code_once(motion, prep, s)
        sections = sections_of(coded, prep)
        return coded.decoded, sections, total_bytes(sections)

    metric = ErrorMetric(motion)

    def check(sections: dict[str, bytes]) -> float:
        return target.score(metric.of_motion(decode(sections, ClipHeader.of(motion))))

    return search(motion.name, [motion], settings, [target], fixed, prep.addh, run, check)


def target_from(motion: AnyMotion, options: dict[str, Any]) -> Target | None:
    """The rate-control target from checked options (None if no target is given)."""
    unit_cm = motion.unit_cm if isinstance(motion, MarkerMotion) else motion.skeleton.unit_cm
    target = Target.from_options(options, unit_cm)
    return target if target.active else None


def code_once(motion: AnyMotion, prep: Prepared, settings: Settings) -> CodedClips:
    return code_clips([motion], prep.hier, settings, prep.weights, prep.addh)


def sections_of(coded: CodedClips, prep: Prepared) -> dict[str, bytes]:
    """Container sections of a coded single clip: hierarchy, clip streams, node databases."""
    out = {"h": prep.hier.to_bytes()}
    out.update(coded.clip_sections[0])
    for k, db in enumerate(coded.dbs[1:], start=1):
        out[f"d{k}"] = db
    return out


def total_bytes(sections: dict[str, bytes]) -> int:
    """Payload size of sections, counting each name and length field like the container does."""
    return int(sum(len(v) + len(k) + 1 + max(1, (len(v).bit_length() + 6) // 7) for k, v in sections.items()))

