"""Exceptions raised by mocapz.

Every error a user can provoke with bad input is a :class:`MocapzError`; it carries the file it is about
as data (:attr:`MocapzError.path`), set where the error is raised or added on the way out with
:meth:`MocapzError.at`. The command-line tool turns them into one line on stderr and an exit code
(1; 2 for an :class:`OptionError`); it never shows a traceback for them.
"""

from __future__ import annotations

from os import PathLike
from typing import Any


class MocapzError(Exception):
    """Base class of every error mocapz raises on bad input or bad options.

    Attributes:
        path: the file the error is about, or ``None``.
        message: what is wrong (without the path).
    """

    def __init__(self, message: str = "", *, path: str | PathLike[str] | None = None) -> None:
        self.message = message
        self.path = None if path is None else str(path)
        super().__init__(message)

    def at(self, path: str | PathLike[str] | None) -> MocapzError:
        """This error, said of ``path`` unless it already names a file; returns itself (``raise exc.at(p)``)."""
        if self.path is None and path is not None and not self.message.startswith(f"{path}:"):
            self.path = str(path)
        return self

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message

    def __reduce__(self) -> tuple[Any, ...]:
        # picklable across processes (parallel batch compression), path included
        return (_rebuild, (type(self), self.message, self.path))


def _rebuild(cls: type[MocapzError], message: str, path: str | None) -> MocapzError:
    exc = cls.__new__(cls)
    MocapzError.__init__(exc, message, path=path)
    return exc


class FormatError(MocapzError):
    """A file could not be read: wrong format, truncated, corrupted or inconsistent.

    The message names the file and, where known, the line or field that is wrong.
    """

    def __init__(self, path: str | PathLike[str] | None, problem: str, line: int | None = None) -> None:
        super().__init__(problem, path=path)
        self.problem = problem
        self.line = line

    def __str__(self) -> str:
        where = self.path or "<data>"
        if self.line is not None:
            where = f"{where}:{self.line}"
        return f"{where}: {self.problem}"

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.path, self.problem, self.line))


class OptionError(MocapzError):
    """An option or parameter is invalid (out of range, contradictory, unknown name...)."""


class TargetError(MocapzError):
    """A rate-control target (maximum distortion or error) cannot be met by the codec."""
