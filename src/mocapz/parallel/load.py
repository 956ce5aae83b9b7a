"""Reading many clips in parallel, for commands that need the motions themselves (e.g. ``compress-db``)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from mocapz.model.motion import AnyMotion
from mocapz.parallel.clip import clip_modules, failure_reason, load_motion
from mocapz.parallel.pool import Pool


def load_many(paths: Iterable[str | os.PathLike[str]], *, jobs: int | None = None, scheduler: str | None = None,
              pool: Pool | None = None) -> Iterator[tuple[Path, AnyMotion | None, str | None]]:
    """Read motion files in parallel; yield ``(path, motion, None)`` or ``(path, None, reason)`` in input order.

    For commands that need the clips themselves (e.g. ``compress-db``, whose shared pattern databases need
    every clip): parsing is spread over the workers and the motions come back to this process, in order,
    with at most ``2 x workers`` of them waiting at once beyond those already consumed.
    """
    items = [Path(p) for p in paths]
    own = pool is None
    run_on = Pool(jobs, scheduler, max_items=len(items), preload=clip_modules("lossless")) if own else pool
    with run_on if own else contextlib.nullcontext(run_on) as active:
        for o in active.imap(load_motion, [str(p.resolve()) for p in items], ordered=True):
            path = items[o.index]
            if o.error is not None:
                yield path, None, failure_reason(o.error, o.item)
            else:
                yield path, o.value, None
