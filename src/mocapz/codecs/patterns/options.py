"""Options of the pattern codec: validation, weights, and the encoder settings they give.

Options (``compress(motion, codec="patterns", **options)``; lengths relative to the ADDH unless noted):

* ``max_arms``: target ARMS, file units or with a unit (``"6.5mm"``); the encoder searches its settings
  and checks the result by decoding.
* ``max_distortion``: target ``distortion_pct`` (METRICS.md), searched the same way.
* ``theta``: Algorithm 1 key-frame threshold (fraction of the ADDH).
* ``ratio``: Algorithm 1 ratio threshold.
* ``tolerance``: clustering distortion threshold (fraction of the ADDH).
* ``clusters``: initial number of clusters K.
* ``metric``: ``"max"`` (MaxError, eq. 2) or ``"ave"`` (AveError, eq. 1).
* ``bits``: quantisation bits of the pattern deltas.
* ``heading``: express node offsets in a frame turning with the body (extension; False = the paper).
* ``weights``: per-marker (or per-joint) weights: a dict, a JSON file ``{"LFHD": 10, ...}``, or the text
  ``"LFHD=10,RFHD=10"``.
* ``hierarchy``: JSON file giving the body-part hierarchy (:mod:`.hierarchy_json`).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mocapz.codecs.patterns.kmeans import AVE, MAX
from mocapz.codecs.patterns.pipeline import Settings
from mocapz.errors import OptionError

OPTIONS: dict[str, str] = {
    "max_arms": "target ARMS, file units or with a unit (6.5mm); searched, checked by decoding",
    "max_distortion": "target distortion_pct; searched, checked by decoding",
    "theta": "Algorithm 1 key-frame threshold, fraction of the ADDH (head-marker diagonal)",
    "ratio": "Algorithm 1 ratio threshold",
    "tolerance": "clustering distortion threshold (MaxError bound), fraction of the ADDH",
    "clusters": "initial number of clusters K",
    "metric": "clustering error metric: max (eq. 2) or ave (eq. 1)",
    "bits": "quantisation bits of the pattern delta frames",
    "heading": "node offsets in a body-turning frame (true) or world axes as in the paper (false)",
    "weights": "per-marker weights: dict, JSON file or LABEL=VALUE[,LABEL=VALUE]",
    "hierarchy": "JSON file giving the body-part hierarchy",
}

DEFAULT = Settings()


def _number(name: str, value: Any, lo: float, hi: float, integer: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or not lo <= v <= hi or (integer and v != int(v)):
        kind = "an integer" if integer else "a number"
        raise OptionError(f"{name}: must be {kind} between {lo:g} and {hi:g}, got {value!r}")
    return int(v) if integer else v


def _flag(name: str, value: Any) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise OptionError(f"{name}: expected true or false, got {value!r}")


def settings_from(options: dict[str, Any], base: Settings = DEFAULT) -> Settings:
    """Encoder settings from the explicit options (targets, weights and hierarchy are handled apart)."""
    unknown = set(options) - set(OPTIONS)
    if unknown:
        raise OptionError(f"unknown option(s) for the patterns codec: {', '.join(sorted(unknown))} "
                          f"(known: {', '.join(OPTIONS)})")
    s = base
    if options.get("theta") is not None:
        s = replace(s, theta=_number("theta", options["theta"], 1e-4, 10.0))
    if options.get("ratio") is not None:
        s = replace(s, ratio=_number("ratio", options["ratio"], 1.0, 100.0))
    if options.get("tolerance") is not None:
        s = replace(s, tol=_number("tolerance", options["tolerance"], 0.0, 10.0))
    if options.get("clusters") is not None:
        s = replace(s, k0=int(_number("clusters", options["clusters"], 1, 100000, integer=True)))
    if options.get("bits") is not None:
        s = replace(s, bits=int(_number("bits", options["bits"], 1, 16, integer=True)))
    if options.get("metric") is not None:
        if options["metric"] not in (MAX, AVE):
            raise OptionError(f"metric: expected 'max' or 'ave', got {options['metric']!r}")
        s = replace(s, metric=options["metric"])
    if options.get("heading") is not None:
        s = replace(s, heading=_flag("heading", options["heading"]))
    return s


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
