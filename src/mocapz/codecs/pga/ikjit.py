"""Compiled (numba) kernels of the PGA decoder, used when numba is installed (``pip install mocapz[fast]``).

The kernels (module :mod:`mocapz.codecs.pga.ikkernels`) do, a block of frames at a time (frames on the
innermost axis of a few small work arrays, the vectorised one), what the NumPy
code of :mod:`mocapz.codecs.pga.iksolve` does over frames: the same Levenberg-Marquardt iteration (cost,
damping schedule, acceptance rule), the same closed-form rotations and right Jacobians, the same Jacobian
(``(G_n J_r(w_n) B_n)`` columns crossed with ``p_e - o_n``), Gaussian elimination of the damped normal
equations. The results agree with the NumPy path to float rounding (tests/test_pga_speed_equal.py).

The kernels compiled ahead of time (:mod:`mocapz.aot`, built by ``make``) are used where built, without importing
numba; else numba is imported lazily and only here; ``MOCAPZ_NO_NUMBA=1`` in the environment (or
:func:`set_enabled`) selects the NumPy path, as on a machine without numba. A clip under :data:`LAZY_FRAMES` frames
takes the NumPy path too, whether or not numba is loaded already: loading it costs more than the NumPy path spends
there, and the path must be a function of the clip alone (the two agree to rounding, not to the bit, and the
encoder's rate control and correction layer decode with it, so the file's bytes could depend on it).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

import numpy as np

from mocapz import aot
from mocapz._jit import COMPILE_ROOM, enabled, room_to_compile, set_enabled

_KERNELS: dict[str, Any] | None = None
LAZY_FRAMES = 500  # clips of fewer frames: the NumPy path, always (the correction layer's threshold too,
# correction/compiled.py: a clip under it loads no numba at all)
_ANY_LENGTH: ContextVar[bool] = ContextVar("pga_any_length", default=False)


@contextmanager
def any_length() -> Iterator[None]:
    """The compiled kernels inside whatever the clip's length: a stream's block (about a second each, but a stream
    is long: loading numba pays, and every block then takes the same path in the encoder and in every decoder,
    which know alike that it is a stream's block), or a short clip's rate search screening its candidates
    (:func:`.ratecontrol.screens`: an estimate the decoder then checks)."""
    token = _ANY_LENGTH.set(True)
    try:
        yield
    finally:
        _ANY_LENGTH.reset(token)


def kernels(frames: int | None = None) -> dict[str, Any] | None:
    """The compiled kernels by name for a clip of ``frames`` frames, or None: without numba, when disabled, or
    when ``frames`` is under :data:`LAZY_FRAMES` (None: whatever the length; tests), but inside
    :func:`any_length` (a stream's block, a rate search's screening). Never a function of whether numba is loaded
    already (see the module's docstring)."""
    global _KERNELS
    if not enabled() or (frames is not None and frames < LAZY_FRAMES and not _ANY_LENGTH.get()):
        return None
    if _KERNELS is None and (ahead := aot.kernels("ik")) is not None:  # compiled ahead of time: nothing to load
        _KERNELS = {name: getattr(ahead, name) for name in ("solve_frames", "pose", "euler_channels")}
    if _KERNELS is None:
        try:
            import numba  # noqa: F401
        except ImportError:
            _KERNELS = {}
        else:
            if not room_to_compile():
                return None  # the NumPy path this time; the kernels are compiled (or loaded) on a later call
            _KERNELS = _compile()
    return _KERNELS or None


def _compile() -> dict[str, Any]:
    from mocapz.codecs.pga import ikkernels as kk

    out = {"solve_frames": kk.solve_frames, "pose": kk.pose, "solve_block": kk.solve_block, "forward": kk.forward,
           "euler_channels": kk.euler_channels}
    _warm(out)
    return out


def _warm(k: dict[str, Any]) -> None:
    """Compile (or load from numba's cache) every kernel now, on a one-joint problem with the argument types of
    the real calls: not later inside a caller's resource limits (tests run damaged files under an address-space
    cap and a timer, and a kernel first compiled there would abort the process)."""
    f8, i8 = np.float64, np.int64
    eye = np.eye(3)[None].copy()
    x = np.zeros((1, 1))
    basis = np.zeros((3, 1))
    k["solve_frames"](x, np.zeros((1, 3)), np.zeros((1, 1)), np.zeros((1, 1, 3)), False, basis,
                      np.ascontiguousarray(basis.T), eye, np.zeros(1, i8), np.full(1, -1, i8), np.zeros(1, i8),
                      eye.copy(), np.zeros(1, i8), np.zeros((1, 3)), np.zeros(1, i8), np.ones((1, 1), np.bool_),
                      1.0, 0.0, False, 1)
    k["pose"](x, np.ascontiguousarray(basis.T), eye, np.empty((1, 1, 3, 3), f8))
    k["euler_channels"](x, np.ascontiguousarray(basis.T), eye, eye.copy(), np.zeros(1, i8),
                        np.array([[2, 0, 1]], dtype=i8), np.ones(1), np.array([[0, 1, 2]], dtype=i8), eye.copy(),
                        np.zeros(1, np.bool_), 1.0, np.zeros((1, 3)))


__all__ = ["COMPILE_ROOM", "LAZY_FRAMES", "any_length", "enabled", "kernels", "room_to_compile", "set_enabled"]
