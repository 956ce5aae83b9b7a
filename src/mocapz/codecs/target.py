"""The quality targets every lossy codec takes, and the one error metric their rate control measures.

Three targets, one meaning in every codec (METRICS.md):

* ``max_error``: the largest position error of any joint, end site or marker in any frame (present
  samples only), a length;
* ``max_distortion``: the global distortion ``distortion_pct`` (Karni-Gotsman), in percent;
* ``max_arms``: the pattern paper's ARMS (mean over frames of the RMS error over points), a length.

:class:`Target` holds them in file units; :class:`ErrorMetric` computes the three figures of a decoded
result against the original's positions (skeletons: forward kinematics of all joints and end sites;
markers: the present samples), like ACL's ``transform_error_metric`` serves all of its rate control.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapz.codecs.options import Length, Option
from mocapz.metrics.figures import arms, distortion_pct, point_errors
from mocapz.model.kinematics import forward_positions
from mocapz.model.motion import AnyMotion, MarkerMotion, Motion

#: what a lossy codec meets when no target is given (codecs/correction)
DEFAULT_TARGET = "max error 1 cm on every joint, end site and marker of every frame, planted feet held " \
                 "(1/170 of the body height when the length unit is unknown)"
DEFAULT_TARGET_TEXT = f"none given: the default target, {DEFAULT_TARGET}"

EFFORTS = ("fast", "medium", "best")  # the correction's search effort (option ``effort``; fast by default: over
# the 39 shared files of a known length unit at 1 cm, fast against medium: quant -0.2 % bytes at 2.3x the speed,
# patterns -0.2 % at 1.4x, pga +1.2 % at 2.1x; docs/benchmarks/effort.md)
DEFAULT_EFFORT = "fast"

#: the target options, declared once and listed by every lossy codec (then ``hold_feet`` and ``effort``)
TARGET_OPTIONS: tuple[Option, ...] = (
    Option("max_error", "length", "target: largest position error of any joint, end site or marker in any frame",
           low=0.0, low_open=True, default_text=DEFAULT_TARGET_TEXT),
    Option("max_distortion", "percent", "target: largest global distortion_pct (METRICS.md)", low=0.0,
           low_open=True),
    Option("max_arms", "length", "target: largest ARMS (mean over frames of the RMS error over points)", low=0.0,
           low_open=True),
    Option("hold_feet", "bool", "keep planted feet still: on the original's foot contacts (METRICS.md) the speed "
           "the decoded feet add is verified (at most 0.3 cm/s, frame to frame and over 0.1 s) and the joints above "
           "them tightened until it holds", default=True),
    Option("effort", "choice", "how hard the correction searches for the smallest file meeting the target: fast "
           "(one lifting depth, knots an eighth of a second apart, coded once), medium (three depths, a long clip's "
           "chosen on two 6-s windows: about 2x the time, as often smaller as larger), best (three depths, each coded "
           "on the whole clip); every one meets the target", default=DEFAULT_EFFORT, choices=EFFORTS),
)
TARGET_NAMES = ("max_error", "max_distortion", "max_arms")
CORRECTION_NAMES = ("hold_feet", "effort")  # the correction layer's own options (not the model's settings)


@dataclass(frozen=True)
class Errors:
    """The three target figures of one decoded result: distortion_pct (%), max error and ARMS (file units)."""

    distortion_pct: float
    max_error: float
    arms: float


@dataclass(frozen=True)
class Target:
    """Rate-control target in file units (``None``: no bound on that figure)."""

    max_error: float | None = None
    max_distortion: float | None = None
    max_arms: float | None = None

    @classmethod
    def from_options(cls, options: dict[str, Any], unit_cm: float | None) -> Target:
        """The target from checked options (:func:`mocapz.codecs.options.validate`), for a clip whose length
        unit is ``unit_cm`` centimetres."""
        def length(name: str) -> float | None:
            v = options.get(name)
            if v is None:
                return None
            return v.in_file_units(unit_cm, name) if isinstance(v, Length) else float(v)

        d = options.get("max_distortion")
        return cls(length("max_error"), None if d is None else float(d), length("max_arms"))

    @property
    def active(self) -> bool:
        return any(v is not None for v in (self.max_error, self.max_distortion, self.max_arms))

    def limits(self, e: Errors) -> list[tuple[float, float]]:
        """``(limit, measured)`` of every bounded figure, in the order distortion, max error, ARMS."""
        pairs = ((self.max_distortion, e.distortion_pct), (self.max_error, e.max_error), (self.max_arms, e.arms))
        return [(lim, val) for lim, val in pairs if lim is not None]

    def met(self, e: Errors) -> bool:
        return all(val <= lim for lim, val in self.limits(e))

    def score(self, e: Errors) -> float:
        """Largest measured / allowed over the bounded figures (<= 1 meets the target)."""
        s = 0.0
        for lim, val in self.limits(e):
            s = max(s, val / lim if lim > 0 else (0.0 if val == 0 else math.inf))
        return s

    def scaled(self, factor: float) -> Target:
        """Every bound times ``factor`` (headroom for estimates)."""
        def f(v: float | None) -> float | None:
            return None if v is None else v * factor

        return Target(f(self.max_error), f(self.max_distortion), f(self.max_arms))

    def describe(self) -> str:
        parts = []
        if self.max_error is not None:
            parts.append(f"max error <= {self.max_error:.4g} file units")
        if self.max_distortion is not None:
            parts.append(f"distortion <= {self.max_distortion:.4g} %")
        if self.max_arms is not None:
            parts.append(f"ARMS <= {self.max_arms:.4g} file units")
        return ", ".join(parts)


class ErrorMetric:
    """The target figures of decoded results against one original clip.

    Args:
        original: the clip the codec encodes.
        positions: its positions ``(frames, points, 3)`` if already computed (skeletons).
    """

    def __init__(self, original: AnyMotion, positions: np.ndarray | None = None) -> None:
        self.original = original
        if isinstance(original, Motion):
            self.positions = forward_positions(original.skeleton, original.channels) if positions is None \
                else positions
            self.valid: np.ndarray | None = None
        else:
            self.positions = original.positions
            self.valid = ~original.missing

    @staticmethod
    def between(a: np.ndarray, b: np.ndarray, valid: np.ndarray | None = None) -> Errors:
        """Figures of positions ``b`` against ``a`` (both ``(frames, points, 3)``) over the ``valid``
        ``(frames, points)`` samples (default: all)."""
        with np.errstate(invalid="ignore"):
            err = point_errors(a, b)
        if valid is None:
            return Errors(distortion_pct(a, b), float(err.max()) if err.size else 0.0,
                          arms(err, np.ones(err.shape, dtype=bool)))
        ev = err[valid]
        if not np.isfinite(ev).all():  # a decoded sample missing where the original has one
            return Errors(math.inf, math.inf, math.inf)
        return Errors(distortion_pct(a, b, valid), float(ev.max()) if ev.size else 0.0, arms(err, valid))

    def of_positions(self, decoded: np.ndarray) -> Errors:
        """Figures of decoded positions ``(frames, points, 3)`` against the original's."""
        return self.between(self.positions, decoded, self.valid)

    def of_motion(self, decoded: AnyMotion) -> Errors:
        """Figures of a decoded motion (skeletons: its channels through the original skeleton)."""
        if isinstance(decoded, MarkerMotion):
            return self.of_positions(decoded.positions)
        assert isinstance(self.original, Motion)
        return self.of_positions(forward_positions(self.original.skeleton, decoded.channels))
