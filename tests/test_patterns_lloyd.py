"""The pattern codec's own K-means (patterns.lloyd) and Gaussian smoothing (patterns.gaussian) against scipy's
kmeans2 and gaussian_filter1d, which they stand for: the same labels and the same bits, on random data and on the
segments and signals of real clips; and a skeletal clip's patterns command imports neither scipy.cluster nor
scipy.ndimage (0.05-0.14 s of a short clip's command), nor scipy.spatial for its decoder's rotations where the
kernels are compiled ahead of time (tests/test_patterns_rotations.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy.cluster.vq import kmeans2
from scipy.ndimage import gaussian_filter1d

import mocapz
from mocapz.codecs.patterns import heading, kmeans, quantise
from mocapz.codecs.patterns.gaussian import gaussian_smooth
from mocapz.codecs.patterns.lloyd import kmeans_pp

SRC = Path(__file__).resolve().parents[1] / "src"


def _scipy_labels(x: np.ndarray, k: int, seed: int) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, lab = kmeans2(x, k, iter=kmeans.ITERATIONS, minit="++", rng=np.random.default_rng(seed),
                         check_finite=False)
    return lab.astype(np.int64)


def test_kmeans_labels_are_scipys_on_random_data() -> None:
    rng = np.random.default_rng(5)
    for trial in range(60):
        n, d, k = int(rng.integers(2, 120)), int(rng.choice([1, 2, 4, 5, 9, 60, 400])), int(rng.integers(2, 9))
        x = rng.normal(size=(n, d)) * 10 ** rng.uniform(-2, 3)
        if trial % 5 == 0:
            x[: n // 2] = x[0]  # repeated rows: empty clusters, ties
        if trial % 7 == 0:
            x = np.round(x)  # a coarse grid: exact ties
        assert np.array_equal(kmeans_pp(x, k, kmeans.ITERATIONS, np.random.default_rng(trial)),
                              _scipy_labels(x, k, trial)), (n, d, k, trial)


@pytest.mark.parametrize("rel", ["cmu/bvh/06_13.bvh", "cmu/c3d/01_01.c3d"])
def test_kmeans_labels_are_scipys_on_a_clips_segments(rel: str, monkeypatch: pytest.MonkeyPatch) -> None:
    seen = []
    mine = kmeans._initial

    def both(x: np.ndarray, k: int, seed: int) -> np.ndarray:
        if k > 1:
            seen.append(np.array_equal(kmeans_pp(x, k, kmeans.ITERATIONS, np.random.default_rng(seed)),
                                       _scipy_labels(x, k, seed)))
        return mine(x, k, seed)

    monkeypatch.setattr(kmeans, "_initial", both)
    motion = mocapz.load(data_path(rel))
    mocapz.compress(motion.slice(0, min(motion.n_frames, 1500)), codec="patterns")
    assert seen and all(seen)


def test_gaussian_smoothing_is_scipys_to_the_bit() -> None:
    rng = np.random.default_rng(2)
    for _ in range(120):
        shape = tuple(int(s) for s in rng.integers(1, 30, size=int(rng.integers(1, 4))))
        a = np.cumsum(rng.normal(size=shape), axis=-1) * 10 ** rng.uniform(-3, 3)
        sigma = float(rng.choice([0.2, 0.5, 1.0, 2.5, 4.0, rng.uniform(0.01, 9.0)]))
        axis = int(rng.integers(0, len(shape)))
        assert np.array_equal(gaussian_smooth(a, sigma, axis), gaussian_filter1d(a, sigma, axis=axis, mode="nearest"))
    pos = mocapz.load(data_path("cmu/c3d/01_01.c3d")).positions[:600]
    filled = np.nan_to_num(pos)
    observed = np.isfinite(pos).all(axis=2)
    raw = heading.measure_yaw(filled, observed, 0, heading.up_axis(filled), sigma=0.0)
    assert np.array_equal(gaussian_smooth(raw, 4.0), gaussian_filter1d(raw, 4.0, mode="nearest"))
    sym, back = quantise.quantise_patterns(np.cumsum(rng.normal(size=(6, 40, 9)), axis=1), 0.05, sigma=1.5)
    assert back.shape == (6, 40, 9) and np.isfinite(back).all()


SCRIPT = """
import json, sys
import mocapz
m = mocapz.load(sys.argv[1])
data = mocapz.compress(m, codec="patterns")
mocapz.decompress(data)
from mocapz import aot
print(json.dumps({"cluster": "scipy.cluster" in sys.modules, "ndimage": "scipy.ndimage" in sys.modules,
                  "scipy": any(k.startswith("scipy") for k in sys.modules), "aot": aot.in_use() == "ahead of time"}))
"""


def test_a_skeletal_patterns_command_imports_no_scipy_module() -> None:
    env = dict(os.environ) | {"PYTHONPATH": str(SRC)}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(data_path("cmu/bvh/09_06.bvh"))], env=env,
                         capture_output=True, text=True, timeout=300, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert not got["cluster"] and not got["ndimage"]
    assert got["scipy"] is not got["aot"]  # scipy.spatial for the rotations exactly where the extension is not used
