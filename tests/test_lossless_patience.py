"""The lossless encoder's predictor pursuit stops a column's own fit after :data:`~predict.PATIENCE` idle steps:
on real clips whose columns are fitted one by one (an ASF/AMC clip with values too large for exact shared sums, a
C3D with gaps) it takes far fewer least-squares steps than the full search, for a file within 0.1 % of the full
search's size, and the values still come back bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import mocapz
from mocapz.codecs.lossless import predict


def _coded(monkeypatch: pytest.MonkeyPatch, motion: mocapz.Motion | mocapz.MarkerMotion,
           patience: int) -> tuple[bytes, int]:
    """The lossless file of ``motion`` with the pursuit's patience set, and the least-squares steps it took."""
    calls = [0]
    real = predict._lstsq

    def counting(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return real(a, b)

    monkeypatch.setattr(predict, "PATIENCE", patience)
    monkeypatch.setattr(predict, "_lstsq", counting)
    data = mocapz.compress(motion, "lossless")
    monkeypatch.undo()
    return data, calls[0]


@pytest.mark.parametrize("rel", ["cmu/asfamc/11_01.amc", "other/markers/btkdata/c3d_samples/Dance.c3d"])
def test_patience_cuts_the_steps_not_the_bytes(monkeypatch: pytest.MonkeyPatch, rel: str) -> None:
    motion = mocapz.load(data_path(rel))
    full, full_steps = _coded(monkeypatch, motion, predict.MAX_PREDICTORS + 1)  # never idle long enough to stop
    data, steps = _coded(monkeypatch, motion, predict.PATIENCE)
    assert full_steps > 0
    assert steps <= 0.7 * full_steps
    assert len(data) <= 1.001 * len(full)
    back = mocapz.decompress(data)
    assert np.array_equal(back.values, motion.values, equal_nan=True)
