"""What every command shares: -q/-v, messages on stderr, --json on stdout, frame ranges, --unit, progress.

Conventions (zstd's where they fit): data and ``--json`` go to stdout, every message to stderr; ``-q``
silences messages and progress, ``-v`` adds detail; a progress display (rich) appears on stderr only when
it is a terminal.
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from mocapz.errors import MocapzError, OptionError
from mocapz.model.motion import UNIT_CM, AnyMotion, MarkerMotion, Motion

#: ``--unit`` choices, in centimetres (``cmu``: the CMU skeleton unit, 2.54/0.45 cm)
UNITS = {"mm": 0.1, "cm": 1.0, "m": 100.0, "in": 2.54, "cmu": 2.54 / 0.45}


class Say:
    """Messages for one command run: ``info`` unless ``-q``, ``detail`` only with ``-v``; all on stderr."""

    def __init__(self, quiet: bool = False, verbose: bool = False) -> None:
        self.quiet, self.verbose = quiet, verbose

    def info(self, text: str) -> None:
        if not self.quiet:
            click.echo(text, err=True)

    def detail(self, text: str) -> None:
        if self.verbose and not self.quiet:
            click.echo(text, err=True)

    @contextlib.contextmanager
    def progress(self, label: str, total: int | None = None) -> Iterator[Progress]:
        """A rich progress display on a terminal (a spinner without ``total``); yields a :class:`Progress`:
        ``advance(n)``, and ``advance.stage(text)`` to say what is being done."""
        if self.quiet or not sys.stderr.isatty():
            yield Progress()
            return
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, SpinnerColumn, TextColumn, TimeElapsedColumn
        from rich.progress import Progress as Bar

        columns = [SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn()]
        if total is not None:
            columns[2:2] = [BarColumn(), MofNCompleteColumn()]
        with Bar(*columns, console=Console(stderr=True), transient=True) as bar:
            task = bar.add_task(label, total=total)
            yield _Progress(lambda n=1: bar.advance(task, n),
                            lambda text: bar.update(task, description=f"{label}: {text}"))


class Progress:
    """What a command reports while it works: ``progress(n)`` units done, ``progress.stage(text)`` the stage
    (nothing shown off a terminal or with ``-q``)."""

    def __call__(self, n: int = 1) -> None:
        pass

    def stage(self, text: str) -> None:
        pass


class _Progress(Progress):
    def __init__(self, advance: Callable[[int], None], stage: Callable[[str], None]) -> None:
        self._advance, self._stage = advance, stage

    def __call__(self, n: int = 1) -> None:
        self._advance(n)

    def stage(self, text: str) -> None:
        self._stage(text)


def each_input(items: list[Any], work: Callable[[Any], dict[str, Any]], many: bool) -> tuple[list[dict[str, Any]], int]:
    """Run ``work`` on every input: with one input its error propagates (exit 1); with several each failure
    is one line on stderr and the others go on. Returns the results and the number of failures."""
    results, failed = [], 0
    for item in items:
        try:
            results.append(work(item))
        except MocapzError as exc:
            if not many:
                raise
            failed += 1
            click.echo(f"mocapz: error: {exc}", err=True)
    return results, failed


def finish(results: list[dict[str, Any]], many: bool, as_json: bool, failed: int) -> None:
    """Print the ``--json`` object (one input's figures, or ``{"files": [...]}``), exit 1 if any input failed."""
    if as_json and results:
        echo_json(results[0] if not many else {"files": results})
    if failed:
        sys.exit(1)


def message_flags(f: Any) -> Any:
    """``-q/--quiet`` and ``-v/--verbose`` on a command."""
    f = click.option("-v", "--verbose", is_flag=True, help="more detail on stderr")(f)
    return click.option("-q", "--quiet", is_flag=True, help="no messages or progress (errors still show)")(f)


def range_flags(f: Any) -> Any:
    """``--frames A:B`` and ``--start/--end`` (seconds) on a command."""
    f = click.option("--end", type=float, default=None, metavar="SECONDS", help="stop at this time")(f)
    f = click.option("--start", type=float, default=None, metavar="SECONDS", help="start at this time")(f)
    return click.option("--frames", default=None, metavar="A:B",
                        help="frames A to B-1 only (Python slice: 100:, :200, -50:)")(f)


def unit_flag(f: Any) -> Any:
    return click.option("--unit", type=click.Choice(list(UNITS), case_sensitive=False), default=None,
                        help="the file's length unit, where it is unknown or guessed wrongly")(f)


def echo_json(obj: Any) -> None:
    click.echo(json.dumps(obj, default=_json_default))


def _json_default(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o).__name__)


def fmt(v: Any, unit: str = "") -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float):
        return f"{v:.4g}{unit}"
    return f"{v}{unit}"


def frame_slice(frames: str | None, start: float | None, end: float | None, rate: float, n: int) -> slice | None:
    """The frames ``--frames`` / ``--start`` / ``--end`` select, or None for all (OptionError if bad)."""
    if frames is None and start is None and end is None:
        return None
    if frames is not None and (start is not None or end is not None):
        raise OptionError("give --frames or --start/--end, not both")
    if frames is not None:
        a, sep, b = frames.partition(":")
        try:
            lo = int(a) if a.strip() else None
            hi = int(b) if b.strip() else None
        except ValueError:
            lo = hi = None
            sep = ""
        if not sep:
            raise OptionError(f"--frames: expected A:B (e.g. 100:400, 100:, :-20), got {frames!r}")
        s = slice(lo, hi)
    else:
        s = slice(None if start is None else round(start * rate), None if end is None else round(end * rate))
    first, last, _ = s.indices(n)
    if last <= first:
        raise OptionError(f"the frame range selects no frame of this clip ({n} frames)")
    return slice(first, last)


def cut(motion: AnyMotion, s: slice | None) -> AnyMotion:
    """Frames ``s`` of a motion (all when None)."""
    return motion if s is None else motion.slice(s.start, s.stop)


def with_unit(motion: AnyMotion, unit: str | None) -> AnyMotion:
    """The motion with its length unit said by the user (``--unit``)."""
    if unit is None:
        return motion
    cm = UNITS[unit.lower()]
    if isinstance(motion, Motion):
        sk = motion.skeleton.copy()
        sk.unit_cm, sk.unit_note = cm, f"given with --unit {unit}"
        return replace(motion, skeleton=sk)
    assert isinstance(motion, MarkerMotion)
    name = next((k for k, v in UNIT_CM.items() if abs(v - cm) < 1e-12), None)
    if name is None:
        raise OptionError(f"--unit {unit}: marker files take mm, cm, m or in")
    return replace(motion, units=name)
