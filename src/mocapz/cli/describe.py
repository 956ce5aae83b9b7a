"""``mocapz info``: describe a motion file, a .mcz file or a .mczdb library."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mocapz.errors import FormatError
from mocapz.model.c3d_extras import C3DExtras
from mocapz.model.motion import Motion


def describe_motion(motion: Any) -> dict[str, Any]:
    d: dict[str, Any] = {"name": motion.name, "format": motion.source_format, "frames": motion.n_frames,
                         "frame_rate": motion.frame_rate, "duration_s": motion.duration,
                         "raw_bytes": motion.raw_bytes}
    if isinstance(motion, Motion):
        sk = motion.skeleton
        d.update(joints=sk.n_joints, end_sites=len(sk.end_sites), channels=sk.n_channels,
                 unit_cm=sk.unit_cm, unit_note=sk.unit_note, angle_unit=sk.angle_unit,
                 root=sk.names[0], joint_names=sk.names)
    else:
        d.update(markers=motion.n_markers, units=motion.units, unit_cm=motion.unit_cm,
                 missing_pct=100.0 * float(motion.missing.mean()) if motion.positions.size else 0.0,
                 labels=motion.labels)
        extras = motion.metadata.get("c3d")
        if isinstance(extras, C3DExtras):
            d.update(_c3d_summary(extras, motion.frame_rate))
    return d


def _c3d_summary(extras: C3DExtras, rate: float) -> dict[str, Any]:
    """What a C3D file holds besides its markers: storage, model-output tracks, analog channels."""
    cpu = {84: "Intel", 85: "DEC", 86: "SGI/MIPS"}[extras.processor]
    storage = f"{cpu} float32" if extras.is_float else f"{cpu} int16 x {extras.quantum or 'per-point scales'}"
    kinds: dict[str, int] = {}
    for kind, unit in zip(extras.track_kinds, extras.track_units, strict=True):
        key = f"{kind} ({unit})" if unit else kind
        kinds[key] = kinds.get(key, 0) + 1
    d: dict[str, Any] = {"c3d_storage": storage,
                         "tracks": ", ".join(f"{n} {k}" for k, n in kinds.items()) or "none",
                         "analog_channels": extras.channels}
    if extras.channels:
        d["analog_rate"] = rate * extras.samples
    return d


def describe(path: Path) -> dict[str, Any]:
    if not path.exists():
        raise FormatError(path, "no such file")
    suffix = path.suffix.lower()
    if suffix == ".mczdb":
        from mocapz.libraries import describe_library

        return describe_library(path)
    if suffix == ".mcz":
        from mocapz.api import read_container
        from mocapz.files import open_motion

        data = path.read_bytes()
        box, _ = read_container(data, path)
        d = {"file": str(path), "container_bytes": len(data), "codec": box.codec,
             "codec_version": box.codec_version,
             "sections": [f"{k}={len(v)}B" for k, v in box.sections.items()],
             "layout_bytes": len(box.layout)}
        motion = open_motion(path).motion
        d.update(describe_motion(motion))
        d["ratio"] = motion.raw_bytes / len(data)
        return d
    from mocapz.io import load

    motion = load(path)
    d = {"file": str(path), "file_bytes": path.stat().st_size}
    d.update(describe_motion(motion))
    return d
