"""Parsing of lengths given by users: ``"1cm"``, ``"4mm"``, ``"0.2"`` (file units)."""

from __future__ import annotations

import re

from mocapz.errors import OptionError
from mocapz.model.motion import UNIT_CM

_LENGTH = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z]*)\s*$")


def parse_length(text: str | float, unit_cm: float | None, what: str = "length") -> float:
    """A length in file units from a number (file units) or a number with a unit (mm, cm, m, in).

    Raises OptionError if the text is malformed, negative, or has a unit while the file's is unknown.
    """
    if isinstance(text, int | float):
        value, unit = float(text), ""
    else:
        m = _LENGTH.match(text)
        if not m:
            raise OptionError(f"{what}: cannot read {text!r} as a length (e.g. 0.5, 1cm, 4mm)")
        value, unit = float(m.group(1)), m.group(2).lower()
    if value < 0:
        raise OptionError(f"{what}: must not be negative")
    if not unit:
        return value
    if unit not in UNIT_CM:
        raise OptionError(f"{what}: unknown unit {unit!r} (use mm, cm, m or in)")
    if unit_cm is None:
        raise OptionError(f"{what}: the file's length unit is unknown; give the value in file units")
    return value * UNIT_CM[unit] / unit_cm
