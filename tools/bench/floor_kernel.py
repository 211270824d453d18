"""A trivial cached numba kernel: the start-up floor of any process that runs njit code.

``tools.bench`` times a bare interpreter that imports numpy, numba and pymavlink's dialect
and calls :func:`add1` once (numba's CPU-target initialisation, which imports scipy.linalg
to find BLAS, plus one cache load): the part of the fc's start-up that is not the fc's.
"""
from numba import njit


@njit(cache=True)
def add1(x):
    return x + 1.0
