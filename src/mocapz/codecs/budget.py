"""A byte budget for a model's encoding, so that a model that cannot win stops early.

The correction layer (:mod:`mocapz.codecs.correction.wrap`) encodes a codec's model only to compare the file on
it with the correction alone: once the model's own sections reach the bytes the correction alone codes the
whole clip in, the model cannot give the smaller file. It sets that cap with :func:`capped`; an encoder that
codes its sections in parts reports the bytes it has written with :func:`spend` after each part, which raises
:class:`OverBudget` at the cap (or where the parts left, each as large as the smallest so far, would reach it).
Outside :func:`capped` the budget is unlimited and :func:`spend` does nothing:
an encoder's output never depends on it (it only stops, or not).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

SECTION_OVERHEAD = 8  # bytes counted per section beside its payload (its name and length, as the bases compare)

_CAP: ContextVar[float] = ContextVar("mocapz_budget", default=math.inf)


class OverBudget(Exception):  # noqa: N818  (a signal, not an error: the caller catches it)
    """An encoding given up at the cap; ``spent``: the bytes its sections had reached (a lower bound of the
    whole encoding's)."""

    def __init__(self, spent: int) -> None:
        super().__init__(f"{spent} bytes reach the budget")
        self.spent = spent


def section_bytes(payloads: Iterable[bytes]) -> int:
    """The bytes sections count for: each payload and :data:`SECTION_OVERHEAD`."""
    return sum(len(p) + SECTION_OVERHEAD for p in payloads)


@contextmanager
def capped(cap: float) -> Iterator[None]:
    """Encoders inside report against ``cap`` bytes."""
    token = _CAP.set(cap)
    try:
        yield
    finally:
        _CAP.reset(token)


def spend(payloads: Iterable[bytes], left: int = 0, least: int = 0) -> None:
    """Raise :class:`OverBudget` if the sections written so far (``payloads``, a part of the encoding's) reach
    the cap, or would with the ``left`` parts still to code each taking ``least`` bytes (an encoder coding its
    sections in parts of like size passes the fewest bytes a part took so far: a model whose parts could not all
    fit stops after two or three of them, not after the one that reaches the cap)."""
    cap = _CAP.get()
    if math.isfinite(cap):
        spent = section_bytes(payloads)
        if spent + max(left, 0) * max(least, 0) >= cap:
            raise OverBudget(spent)
