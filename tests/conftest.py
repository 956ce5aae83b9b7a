"""Shared test fixtures: the real motion-capture data in ../shared/data (never copied into the repo)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import mocapz  # noqa: F401  (first: pins the BLAS kernels before NumPy is imported, see mocapz._blas)

DATA = Path(os.environ.get("MOCAPZ_DATA", Path(__file__).resolve().parents[1].parent / "shared" / "data"))


def data_path(rel: str) -> Path:
    p = DATA / rel
    if not p.exists():
        pytest.fail(f"shared data file missing: {p} (tests need ../shared/data beside the checkout)")
    return p


@pytest.fixture
def data() -> Path:
    return DATA


def first_block_sections(data: bytes) -> dict[str, bytes]:
    """The codec's sections of a ``.mcz`` in one block, or of its first block (blocked files name them
    ``"0:name"``, see mocapz.format.blocks)."""
    from mocapz.format.container import Container

    sections = Container.from_bytes(data).sections
    if "blk" not in sections:
        return sections
    return {k[2:]: v for k, v in sections.items() if k.startswith("0:")}


def correction_case(rel: str, frames: int | None, relax: float, seed: int, top: int):  # noqa: ANN201
    """A shared clip's closed-loop case: ``(Clip, base tolerances t0 (columns,), levels (frames, groups))``, the
    tolerances ``relax`` times the safe ones at the default target, levels drawn below ``top`` (some joints
    tightened on some frames, as the verification leaves them)."""
    import numpy as np

    from mocapz.codecs.correction import bounds
    from mocapz.codecs.correction.fit import Clip

    m = mocapz.load(data_path(rel))
    m = m if frames is None else m.slice(0, frames)
    clip = Clip(m, True)
    lay = clip.layout
    e = 1.0 / m.unit_cm if m.unit_cm else clip.body / 170.0
    t0 = bounds.tol_of(bounds.code_for(np.where(lay.moving, relax * lay.t_safe * e, bounds.TINY * lay.t_safe * e)))
    return clip, t0, np.random.default_rng(seed).integers(0, top, size=(m.n_frames, lay.n_groups))
