"""Order-0 entropy bounds for lossless coding of the CMU BVH clips' second differences.

Prints the ratio (raw float32 bytes / ideal coded bytes) an ideal order-0 coder would reach on the
second temporal differences of the integer channel values, with its histogram
(a) per clip and per channel, histograms not counted (an overfit bound: few samples, many values),
(b) per channel pooled over the whole corpus (a model the decoder gets for free),
(c) one histogram pooled over everything.
Compare with `scripts/lossless.py` (the real codec, every byte counted).

Usage: python scripts/lossless_bound.py [DATA_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import mocapz


def entropy_bytes(values: np.ndarray) -> float:
    """Ideal order-0 code length in bytes of a 1-D integer array under its own histogram."""
    _, counts = np.unique(values, return_counts=True)
    p = counts / counts.sum()
    return float(-(counts * np.log2(p)).sum() / 8)


def main() -> None:
    data = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared" / "data"
    raw, residuals = 0, []
    for f in sorted((data / "cmu" / "bvh").glob("*.bvh")):
        m = mocapz.load(f)
        x = np.round(m.channels * 10.0**m.decimals).astype(np.int64)
        residuals.append(np.diff(x, 2, axis=0))
        raw += m.raw_bytes
    per_clip = sum(entropy_bytes(r[:, c]) for r in residuals for c in range(r.shape[1]))
    pooled = np.concatenate(residuals)
    per_channel = sum(entropy_bytes(pooled[:, c]) for c in range(pooled.shape[1]))
    print(f"(a) per clip and channel, histograms free: {raw / per_clip:.3f}")
    print(f"(b) per channel pooled over the corpus:    {raw / per_channel:.3f}")
    print(f"(c) one pooled histogram:                  {raw / entropy_bytes(pooled.ravel()):.3f}")


if __name__ == "__main__":
    main()
