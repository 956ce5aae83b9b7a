"""A short clip's PGA encode and decode take the NumPy IK whether or not numba is loaded (ikjit.LAZY_FRAMES):
no numba import on a one-shot short clip, and bytes and decoded values that depend on the clip alone (the
compiled IK agrees with the NumPy path to rounding only, not to the bit)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import data_path

from mocapz.codecs.correction import compiled
from mocapz.codecs.pga import ikjit

SRC = Path(__file__).resolve().parents[1] / "src"

SCRIPT = """
import hashlib, json, sys
import mocapz
if sys.argv[2] == "preload":
    from mocapz.codecs.pga import ikjit
    assert ikjit.kernels() is not None  # numba imported and the IK kernels loaded before the clip
m = mocapz.load(sys.argv[1])
data = mocapz.compress(m, codec="pga")
back = mocapz.decompress(data)
print(json.dumps({"bytes": hashlib.sha256(data).hexdigest(),
                  "values": hashlib.sha256(back.channels.tobytes()).hexdigest(),
                  "numba": "numba" in sys.modules}))
"""


def _run(path: Path, mode: str, **env: str) -> dict:
    e = {k: v for k, v in os.environ.items() if k not in ("MOCAPZ_NO_NUMBA", "MOCAPZ_NO_AOT")}
    e |= {"PYTHONPATH": str(SRC), **env}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(path), mode], env=e, capture_output=True, text=True,
                         timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_short_clip_same_output_whether_numba_is_loaded_or_not() -> None:
    path = data_path("cmu/bvh/09_06.bvh")  # 142 frames
    plain = _run(path, "fresh")
    assert not plain["numba"], "a short clip's pga encode and decode imported numba"
    off = _run(path, "fresh", MOCAPZ_NO_NUMBA="1")
    assert (plain["bytes"], plain["values"]) == (off["bytes"], off["values"])
    pytest.importorskip("numba")
    loaded = _run(path, "preload", MOCAPZ_NO_AOT="1")  # numba's just-in-time kernels loaded first
    assert loaded["numba"]
    assert (loaded["bytes"], loaded["values"]) == (plain["bytes"], plain["values"])
    ahead = _run(path, "preload", MOCAPZ_NO_AOT="0")  # the kernels compiled ahead of time, where built
    assert (ahead["bytes"], ahead["values"]) == (plain["bytes"], plain["values"])


def test_the_path_is_a_function_of_the_length_only() -> None:
    pytest.importorskip("numba")
    assert ikjit.kernels() is not None  # numba loaded
    assert ikjit.kernels(ikjit.LAZY_FRAMES - 1) is None
    assert ikjit.kernels(ikjit.LAZY_FRAMES) is not None
    assert ikjit.LAZY_FRAMES <= compiled.LAZY_FRAMES <= compiled.LAZY_DECODE_FRAMES  # under all: no numba at all


def test_a_streams_blocks_take_the_compiled_ik_whatever_their_length(monkeypatch: pytest.MonkeyPatch) -> None:
    """A pga stream's blocks (about 1 s, under LAZY_FRAMES) take the compiled IK in the encoder and in every
    decoder, which all know the block is a stream's (ikjit.any_length): the same values from the stream
    decoder and from mocapz.decompress, within the target; the blocks' IK does run compiled."""
    pytest.importorskip("numba")
    import numpy as np

    import mocapz
    from mocapz.codecs.pga import iksolve

    assert ikjit.kernels(ikjit.LAZY_FRAMES - 1) is None
    with ikjit.any_length():
        assert ikjit.kernels(ikjit.LAZY_FRAMES - 1) is not None
    assert ikjit.kernels(ikjit.LAZY_FRAMES - 1) is None  # only inside
    m = mocapz.load(data_path("cmu/bvh/02_05.bvh")).slice(0, 400)
    # geodesics given: every block on the model (with none given they take the correction alone, smaller here)
    enc = mocapz.StreamEncoder(m, codec="pga", max_error="1cm", geodesics=16)
    data = enc.write(m.values) + enc.close()
    paths = []
    real = iksolve.solve_fast

    def spy(*args, **kwargs):  # which path each block's IK takes
        paths.append(ikjit.kernels(kwargs.get("frames")) is not None)
        return real(*args, **kwargs)

    monkeypatch.setattr("mocapz.codecs.pga.decode.solve_fast", spy)
    back = mocapz.decompress(data)
    assert paths and all(paths), paths
    blocks = mocapz.StreamDecoder().feed(data)
    assert np.array_equal(np.concatenate([b.values for b in blocks]), back.values)
    assert mocapz.evaluate(m, back).max_err_cm <= 1.0 + 1e-9
