"""Gaussian smoothing of the pattern codec (the heading's yaw, the dequantised patterns): what
``scipy.ndimage.gaussian_filter1d(a, sigma, axis, mode="nearest")`` computes, in its arithmetic, without importing
``scipy.ndimage`` (0.2 s a process alone, 0.03 s beside ``scipy.spatial``).

scipy's filter is the reference (tests/test_patterns_lloyd.py: the same bits on random arrays and the shared
clips' data): the kernel ``exp(-x**2 / (2 sigma**2))`` normalised by its sum, over ``int(4 sigma + 0.5)`` frames on
either side, the signal extended by its end values, and each output ``a[t] w[0] + sum_(j=r..1) (a[t-j] + a[t+j])
w[j]`` summed from the farthest pair in (ndimage's symmetric-kernel loop, ``NI_Correlate1D``).
"""

from __future__ import annotations

import numpy as np

TRUNCATE = 4.0  # scipy's default: the kernel reaches this many standard deviations


def gaussian_smooth(a: np.ndarray, sigma: float, axis: int = -1) -> np.ndarray:
    """``a`` (float64, any shape) smoothed along ``axis`` by a Gaussian of ``sigma`` samples, ends held
    (``mode="nearest"``); the same values as scipy's ``gaussian_filter1d``."""
    radius = int(TRUNCATE * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1)
    w = np.exp(-0.5 / (sigma * sigma) * x**2)
    w = (w / w.sum())[::-1]  # reversed, as scipy correlates (symmetric: ndimage's symmetric-kernel loop)
    moved = np.moveaxis(np.asarray(a, dtype=np.float64), axis, -1)
    n = moved.shape[-1]
    if n == 0:
        return np.array(a, dtype=np.float64)
    padded = np.pad(moved, [(0, 0)] * (moved.ndim - 1) + [(radius, radius)], mode="edge")
    out = padded[..., radius:radius + n] * w[radius]
    for j in range(radius, 0, -1):
        out += (padded[..., radius - j:radius - j + n] + padded[..., radius + j:radius + j + n]) * w[radius - j]
    return np.moveaxis(out, -1, axis)
