"""Make the golden ``.mcz`` files: small clips encoded by today's encoders, with a hash of their decoded values.

Run only for a deliberate format change (the codec's version is bumped and the old golden files stay):
``.venv/bin/python tests/golden/make.py [CODEC...]`` (only the named codecs' files are rewritten).
``tests/test_golden.py`` decodes every file listed in
``golden.json`` for ever, and re-encodes the sources to check the bytes have not moved.
"""

# ruff: noqa: I001  (mocapz before numpy: it pins the BLAS kernels, see mocapz._blas)
from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import replace
from pathlib import Path

import mocapz  # first: pins the BLAS kernels before NumPy is imported (mocapz._blas)
import numpy as np
from mocapz.model.motion import MarkerMotion, Motion

HERE = Path(__file__).resolve().parent
DATA = Path(os.environ.get("MOCAPZ_DATA", HERE.parents[1].parent / "shared" / "data"))

# (golden file, source file, first frame, stop frame, codec, options)
CASES: list[tuple[str, str, int, int, str, dict]] = [
    ("bvh_lossless", "cmu/bvh/09_06.bvh", 0, 40, "lossless", {}),
    ("amc_lossless", "cmu/asfamc/01_01.amc", 0, 30, "lossless", {}),
    ("c3d_lossless", "cmu/c3d/01_01.c3d", 0, 40, "lossless", {}),
    ("trc_lossless", "other/markers/btkdata/Gait.trc", 0, 30, "lossless", {}),
    ("bvh_lossless_blocks", "cmu/bvh/09_06.bvh", 0, 100, "lossless", {"block": 40}),  # container version 2
    ("bvh_pga", "cmu/bvh/09_06.bvh", 0, 120, "pga", {}),
    ("bvh_pga_fixed", "cmu/bvh/09_06.bvh", 0, 120, "pga", {"geodesics": 6, "lod_root": 1, "lod_effectors": 1}),
    ("bvh_pga_distortion", "cmu/bvh/09_06.bvh", 0, 120, "pga", {"max_distortion": 0.5}),
    ("bvh_pga_error", "cmu/bvh/09_06.bvh", 0, 120, "pga", {"max_error": "3cm"}),
    ("bvh_patterns", "cmu/bvh/09_06.bvh", 0, 120, "patterns", {}),
    ("c3d_patterns", "cmu/c3d/01_01.c3d", 0, 120, "patterns", {}),
    ("c3d_patterns_arms", "cmu/c3d/01_01.c3d", 0, 120, "patterns", {"max_arms": "8mm"}),
    ("bvh_subsample", "cmu/bvh/09_06.bvh", 0, 60, "subsample", {}),
    ("c3d_subsample", "cmu/c3d/01_01.c3d", 0, 60, "subsample", {}),
    ("bvh_pca", "cmu/bvh/09_06.bvh", 0, 120, "pca", {}),
    ("c3d_pca", "cmu/c3d/01_01.c3d", 0, 60, "pca", {}),
    ("bvh_segpca", "cmu/bvh/09_06.bvh", 0, 120, "segpca", {}),
    ("bvh_quant", "cmu/bvh/09_06.bvh", 0, 120, "quant", {}),
    ("c3d_quant", "cmu/c3d/01_01.c3d", 0, 60, "quant", {}),
    ("c3d_quant_blocks", "cmu/c3d/01_01.c3d", 0, 90, "quant", {"block": 30}),
    ("bvh_quant_seek", "cmu/bvh/06_13.bvh", 0, 1100, "quant", {}),  # c.head format 3: seekable streams
    ("c3d_quant_seek", "cmu/c3d/01_01.c3d", 0, 1100, "quant", {}),
    # streams (mocapz.StreamEncoder; "stream": frames per write): continued blocks, a short last one
    ("bvh_quant_stream", "other/bvh/bvh-python/test_mocapbank.bvh", 0, 100, "quant", {"stream": 41}),
    ("trc_quant_stream", "other/markers/btkdata/Gait.trc", 0, 130, "quant", {"stream": 41}),
]


def source(rel: str, start: int, stop: int) -> Motion | MarkerMotion:
    """Frames ``start:stop`` of a shared file."""
    m = mocapz.load(DATA / rel)
    if isinstance(m, Motion):
        return m.slice(start, stop)
    return replace(m, positions=m.positions[start:stop].copy())


def encode(motion: Motion | MarkerMotion, codec: str, options: dict) -> bytes:
    """``mocapz.compress``, or for a case with ``"stream"`` in its options a :class:`mocapz.StreamEncoder` written
    that many frames at a time."""
    options = dict(options)
    chunk = options.pop("stream", None)
    if chunk is None:
        return mocapz.compress(motion, codec=codec, **options)
    enc = mocapz.StreamEncoder(motion, codec, **options)
    out = b"".join(enc.write(motion.values[i:i + chunk]) for i in range(0, motion.n_frames, chunk))
    return out + enc.close()


def values_hash(m: Motion | MarkerMotion) -> str:
    """SHA-256 of the decoded values rounded to 1e-6 (file units / degrees); NaN gaps included."""
    v = m.channels if isinstance(m, Motion) else m.positions
    r = np.round(np.asarray(v, dtype=np.float64), 6) + 0.0  # +0.0: -0 and 0 hash alike
    return hashlib.sha256(np.ascontiguousarray(r).tobytes()).hexdigest()


def main(codecs: list[str]) -> int:
    """Write the golden files of the given codecs (all when none are given); other entries stay as they are."""
    old = {e["file"]: e for e in json.loads((HERE / "golden.json").read_text())} if codecs else {}
    entries = []
    for name, rel, a, b, codec, options in CASES:
        if codecs and codec not in codecs and f"{name}.mcz" in old:
            entries.append(old[f"{name}.mcz"])
            continue
        data = encode(source(rel, a, b), codec, options)
        (HERE / f"{name}.mcz").write_bytes(data)
        back = mocapz.decompress(data)
        entries.append({"file": f"{name}.mcz", "source": rel, "frames": [a, b], "codec": codec,
                        "options": options, "bytes": len(data),
                        "sha256": hashlib.sha256(data).hexdigest(), "values_sha256": values_hash(back)})
        print(f"{name}: {len(data)} B", file=sys.stderr)
    (HERE / "golden.json").write_text(json.dumps(entries, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
