"""Lossless codec ratio per clip over the CMU BVH clips of ../shared/data (METRICS.md figures).

Usage: python scripts/lossless.py [DATA_DIR]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import mocapz


def main() -> None:
    data = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared" / "data"
    files = sorted((data / "cmu" / "bvh").glob("*.bvh"))
    total_raw = total_comp = total_file = 0
    print(f"{'clip':<10} {'frames':>7} {'raw_bytes':>10} {'compressed':>10} {'ratio':>6} {'ratio_file':>10} "
          f"{'enc ms/f':>8} {'dec ms/f':>8}")
    for f in files:
        m = mocapz.load(f)
        t0 = time.perf_counter()
        data_bytes = mocapz.compress(m, codec="lossless")
        t1 = time.perf_counter()
        back = mocapz.decompress(data_bytes)
        t2 = time.perf_counter()
        assert np.array_equal(back.channels, m.channels), f
        total_raw += m.raw_bytes
        total_comp += len(data_bytes)
        total_file += f.stat().st_size
        print(f"{f.stem:<10} {m.n_frames:>7} {m.raw_bytes:>10} {len(data_bytes):>10} "
              f"{m.raw_bytes / len(data_bytes):>6.3f} {f.stat().st_size / len(data_bytes):>10.3f} "
              f"{1000 * (t1 - t0) / m.n_frames:>8.4f} {1000 * (t2 - t1) / m.n_frames:>8.4f}")
    print(f"{'TOTAL':<10} {'':>7} {total_raw:>10} {total_comp:>10} {total_raw / total_comp:>6.3f} "
          f"{total_file / total_comp:>10.3f}")


if __name__ == "__main__":
    main()
