"""Options of the pattern codec: declarations, the encoder settings they give, and member weights.

Lengths of the Algorithm 1 and clustering thresholds are relative to the ADDH (the head-marker diagonal,
or its skeletal equivalent). Options not given keep :class:`~mocapz.codecs.patterns.pipeline.Settings`'
defaults; with a target the encoder searches ``tolerance`` and ``bits`` unless they are given.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.codecs.options import Option
from mocapz.codecs.patterns.kmeans import AVE, MAX
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.codecs.target import TARGET_OPTIONS
from mocapz.errors import OptionError

DEFAULT = Settings()
SEARCHED = "; searched with a target"

OPTIONS: tuple[Option, ...] = TARGET_OPTIONS + (
    Option("theta", "float", "Algorithm 1 key-frame threshold, fraction of the ADDH (head-marker diagonal)",
           low=1e-4, high=10.0, default_text=str(DEFAULT.theta)),
    Option("ratio", "float", "Algorithm 1 ratio threshold", low=1.0, high=100.0, default_text=str(DEFAULT.ratio)),
    Option("tolerance", "float", "clustering threshold (MaxError bound), fraction of the ADDH", low=0.0, high=10.0,
           default_text=f"{DEFAULT.tol}{SEARCHED}"),
    Option("clusters", "int", "initial number of clusters K", low=1, high=100000, default_text=str(DEFAULT.k0)),
    Option("metric", "choice", "clustering error metric: max (eq. 2) or ave (eq. 1)", choices=(MAX, AVE),
           default_text=DEFAULT.metric),
    Option("bits", "int", "quantisation bits of the pattern delta frames", low=1, high=16,
           default_text=f"{DEFAULT.bits}{SEARCHED}"),
    Option("heading", "bool", "node offsets in a body-turning frame (true) or world axes as in the paper (false)",
           default_text=str(DEFAULT.heading).lower()),
    Option("weights", "weights", "per-marker (or per-joint) weights: JSON file or LABEL=VALUE[,LABEL=VALUE]",
           default_text="1 for every member"),
    Option("hierarchy", "file", "JSON file giving the body-part hierarchy",
           default_text="from the marker names, or the joint tree"),
)

_SETTING = {"theta": "theta", "ratio": "ratio", "tolerance": "tol", "clusters": "k0", "metric": "metric",
            "bits": "bits", "heading": "heading"}


def settings_from(options: dict[str, Any], base: Settings = DEFAULT) -> Settings:
    """Encoder settings from checked options (targets, weights and hierarchy are handled apart)."""
    return replace(base, **{_SETTING[k]: options[k] for k in _SETTING if options.get(k) is not None})


def _number(name: str, value: Any, lo: float, hi: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or not lo <= v <= hi:
        raise OptionError(f"{name}: must be a number between {lo:g} and {hi:g}, got {value!r}")
    return v


def parse_weights(spec: Any, names: list[str], source: str | None = None) -> np.ndarray:
    """Member weights ``(members,)`` (default 1) from a dict, a JSON file or ``"A=1,B=2"`` text.

    Raises OptionError naming the file (the weights file, else ``source``, the motion's file) and the
    label for unknown labels or bad values.
    """
    w = np.ones(len(names))
    if spec is None:
        return w
    where = f"{source}: weights" if source else "weights"
    if isinstance(spec, dict):
        table = spec
    elif isinstance(spec, Path) or (isinstance(spec, str) and (spec.lower().endswith(".json") or "=" not in spec)):
        path = Path(spec)
        where = f"{path}: weights"
        if not path.is_file():
            raise OptionError(f"{where}: no such file")
        try:
            table = json.loads(path.read_text(encoding="utf-8"))
        except (ValueError, UnicodeDecodeError) as exc:
            raise OptionError(f"{where}: not valid JSON ({exc})") from None
        if isinstance(table, dict) and isinstance(table.get("weights"), dict):
            table = table["weights"]
        if not isinstance(table, dict):
            raise OptionError(f'{where}: expected an object {{"LABEL": weight, ...}}')
    elif isinstance(spec, str):
        table = {}
        for item in spec.split(","):
            label, sep, value = item.partition("=")
            if not sep or not label.strip():
                raise OptionError(f"weights: expected LABEL=VALUE, got {item!r}")
            table[label.strip()] = value.strip()
    else:
        raise OptionError(f"weights: expected a dict, a JSON file or LABEL=VALUE text, got {type(spec).__name__}")
    index = {n: i for i, n in enumerate(names)}
    for label, value in table.items():
        if label not in index:
            raise OptionError(f"{where}: unknown label {label!r} (not in this file)")
        w[index[label]] = _number(f"{where} for {label!r}", value, 0.0, 1e6)
    return w
