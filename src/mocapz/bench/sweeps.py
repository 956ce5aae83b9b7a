"""The settings each codec is measured at: a rate-distortion sweep per codec, full or quick.

The lossy codecs with a correction layer (``pga``, ``patterns``, ``quant``) are swept over max-error targets,
0.03-30 cm: what ``mocapz compress --max-error`` gives (their model's settings are then the codec's own choice;
fixed settings alone would all be corrected to the default 1 cm and give one point). The baselines
(``subsample``, ``pca``, ``segpca``) are swept over their settings, each corrected to the default target as well:
their models differ, so their points do (a setting equal to the default leaves the codec free to take the
correction alone).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mocapz.codecs import codec_names
from mocapz.errors import OptionError
from mocapz.model.motion import AnyMotion, Motion

#: General-purpose compressors, measured on the source file's bytes (lossless).
GENERIC = ("gzip", "bzip2", "xz", "zstd")

#: Codecs measured by default, in report order. ``lossless`` is the speed reference of every clip.
DEFAULT_CODECS = ("lossless", "pga", "patterns", "quant", "subsample", "pca", "segpca") + GENERIC

Setting = dict[str, Any]


def _unit_cm(motion: AnyMotion) -> float | None:
    return motion.skeleton.unit_cm if isinstance(motion, Motion) else motion.unit_cm


def _targets(motion: AnyMotion, quick: bool) -> list[Setting]:
    """Max-error targets in cm (file units where the unit is unknown: 1/1000 of the clip's extent for 1 mm)."""
    cms = (0.1, 0.3, 1.0, 3.0, 10.0) if quick else (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0)
    if _unit_cm(motion):
        return [{"max_error": f"{c:g}cm"} for c in cms]
    from mocapz.codecs.baselines.quant import default_error  # 1/1000 of the clip's extent stands for 1 mm

    unit = default_error(motion)
    return [{"max_error": float(f"{10 * c * unit:.6g}")} for c in cms]


def _subsample(motion: AnyMotion, quick: bool) -> list[Setting]:
    factors = (2, 4, 8) if quick else (1, 2, 3, 4, 6, 8, 12, 16, 24)
    return [{"factor": f} for f in factors]


def _pca(motion: AnyMotion, quick: bool) -> list[Setting]:
    vs = (0.95, 0.99, 0.999) if quick else (0.9, 0.95, 0.99, 0.995, 0.999, 0.9999, 0.99999)
    return [{"variance": v} for v in vs]


def _segpca(motion: AnyMotion, quick: bool) -> list[Setting]:
    grid = [(0.99, 6, 4), (0.999, 10, 4), (0.9999, 15, 2)] if quick else [
        (0.95, 4, 8), (0.99, 6, 8), (0.99, 6, 4), (0.995, 8, 4), (0.999, 10, 4), (0.999, 10, 2), (0.9999, 15, 2),
        (0.99999, 20, 1)]
    return [{"variance": v, "components": k, "key": key} for v, k, key in grid]


SWEEPS: dict[str, Callable[[AnyMotion, bool], list[Setting]]] = {
    "pga": _targets,
    "patterns": _targets,
    "quant": _targets,
    "subsample": _subsample,
    "pca": _pca,
    "segpca": _segpca,
}


def settings_for(codec: str, motion: AnyMotion, quick: bool) -> list[Setting]:
    """The sweep of ``codec`` on ``motion`` (one empty setting for codecs without a sweep)."""
    fn = SWEEPS.get(codec)
    return fn(motion, quick) if fn else [{}]


def label(setting: Setting) -> str:
    """Short text of a setting: ``geodesics=6 lod_root=3`` (``default`` when empty)."""
    return " ".join(f"{k}={v}" for k, v in setting.items()) or "default"


def parse_codecs(text: str | None) -> list[str]:
    """Codec list from ``--codecs a,b,...`` (default :data:`DEFAULT_CODECS`); ``lossless`` always first.

    Raises OptionError for an unknown name.
    """
    known = set(codec_names()) | set(GENERIC)
    if text is None or not text.strip():
        names = [c for c in DEFAULT_CODECS if c in known]
    else:
        names = []
        for n in (s.strip() for s in text.split(",")):
            if not n:
                continue
            if n not in known:
                raise OptionError(f"--codecs: unknown codec {n!r} (available: {', '.join(sorted(known))})")
            if n not in names:
                names.append(n)
    if "lossless" in names:
        names.remove("lossless")
    return ["lossless", *names]
