"""Small scalar and 3x3 helpers of the law's kernels: angle wrap, clip, det and solve of a
3x3 matrix stored flat row-major at a[o : o + 9]. numba-compiled, allocation-free."""
from __future__ import annotations

import math

from numba import njit


PI = math.pi


@njit(cache=True, inline="always", error_model="numpy")
def wrap_pi(a):
    """Angle wrapped into [-pi, pi)."""
    return (a + PI) % (2.0 * PI) - PI


@njit(cache=True, inline="always", error_model="numpy")
def clip(v, lo, hi):
    """v limited to [lo, hi]."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


@njit(cache=True, inline="always", error_model="numpy")
def det3(a, o):
    """det of the 3x3 matrix a[o:o+9] (row-major)."""
    return (a[o] * (a[o + 4] * a[o + 8] - a[o + 5] * a[o + 7])
            - a[o + 1] * (a[o + 3] * a[o + 8] - a[o + 5] * a[o + 6])
            + a[o + 2] * (a[o + 3] * a[o + 7] - a[o + 4] * a[o + 6]))


@njit(cache=True, error_model="numpy")
def solve3(a, o, b0, b1, b2, out, oo):
    """Solve A u = b for the 3x3 A = a[o:o+9] (row-major) by cofactors; writes out[oo:oo+3].

    Returns det(A); the caller guarantees it is not 0. Written out by hand: the cofactors
    are the whole cost, and a loop over index tables would read them from memory.
    """
    c00 = a[o + 4] * a[o + 8] - a[o + 5] * a[o + 7]
    c01 = a[o + 5] * a[o + 6] - a[o + 3] * a[o + 8]
    c02 = a[o + 3] * a[o + 7] - a[o + 4] * a[o + 6]
    det = a[o] * c00 + a[o + 1] * c01 + a[o + 2] * c02
    inv = 1.0 / det
    c10 = a[o + 2] * a[o + 7] - a[o + 1] * a[o + 8]
    c11 = a[o] * a[o + 8] - a[o + 2] * a[o + 6]
    c12 = a[o + 1] * a[o + 6] - a[o] * a[o + 7]
    c20 = a[o + 1] * a[o + 5] - a[o + 2] * a[o + 4]
    c21 = a[o + 2] * a[o + 3] - a[o] * a[o + 5]
    c22 = a[o] * a[o + 4] - a[o + 1] * a[o + 3]
    # inverse = adjugate / det, adjugate = cofactor matrix transposed
    out[oo] = (c00 * b0 + c10 * b1 + c20 * b2) * inv
    out[oo + 1] = (c01 * b0 + c11 * b1 + c21 * b2) * inv
    out[oo + 2] = (c02 * b0 + c12 * b1 + c22 * b2) * inv
    return det


@njit(cache=True, inline="always", error_model="numpy")
def matvec3(a, o, v0, v1, v2):
    """(A v) for the 3x3 A = a[o:o+9] (row-major), as a tuple."""
    return (a[o] * v0 + a[o + 1] * v1 + a[o + 2] * v2,
            a[o + 3] * v0 + a[o + 4] * v1 + a[o + 5] * v2,
            a[o + 6] * v0 + a[o + 7] * v1 + a[o + 8] * v2)


@njit(cache=True, inline="always", error_model="numpy")
def put3(out, o, v):
    """out[o:o+3] = the 3-tuple v."""
    out[o] = v[0]
    out[o + 1] = v[1]
    out[o + 2] = v[2]
