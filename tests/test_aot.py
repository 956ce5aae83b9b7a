"""The kernels compiled ahead of time (mocapz.aot): built by make and current, used without importing numba by
every codec on a clip long enough for every kernel (06_13, 4,906 frames: the correction's, the PGA decoder's, the
range decoder's, the lossless codec's), with the bytes and decoded values of numba's just-in-time kernels; a call
whose arguments fit no compiled variant goes to the just-in-time kernel, with the same result."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

from mocapz import aot

pytest.importorskip("numba")

SRC = Path(__file__).resolve().parents[1] / "src"

SCRIPT = """
import hashlib, json, sys
import mocapz
m = mocapz.load(sys.argv[1])
out = {}
for codec in ("lossless", "quant", "pga", "patterns"):
    data = mocapz.compress(m, codec=codec)
    back = mocapz.decompress(data)
    part = mocapz.decompress(data, frames=slice(2500, 2520))
    out[codec] = [hashlib.sha256(data).hexdigest(), hashlib.sha256(back.channels.tobytes()).hexdigest(),
                  hashlib.sha256(part.channels.tobytes()).hexdigest()]
from mocapz import aot
print(json.dumps({"codecs": out, "numba": "numba" in sys.modules, "aot": aot.extension() is not None}))
"""


def _run(path: Path, no_aot: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("MOCAPZ_NO_NUMBA", "MOCAPZ_NO_AOT")}
    env |= {"PYTHONPATH": str(SRC), "MOCAPZ_NO_AOT": "1" if no_aot else "0"}
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(path)], env=env, capture_output=True, text=True,
                         timeout=600, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _built() -> None:
    if importlib.util.find_spec("numba.pycc") is None:
        pytest.skip("this numba has no ahead-of-time compiler: the just-in-time kernels are used")
    assert aot.extension() is not None, "the compiled kernels are missing or stale: run `make kernels`"


@pytest.mark.slow
def test_every_codec_runs_without_numba_and_gives_the_just_in_time_bytes() -> None:
    _built()
    ahead = _run(data_path("cmu/bvh/06_13.bvh"), no_aot=False)
    assert ahead["aot"] and not ahead["numba"]  # every kernel call fitted a compiled variant
    jit = _run(data_path("cmu/bvh/06_13.bvh"), no_aot=True)
    assert not jit["aot"] and jit["numba"]
    assert ahead["codecs"] == jit["codecs"]


def test_the_extension_is_the_source_it_was_built_from(monkeypatch: pytest.MonkeyPatch) -> None:
    _built()
    monkeypatch.setattr(aot, "_STATE", {})
    assert aot.in_use() == "ahead of time"
    monkeypatch.setattr(aot, "stamp", lambda: 12345)  # the kernels' source changed since the build
    monkeypatch.setattr(aot, "_STATE", {})
    assert aot.extension() is None and aot.kernels("range") is None and aot.in_use() == "numba"
    monkeypatch.setattr(aot, "_STATE", {})
    monkeypatch.undo()
    monkeypatch.setenv("MOCAPZ_NO_AOT", "1")
    monkeypatch.setattr(aot, "_STATE", {})
    assert aot.extension() is None


def test_arguments_fit_a_variant_as_numba_types_them() -> None:
    specs = aot._arg_specs("none(f8[:, :, ::1], f8[:, :, :], i8, f8, b1, Array(f8, 2, 'A', readonly=True))")
    a = np.zeros((2, 3, 4))
    ro = np.zeros((2, 2))
    ro.flags.writeable = False
    good = (a, a[:, ::2], 3, 0.5, True, ro)
    assert all(aot._fits(v, s) for v, s in zip(good, specs, strict=True))
    assert not aot._fits(a[:, ::2], specs[0])  # C-contiguous wanted
    assert not aot._fits(a.astype(np.float32), specs[1])  # another dtype
    assert not aot._fits(a[0], specs[1])  # another number of dimensions
    assert not aot._fits(ro, aot._spec("f8[:, ::1]"))  # the kernel may write: a read-only array does not fit
    assert not aot._fits(3.0, specs[2]) and not aot._fits(True, specs[2]) and not aot._fits(3, specs[3])
    assert not aot._fits(1, specs[4])
    c, f = np.zeros((5, 4)), np.zeros((5, 4), order="F")  # column-major variants (the correction's round)
    assert aot._fits(f, aot._spec("f8[::1, :]")) and not aot._fits(c, aot._spec("f8[::1, :]"))
    assert aot._fits(c, aot._spec("f8[:, ::1]")) and not aot._fits(f, aot._spec("f8[:, ::1]"))
    assert not aot._fits(f[::2], aot._spec("f8[::1, :]")) and aot._fits(f[::2], aot._spec("f8[:, :]"))


def test_a_call_no_variant_takes_goes_to_the_just_in_time_kernel() -> None:
    _built()
    from mocapz.codecs.correction import liftkernels
    from mocapz.codecs.pga.lifting import _table, coefficient_rows, encode_rn, n_levels

    k = aot.kernels("lift")
    assert k is not None
    x = np.cumsum(np.random.default_rng(0).normal(size=(100, 3)), axis=0)
    q, _ = encode_rn(x, 0.01, 0)
    assert q.shape[0] == coefficient_rows(100, 0)
    outs = []
    for fn, order in ((k.rn_levels, "C"), (liftkernels.rn_levels, "C"), (k.rn_levels, "F")):  # F: no variant
        recon = np.zeros((100, 3), order=order)
        recon[0] = q[0] * 0.01
        fn(q, recon, n_levels(100), 0, 0.01, *_table())
        outs.append(recon)
    assert np.abs(outs[0] - x).max() < 0.01
    assert np.array_equal(outs[0], outs[1]) and np.array_equal(outs[0], outs[2])
