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
