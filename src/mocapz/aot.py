"""The compiled kernels ahead of time: one extension module (:data:`EXTENSION`) that holds every numba kernel Python
calls, compiled by :mod:`mocapz.aot_build` (``make`` builds it), so that a process uses them without importing
numba or loading its cache (about 0.5 s and 100 MB a process: most of a short clip's command).

The kernels are numba's: the same source (the ``*kernels.py`` modules) compiled by numba's ahead-of-time compiler
for the argument types of :data:`SIGNATURES` and this machine's processor, each a function of the extension named
``{alias}__{name}__{i}``. :func:`kernels` gives an alias's functions by name; each call takes the first compiled
variant its arguments fit exactly (the types numba's just-in-time dispatcher would give them: dtype, dimensions, a
C- or F-contiguous array where the variant wants one, a writeable one where it may write) and otherwise calls the
just-in-time kernel (numba loaded then): the same code either way, the same bits.

The extension is used only where it was built from the kernels' present source (:func:`stamp`, a hash of their
files, of :data:`SIGNATURES` and of the processor's features, compiled into it), and not with ``MOCAPZ_NO_AOT=1``
in the environment (the just-in-time kernels then; tests compare the two). Whether any compiled kernel is used at
all stays with :mod:`mocapz._jit`'s switch (``MOCAPZ_NO_NUMBA``) and each caller's own rule.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import platform
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

EXTENSION = "mocapz._kernels_aot"
#: the kernel modules by alias (their functions' prefix in the extension)
MODULES = {
    "range": "mocapz.format.rangekernels",
    "lossless": "mocapz.codecs.lossless._kernels",
    "ik": "mocapz.codecs.pga.ikkernels",
    "so3": "mocapz.codecs.pga.so3kernels",
    "lift": "mocapz.codecs.correction.liftkernels",
    "round": "mocapz.codecs.correction.roundkernels",
    "chain": "mocapz.codecs.correction.chainkernels",
    "rot": "mocapz.codecs.patterns.rotkernels",
    "fk": "mocapz.model.fkkernels",
    "err": "mocapz.metrics.errkernels",
}
#: modules whose constants the kernels compile in (their source is part of the stamp too)
CONSTANTS = ("mocapz.codecs.pga.ik", "mocapz.codecs.lossless.status")


def _args(sig: str) -> list[str]:
    """The argument types of a signature string, as written (commas inside brackets and ``Array(...)`` kept)."""
    inner = sig[sig.index("(") + 1:sig.rindex(")")]
    out, depth, cur = [], 0, ""
    for ch in inner + ",":
        if ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
            continue
        depth += 1 if ch in "([" else -1 if ch in ")]" else 0
        cur += ch
    return out


def _column_major(sig: str, which: tuple[int, ...]) -> str:
    """``sig`` with its 2-D C-contiguous arguments ``which`` Fortran-contiguous (``T[::1, :]``) instead."""
    args = [a.replace("[:, ::1]", "[::1, :]") if k in which else a for k, a in enumerate(_args(sig))]
    return f"{sig[:sig.index('(') + 1]}{', '.join(args)})"


#: the correction's whole round (:mod:`mocapz.codecs.correction.roundkernels`); its residual, tolerance levels,
#: decoded residual and integers (arguments 0, 4, 13, 14) come column-major from the fit (a joint's columns
#: contiguous), or row-major from other callers: a variant for each
_ROUND = (
    "none(f8[:, ::1], Array(f8, 2, 'A', readonly=True), f8[::1], i8[::1], i8[:, ::1], i8, f8[::1], i8, i8, "
    "f8[::1], f8, i8, f8[:, ::1], f8[:, ::1], i8[:, ::1], f8[:, :, ::1], f8[:, :, :, ::1], f8[:, :, :, ::1], "
    "b1[:, ::1], b1[:, ::1], b1, b1, b1[::1], i8[::1], i8[::1], i8[::1], i8[::1], i8[::1], b1[::1], i8[:, ::1], "
    "b1[::1], i8[:, ::1], i8[:, ::1], i8[:, ::1], f8[:, :, ::1], b1[::1], i8[::1], i8[:, ::1], f8[::1], i8[::1], "
    "f8[:, :, :, ::1], f8[:, :, ::1], f8[:, ::1], i8[:, ::1], f8[:, ::1], i8[::1], i8[::1], f8, f8, f8, "
    "i8[::1], i8[::1], i8[:, ::1], f8[:, ::1], f8)")
ROUND_COLUMN_MAJOR = (0, 4, 13, 14)


#: (alias, kernel, numba signature): the argument types the callers give (numba's ``typeof`` of them), as the
#: just-in-time dispatcher compiles them; ``Array(..., readonly=True)`` is a read-only (or any) array
SIGNATURES: tuple[tuple[str, str, str], ...] = (
    ("range", "begin", "u8[::1](u4[::1])"),
    ("range", "decode_laplace", "i8(u4[::1], u8[::1], f8[:, ::1], i8, i8, i8, i8[:, ::1])"),
    ("range", "encode_laplace", "i8(i8[:, ::1], f8[:, ::1], i8, i8, i8, u8[::1], u4[::1])"),
    ("range", "seal", "i8(u8[::1], u4[::1])"),
    ("range", "histogram_codes", "none(i8[:, ::1], i8, f8[:, :, ::1], f8[:, ::1], b1[::1], i8[:, ::1])"),
    ("range", "block_codes", "none(i8[:, ::1], f8[:, ::1], f8[:, ::1], i8[::1], i8[::1], f8[:, ::1], i8[::1])"),
    ("lossless", "decode_residual_rows", "i8(u4[::1], b1[:, ::1], i8[::1], i8[::1], u1[::1], i8[:, ::1])"),
    ("lossless", "row_models", "none(i8[:, ::1], b1[:, ::1], i8[::1], i8[:, ::1], f8[:, ::1])"),
    ("lossless", "undo_prediction",
     "none(i8[:, ::1], i8[::1], i8[::1], i8[:, ::1], i8[:, ::1], i8[::1], i8[::1], i8[:, ::1])"),
    ("lossless", "pack_low", "u1[::1](u8[::1], i8[::1])"),
    ("ik", "solve_frames",
     "none(f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, :, ::1], b1, f8[:, ::1], f8[:, ::1], f8[:, :, ::1], i8[::1], "
     "i8[::1], i8[::1], f8[:, :, ::1], i8[::1], f8[:, ::1], i8[::1], b1[:, ::1], f8, f8, b1, i8)"),
    ("ik", "pose", "none(f8[:, ::1], f8[:, ::1], f8[:, :, ::1], f8[:, :, :, ::1])"),
    ("ik", "euler_channels",
     "i8(f8[:, ::1], f8[:, ::1], f8[:, :, ::1], f8[:, :, ::1], i8[::1], i8[:, ::1], f8[::1], i8[:, ::1], "
     "f8[:, :, ::1], b1[::1], f8, f8[:, ::1])"),
    ("so3", "products_t",
     "none(f8[:, :, ::1], Array(f8, 4, 'A', readonly=True), i8[::1], i8, i8, f8[:, :, :, ::1])"),
    ("lift", "details", "none(f8[:, ::1], f8[:, ::1], f8[:, ::1], i8[:, ::1], i8, f8[::1], f8, i8, f8[:, ::1])"),
    ("lift", "decode_details",
     "none(i8[:, ::1], f8[::1], f8[::1], i8[:, ::1], i8[::1], f8[:, ::1], i8, f8[::1], f8, i8, i8, f8, f8[:, ::1])"),
    ("lift", "rn_levels", "none(i8[:, ::1], f8[:, ::1], i8, i8, f8, i8[:, ::1], f8[:, ::1], i8[::1])"),
    ("round", "run", _ROUND),
    ("round", "run", _column_major(_ROUND, ROUND_COLUMN_MAJOR)),
    ("chain", "place", "none(f8[:, :, ::1], f8[:, :, :], i8, i8, f8[:, ::1])"),
    ("chain", "goal_angles",
     "none(f8[:, :, ::1], f8[:, :, :], i8, i8, f8[:, :, ::1], f8[:, :, ::1], i8, f8, f8[:, ::1], b1, i8[::1], f8, "
     "f8, f8[:, ::1], i8[::1], f8, f8[:, ::1], i8[::1])"),
    ("chain", "compose",
     "none(f8[:, :, ::1], f8[:, :, ::1], i8, f8[:, ::1], f8, i8[::1], f8[:, ::1], b1, i8[::1])"),
    ("chain", "hinge_residual",
     "none(f8[:, :, ::1], f8[:, :, :], i8, i8, f8[:, :, ::1], f8[:, ::1], f8[::1], i8[::1], f8, f8[:, ::1], i8[::1], "
     "f8[:, :], f8, f8, f8[:, :], i8[::1])"),
    ("rot", "rotvec_euler", "i8(f8[:, ::1], i8[::1], b1, f8[:, ::1])"),
    ("fk", "forward",
     "none(f8[:, ::1], f8, i8[::1], i8[:, ::1], i8[:, ::1], i8[::1], b1[::1], f8[:, :, ::1], i8[:, ::1], f8[:, ::1], "
     "i8[::1], f8[:, ::1], f8[:, :, ::1], f8[:, :, :, ::1], b1)"),
    ("fk", "local", "none(f8[:, ::1], f8, i8[:, ::1], i8[:, ::1], i8[::1], b1[::1], f8[:, :, ::1], f8[:, :, :, ::1])"),
    ("err", "point_errors",
     "none(Array(f8, 3, 'A', readonly=True), Array(f8, 3, 'A', readonly=True), f8[:, ::1])"),
    ("err", "farthest", "none(Array(f8, 3, 'A', readonly=True), i8[::1], i8[::1], f8[::1])"),
)
_DTYPES = {"f8": np.dtype(np.float64), "i8": np.dtype(np.int64), "u8": np.dtype(np.uint64),
           "u4": np.dtype(np.uint32), "u1": np.dtype(np.uint8), "b1": np.dtype(np.bool_)}
_STATE: dict[str, Any] = {}


def stamp() -> int:
    """A 60-bit hash of the kernels' source files, the modules whose constants they use, :data:`SIGNATURES` and
    the processor's features (:func:`processor`; the extension is compiled for the processor it is built on):
    what the extension was built from and for (compiled into it) against what this package holds and runs on."""
    h = hashlib.sha256(repr(SIGNATURES).encode() + processor())
    for name in (*MODULES.values(), *CONSTANTS):
        h.update(_source(name).read_bytes())
    return int.from_bytes(h.digest()[:8], "little") >> 4


def processor() -> bytes:
    """The processor's feature flags (Linux: the first ``flags`` line of /proc/cpuinfo), else its architecture."""
    try:
        with open("/proc/cpuinfo", "rb") as f:
            for line in f:
                if line.startswith(b"flags"):
                    return line.strip()
    except OSError:
        pass
    return platform.machine().encode()


def _source(module: str) -> Path:
    return Path(__file__).resolve().parent.joinpath(*module.split(".")[1:]).with_suffix(".py")


def extension() -> ModuleType | None:
    """The built extension when it matches the kernels' source (:func:`stamp`) and is not turned off
    (``MOCAPZ_NO_AOT``), else None."""
    if "ext" not in _STATE:
        _STATE["ext"] = None
        if os.environ.get("MOCAPZ_NO_AOT", "") in ("", "0"):
            try:
                ext = importlib.import_module(EXTENSION)
                if ext.stamp() == stamp():
                    _STATE["ext"] = ext
            except (ImportError, AttributeError, OSError):
                pass
    return _STATE["ext"]


def in_use() -> str:
    """Which compiled kernels this process uses where it uses any: ``"ahead of time"`` (the extension),
    ``"numba"`` (just in time: the extension missing, stale or turned off) or ``"none"`` (no numba, or turned off by
    ``MOCAPZ_NO_NUMBA``: NumPy)."""
    from mocapz import _jit

    if not _jit.enabled():
        return "none"
    if extension() is not None:
        return "ahead of time"
    return "numba" if importlib.util.find_spec("numba") is not None else "none"


class Kernels:
    """An alias's compiled kernels by name (``k.decode_laplace(...)``), as the kernel module gives them; any
    other name is the kernel module's (numba imported then)."""

    def __init__(self, alias: str, ext: ModuleType) -> None:
        self._alias = alias
        variants: dict[str, list[tuple[list[tuple[str, Any]], Callable[..., Any]]]] = {}
        for i_alias, name, sig in SIGNATURES:
            if i_alias == alias:
                mine = variants.setdefault(name, [])
                mine.append((_arg_specs(sig), getattr(ext, f"{alias}__{name}__{len(mine)}")))
        for name, options in variants.items():
            setattr(self, name, _dispatcher(alias, name, options))

    def __getattr__(self, name: str) -> Any:  # a name without a compiled variant: the just-in-time module's
        return getattr(importlib.import_module(MODULES[self._alias]), name)


def kernels(alias: str) -> Kernels | None:
    """The compiled kernels of ``alias`` (a key of :data:`MODULES`) from the extension, or None without it."""
    ext = extension()
    if ext is None:
        return None
    key = f"k:{alias}"
    if key not in _STATE:
        _STATE[key] = Kernels(alias, ext)
    return _STATE[key]


def _dispatcher(alias: str, name: str, options: list[tuple[list[tuple[str, Any]], Callable[..., Any]]]
                ) -> Callable[..., Any]:
    def call(*args: Any) -> Any:
        for specs, fn in options:
            if len(args) == len(specs) and all(_fits(a, s) for a, s in zip(args, specs, strict=True)):
                return fn(*args)
        return getattr(importlib.import_module(MODULES[alias]), name)(*args)  # another type: just in time

    call.__name__ = name
    return call


def _arg_specs(sig: str) -> list[tuple[str, Any]]:
    """The arguments of a signature string: ``("scalar", code)`` or ``("array", (dtype, ndim, layout, writes))``
    (layout: ``"C"`` or ``"F"`` where the variant wants a contiguous array, ``""`` for any)."""
    return [_spec(a) for a in _args(sig)]


def _spec(arg: str) -> tuple[str, Any]:
    if arg.startswith("Array("):
        parts = [p.strip() for p in arg[6:-1].split(",")]
        layout = parts[2].strip("'\"")
        return "array", (_DTYPES[parts[0]], int(parts[1]), layout if layout in "CF" else "", False)
    if "[" in arg:
        dims = [d.strip() for d in arg[arg.index("[") + 1:-1].split(",")]
        layout = "C" if dims[-1] == "::1" else "F" if dims[0] == "::1" else ""
        return "array", (_DTYPES[arg[:arg.index("[")]], len(dims), layout, True)
    return "scalar", arg


def _fits(value: Any, spec: tuple[str, Any]) -> bool:
    """Whether ``value`` has the type numba's dispatcher would give it in this argument (or one the compiled
    code takes the same way: any array where the variant takes any layout, read-only or not)."""
    kind, what = spec
    if kind == "array":
        dtype, ndim, contiguous, writes = what
        return (type(value) is np.ndarray and value.dtype == dtype and value.ndim == ndim
                and (not contiguous or (value.flags.c_contiguous if contiguous == "C" else value.flags.f_contiguous))
                and (not writes or value.flags.writeable))
    if what == "f8":
        return type(value) is float or type(value) is np.float64
    if what == "i8":
        return type(value) is int or type(value) is np.int64
    if what == "b1":
        return type(value) is bool or type(value) is np.bool_
    if what == "u8":
        return type(value) is np.uint64
    return False
