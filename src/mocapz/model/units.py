"""Lengths given by users: ``"1cm"``, ``"4mm"``, ``"0.2"`` (file units).

A :class:`Length` keeps the number and the unit as given; it is resolved against a file's unit
(centimetres per file unit) only where the file is known.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from mocapz.errors import OptionError
from mocapz.model.motion import UNIT_CM

_LENGTH = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z]*)\s*$")


@dataclass(frozen=True)
class Length:
    """A length as the user gave it: a number in ``unit`` (``"mm"``, ``"cm"``, ``"m"``, ``"in"``), or in the
    file's own length unit when ``unit`` is empty."""

    value: float
    unit: str = ""

    def in_file_units(self, unit_cm: float | None, what: str = "length") -> float:
        """The length in file units, for a file whose unit is ``unit_cm`` centimetres (None: unknown)."""
        if not self.unit:
            return self.value
        if unit_cm is None:
            raise OptionError(f"{what}: the file's length unit is unknown; give the value in file units "
                              f"(without a unit) or say the file's unit with --unit")
        return self.value * UNIT_CM[self.unit] / unit_cm

    def __str__(self) -> str:
        return f"{self.value:g}{self.unit}"


def parse_length(text: Any) -> Length:
    """A :class:`Length` from ``0.5``, ``"0.5"``, ``"2cm"``, ``"4 mm"``; raises ValueError when malformed."""
    if isinstance(text, Length):
        return text
    if isinstance(text, bool):
        raise ValueError("not a length")
    if isinstance(text, int | float):
        return Length(float(text))
    m = _LENGTH.match(str(text))
    if not m:
        raise ValueError("not a length")
    unit = m.group(2).lower()
    if unit and unit not in UNIT_CM:
        raise ValueError(f"unknown unit {unit!r}")
    return Length(float(m.group(1)), unit)


def length_in_file_units(text: Any, unit_cm: float | None, what: str = "length") -> float:
    """A user's length (``0.5``, ``"2cm"``) in file units; OptionError naming ``what`` if it is bad."""
    try:
        length = parse_length(text)
    except ValueError:
        raise OptionError(f"{what}: cannot read {text!r} as a length (e.g. 0.5, 1cm, 4mm)") from None
    if length.value < 0:
        raise OptionError(f"{what}: must not be negative")
    return length.in_file_units(unit_cm, what)
