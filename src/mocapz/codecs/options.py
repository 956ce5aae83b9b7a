"""Codec options, declared once: name, kind, range or choices, default, one line of help.

Every codec lists its :class:`Option` declarations in its :class:`~mocapz.codecs.CodecInfo`; from them come
the API's validation (:func:`validate`, one :class:`~mocapz.errors.OptionError` naming the option and what
it accepts), the command-line flags, ``mocapz compress --codec NAME --help`` and ``docs/options.md``
(:func:`options_markdown`). Options are checked once, at the edge, before any input is read; a codec's
encoder receives the checked values (lengths as :class:`Length`, resolved against the clip's unit there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mocapz.errors import OptionError
from mocapz.model.units import Length, parse_length

KINDS = ("int", "float", "length", "percent", "bool", "choice", "names", "file", "weights", "indices")


@dataclass(frozen=True)
class Option:
    """One codec option.

    Attributes:
        name: the API keyword (``max_error``); the flag is ``--max-error``.
        kind: one of :data:`KINDS`.
        help: one line.
        default: the value used when the option is not given, or ``None`` when the codec decides (then
            ``default_text`` says how; an option the codec searches must stay ``None``).
        low, high: inclusive bounds of numbers (``low_open``: ``low`` itself excluded).
        choices: the accepted words of a ``choice``.
        cli: offered as a command-line flag (False: Python API only).
        default_text: how the default is chosen, for help and docs.
    """

    name: str
    kind: str
    help: str
    default: Any = None
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    cli: bool = True
    default_text: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"option {self.name}: unknown kind {self.kind!r}")

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    @property
    def metavar(self) -> str:
        return {"int": "N", "float": "X", "length": "LENGTH", "percent": "PCT", "choice": "|".join(self.choices),
                "names": "NAME,...", "file": "FILE", "weights": "SPEC", "indices": "I,..."}.get(self.kind, "")

    def accepts(self) -> str:
        """What the option accepts, in words (used by errors, help and docs)."""
        if self.kind in ("int", "float", "length", "percent"):
            what = {"int": "an integer", "float": "a number", "length": "a length (2cm, 4mm, 0.5 in file units)",
                    "percent": "a percentage"}[self.kind]
            lo = "" if self.low is None else (f"> {self.low:g}" if self.low_open else f">= {self.low:g}")
            hi = "" if self.high is None else f"<= {self.high:g}"
            bounds = " and ".join(b for b in (lo, hi) if b)
            return f"{what} {bounds}".strip()
        return {"bool": "true or false", "choice": "one of " + ", ".join(self.choices),
                "names": "comma-separated names", "file": "the path of an existing file",
                "weights": "a JSON file, LABEL=VALUE[,LABEL=VALUE] or a dict",
                "indices": "a list of frame indices"}[self.kind]

    def describe_default(self) -> str:
        if self.default_text is not None:
            return self.default_text
        if self.default is None:
            return "none"
        return str(self.default).lower() if isinstance(self.default, bool) else str(self.default)

    def check(self, value: Any, codec: str = "") -> Any:
        """The checked value (ints as int, lengths as :class:`Length`...); raises OptionError if it is bad."""
        try:
            out = self._convert(value)
        except (TypeError, ValueError, OverflowError):
            out = None
        if out is None or not self._in_range(out):
            of = f" of the {codec} codec" if codec else ""
            raise OptionError(f"option {self.name} ({self.flag}){of} must be {self.accepts()}; got {value!r}")
        return out

    def _convert(self, v: Any) -> Any:
        k = self.kind
        if k == "int":
            if isinstance(v, bool):
                return None
            f = float(v)
            return int(f) if math.isfinite(f) and f == int(f) else None
        if k in ("float", "percent"):
            if isinstance(v, bool):
                return None
            text = v.strip().rstrip("%") if isinstance(v, str) and k == "percent" else v
            f = float(text)
            return f if math.isfinite(f) else None
        if k == "length":
            return parse_length(v)
        if k == "bool":
            if isinstance(v, bool):
                return v
            t = str(v).strip().lower()
            return True if t in ("1", "true", "yes", "on") else False if t in ("0", "false", "no", "off") else None
        if k == "choice":
            t = str(v).strip().lower()
            return t if t in self.choices else None
        if k == "names":
            names = [n.strip() for n in v.split(",")] if isinstance(v, str) else [str(n).strip() for n in v]
            names = [n for n in names if n]
            return names or None
        if k == "file":
            return str(v) if Path(v).is_file() else None
        if k == "weights":
            if isinstance(v, dict):
                return dict(v)
            if isinstance(v, Path):
                return str(v) if v.is_file() else None
            if isinstance(v, str):
                return v if ("=" in v and not v.lower().endswith(".json")) or Path(v).is_file() else None
            return None
        if k == "indices":
            items = [x for x in v.split(",") if x.strip()] if isinstance(v, str) else list(v)
            out = [int(float(x)) for x in items]
            return out if all(i >= 0 for i in out) else None
        return None  # pragma: no cover - kinds are checked in __post_init__

    def _in_range(self, v: Any) -> bool:
        if self.kind not in ("int", "float", "length", "percent"):
            return True
        x = v.value if isinstance(v, Length) else v
        if self.low is not None and (x <= self.low if self.low_open else x < self.low):
            return False
        return self.high is None or x <= self.high


def validate(codec: str, declared: tuple[Option, ...], options: dict[str, Any]) -> dict[str, Any]:
    """Check ``options`` against a codec's declarations and return the checked values.

    Options given as ``None`` count as not given. Declared static defaults are filled in; options whose
    default is ``None`` (the codec decides) are left out when not given.
    """
    table = {o.name: o for o in declared}
    given = {k: v for k, v in options.items() if v is not None}
    unknown = sorted(set(given) - set(table))
    if unknown:
        names = ", ".join(f"{n} (--{n.replace('_', '-')})" for n in unknown)
        if not declared:
            raise OptionError(f"the {codec} codec takes no options; got {names}")
        flags = ", ".join(o.flag if o.cli else o.name for o in declared)
        raise OptionError(f"the {codec} codec has no option {names}; its options: {flags}")
    out = {o.name: o.default for o in declared if o.default is not None}
    for name, value in given.items():
        out[name] = table[name].check(value, codec)
    return out


def options_markdown(codecs: list[Any]) -> str:
    """``docs/options.md``: every codec's options, generated from the declarations."""
    lines = ["# Codec options", "",
             "Generated from the codecs' option declarations (`python -m mocapz.codecs > docs/options.md`;",
             "a test keeps this file in step). Lengths take a unit (`2cm`, `4mm`, `1in`) or are in the file's",
             "own length unit; `mocapz compress --codec NAME --help` prints the same table for one codec.", ""]
    for info in codecs:
        lines += [f"## `{info.name}`", "", info.summary, ""]
        if not info.options:
            lines += ["No options.", ""]
            continue
        lines += ["| option | flag | accepts | default | what it does |", "|---|---|---|---|---|"]
        for o in info.options:
            flag = f"`{o.flag}`" if o.cli else "(API only)"
            lines.append(f"| `{o.name}` | {flag} | {o.accepts()} | {o.describe_default()} | {o.help} |")
        lines.append("")
    return "\n".join(lines)

