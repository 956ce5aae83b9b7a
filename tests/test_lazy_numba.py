"""One command on a clip of a few thousand frames loads no numba where the NumPy path is faster end to end
(``correction.compiled.LAZY_FRAMES`` / ``LAZY_DECODE_FRAMES``, ``entropy.LAZY_VALUES``, ``lossless.fast``): a
quant compress of 1,855 frames and the decompress of its file, a lossless round trip of 4,906 frames; the bytes
and the decoded values are those of a process that loaded every kernel first."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import data_path

pytest.importorskip("numba")

SRC = Path(__file__).resolve().parents[1] / "src"

SCRIPT = """
import hashlib, json, sys
import mocapz
codec, path, mode = sys.argv[1], sys.argv[2], sys.argv[3]
if mode == "preload":  # every kernel loaded first: a process that coded a long clip already
    import numba
    from mocapz.codecs.correction import compiled
    from mocapz.codecs.lossless import fast
    for name in ("chainkernels", "liftkernels", "roundkernels"):
        assert compiled.kernels(0, name) is not None
    assert fast.kernels(force=True) is not None
m = mocapz.load(path)
data = mocapz.compress(m, codec=codec)
coded = "numba" in sys.modules
back = mocapz.decompress(data)
print(json.dumps({"bytes": hashlib.sha256(data).hexdigest(), "coded_with_numba": coded,
                  "values": hashlib.sha256(back.channels.tobytes()).hexdigest(), "numba": "numba" in sys.modules}))
"""


def _run(codec: str, path: Path, mode: str) -> dict:  # numba's just-in-time kernels (test_aot: ahead of time)
    env = {k: v for k, v in os.environ.items() if k != "MOCAPZ_NO_NUMBA"} | {"PYTHONPATH": str(SRC),
                                                                            "MOCAPZ_NO_AOT": "1"}
    out = subprocess.run([sys.executable, "-c", SCRIPT, codec, str(path), mode], env=env, capture_output=True,
                         text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize(("codec", "rel"), [("quant", "cmu/bvh/02_05.bvh"), ("lossless", "cmu/bvh/06_13.bvh")])
def test_a_one_shot_command_loads_no_numba_and_gives_the_same_bytes(codec: str, rel: str) -> None:
    cold = _run(codec, data_path(rel), "cold")
    assert not cold["numba"]  # neither the encoder nor the decoder imported it
    warm = _run(codec, data_path(rel), "preload")
    assert warm["numba"] and warm["coded_with_numba"]
    assert (cold["bytes"], cold["values"]) == (warm["bytes"], warm["values"])


BATCH = """
import hashlib, json, sys
import mocapz
from mocapz.codecs.correction import compiled
compiled.LAZY_WORK = int(sys.argv[2])
m = mocapz.load(sys.argv[1])
out = []
for _ in range(3):  # a batch: the same short clip three times
    out.append([hashlib.sha256(mocapz.compress(m, codec="quant")).hexdigest(), "numba" in sys.modules])
print(json.dumps(out))
"""


def test_a_batch_of_short_clips_loads_the_kernels_once_it_has_coded_enough() -> None:
    """Under ``LAZY_FRAMES`` a clip takes the NumPy path until the process has coded ``LAZY_WORK`` frame-rounds
    (made small here: a batch of three 344-frame clips); the bytes stay the same. (numba's just-in-time kernels:
    those compiled ahead of time, where built, cost nothing to load and are used whatever the length.)"""
    env = {k: v for k, v in os.environ.items() if k != "MOCAPZ_NO_NUMBA"} | {"PYTHONPATH": str(SRC),
                                                                            "MOCAPZ_NO_AOT": "1"}
    path = str(data_path("cmu/bvh/02_01.bvh"))
    run = subprocess.run([sys.executable, "-c", BATCH, path, "1000"], env=env, capture_output=True, text=True,
                         timeout=300, check=True)
    clips = json.loads(run.stdout.strip().splitlines()[-1])
    assert [c[1] for c in clips] == [True, True, True]  # 1,000 frame-rounds: loaded during the first clip
    run = subprocess.run([sys.executable, "-c", BATCH, path, str(10 ** 9)], env=env, capture_output=True,
                         text=True, timeout=300, check=True)
    never = json.loads(run.stdout.strip().splitlines()[-1])
    assert [c[1] for c in never] == [False, False, False]
    assert {c[0] for c in clips} == {c[0] for c in never} and len({c[0] for c in clips}) == 1
