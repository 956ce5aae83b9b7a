"""Exceptions raised by mocapz.

Every error a user can provoke with bad input is a :class:`MocapzError`. The command-line tool turns
them into one line on stderr and exit code 1; it never shows a traceback for them.
"""

from __future__ import annotations

from os import PathLike


class MocapzError(Exception):
    """Base class of every error mocapz raises on bad input or bad options."""


class FormatError(MocapzError):
    """A file could not be read: wrong format, truncated, corrupted or inconsistent.

    The message names the file and, where known, the line or field that is wrong.
    """

    def __init__(self, path: str | PathLike[str] | None, problem: str, line: int | None = None) -> None:
        self.path = None if path is None else str(path)
        self.problem = problem
        self.line = line
        where = self.path or "<data>"
        if line is not None:
            where = f"{where}:{line}"
        super().__init__(f"{where}: {problem}")

    def __reduce__(self) -> tuple[type, tuple[str | None, str, int | None]]:
        # picklable across processes (parallel batch compression)
        return (type(self), (self.path, self.problem, self.line))


class OptionError(MocapzError):
    """An option or parameter is invalid (out of range, contradictory, unknown name...)."""


class TargetError(MocapzError):
    """A rate-control target (maximum distortion or error) cannot be met by the codec."""
