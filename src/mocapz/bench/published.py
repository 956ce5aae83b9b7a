"""Published operating points (../shared/METRICS.md, "Reference operating points"), shown beside the
measured curves. They were measured by their authors, mostly on other clips than ours: reports mark
them as published figures and name their clip.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Published:
    """One published operating point (or range).

    Attributes:
        system: who published it (paper and table).
        clip: the clip it was measured on (CMU trial id, or a description).
        ratio: ``(low, high)`` compression ratio (equal for a single figure).
        metric: the error figure it is given at (``distortion_pct``, ``arms_cm``) or ``None`` if none.
        error: ``(low, high)`` error, in the metric's unit (``arms_cm`` in cm).
        note: what to keep in mind when comparing.
    """

    system: str
    clip: str
    ratio: tuple[float, float]
    metric: str | None
    error: tuple[float, float] | None
    note: str = ""

    @property
    def short(self) -> str:
        return f"{self.system} ({self.clip})"


PUBLISHED: tuple[Published, ...] = (
    Published("PGA paper, Table 2", "09_06 run", (18, 18), "distortion_pct", (0.36, 0.36),
              "same trial as cmu/bvh/09_06 (the paper leaves out the T-pose frame)"),
    Published("PGA paper, Table 2", "17_08 slow walk", (182, 182), "distortion_pct", (0.049, 0.049)),
    Published("PGA paper, Table 2", "15_04 dance/boxing", (69, 69), "distortion_pct", (1.55, 1.55)),
    Published("PGA paper, Table 2", "85_12 breakdance", (97, 97), "distortion_pct", (0.56, 0.56)),
    Published("PGA paper, Table 2", "17_10 boxing", (61, 61), "distortion_pct", (0.49, 0.49)),
    Published("PGA paper, Table 3 (Liu & McMillan 2006)", "various CMU", (18, 62), "distortion_pct", (5.1, 7.1)),
    Published("pattern paper, Table I", "CMU marker sets", (23, 42), "arms_cm", (0.41, 0.65),
              "ARMS 4.1-6.5, taken as mm (the unit of CMU C3D marker data)"),
    Published("Arikan 2006", "CMU-like database", (30, 30), None, None,
              "no error figure: \"little visible degradation\""),
)


def same_clip(p: Published, clip_id: str) -> bool:
    """Whether a published point was measured on this clip (CMU trial id as the file stem)."""
    trial = p.clip.split()[0]
    stem = clip_id.rsplit("/", 1)[-1].split(".")[0]
    return "_" in trial and trial == stem
