"""Compiled (numba) kernel of the skeletal pattern decoder's rotations: rotation vectors to Euler angles, with the
arithmetic of scipy's ``Rotation.from_rotvec(rv).as_euler(seq)`` (its compiled backend, scipy 1.17), so that a
decode gives scipy's bits without importing ``scipy.spatial`` (0.2 s of a skeletal patterns command).

The rotation vector becomes a quaternion (``sin(a / 2) / a`` times the vector, or its Taylor series under 1e-3
rad; ``cos(a / 2)``), the quaternion Euler angles by Bernardes & Viollet's direct method (PLoS ONE 17(11),
e0276302, 2022: a permutation of the quaternion's elements, two ``atan2`` of ``hypot``\\ s, a singular case at 0
and pi), each float operation in scipy's order with the C library's functions (numba calls libm's ``sin``,
``cos``, ``atan2`` and ``hypot`` as scipy's Cython does; NumPy's ``arctan2`` differs from libm's in the last bit for
a few % of arguments). tests/test_patterns_rotations.py holds it to scipy's bits.

Shapes: ``rv`` and ``out`` ``(frames, 3)`` (radians); ``axes`` ``(3,)`` the sequence's axis indices (0 x, 1 y, 2 z)
in scipy's extrinsic form (an intrinsic sequence reversed, :func:`mocapz.codecs.patterns.rotvec.scipy_axes`).
"""

# ruff: noqa: ANN001
from __future__ import annotations

import math

from numba import njit

jit = njit(cache=True, nogil=True, error_model="numpy")

SMALL_ANGLE = 1e-3  # radians under which scipy's from_rotvec takes the Taylor series of sin(a / 2) / a
SINGULAR = 1e-7  # radians from 0 or pi of the middle angle at which scipy sets the third angle to zero


@jit
def rotvec_euler(rv, axes, extrinsic, out) -> int:
    """Euler angles ``out`` of the rotation vectors ``rv`` about ``axes``; returns how many were singular (the
    middle angle within :data:`SINGULAR` of 0 or pi, the third angle set to zero, where scipy warns)."""
    i, j, k = axes[0], axes[1], axes[2]
    symmetric = i == k
    if symmetric:
        k = 3 - i - j
    sign = (i - j) * (j - k) * (k - i) // 2
    first, third = (0, 2) if extrinsic else (2, 0)
    half_pi = math.pi / 2
    q = [0.0, 0.0, 0.0, 0.0]
    singular = 0
    for t in range(rv.shape[0]):
        x, y, z = rv[t, 0], rv[t, 1], rv[t, 2]
        angle = math.sqrt(x * x + y * y + z * z)
        if angle <= SMALL_ANGLE:
            a2 = angle * angle
            scale = 0.5 - a2 / 48 + a2 * a2 / 3840
        else:
            scale = math.sin(angle / 2) / angle
        q[0], q[1], q[2], q[3] = scale * x, scale * y, scale * z, math.cos(angle / 2)
        if symmetric:
            a, b, c, d = q[3], q[i], q[j], q[k] * sign
        else:
            a = q[3] - q[j]
            b = q[i] + q[k] * sign
            c = q[j] + q[3]
            d = q[k] * sign - q[i]
        middle = 2 * math.atan2(math.hypot(c, d), math.hypot(a, b))
        half_sum = math.atan2(b, a)
        half_diff = math.atan2(d, c)
        case = 1 if abs(middle) <= SINGULAR else 2 if abs(middle - math.pi) <= SINGULAR else 0
        if case == 0:
            out[t, first] = half_sum - half_diff
            out[t, third] = half_sum + half_diff
        else:
            singular += 1
            out[t, 2] = 0.0
            out[t, 0] = 2 * half_sum if case == 1 else 2 * half_diff * (-1.0 if extrinsic else 1.0)
        out[t, 1] = middle
        if not symmetric:
            out[t, third] *= sign
            out[t, 1] -= half_pi
        for n in range(3):
            if out[t, n] < -math.pi:
                out[t, n] += 2 * math.pi
            elif out[t, n] > math.pi:
                out[t, n] -= 2 * math.pi
    return singular
