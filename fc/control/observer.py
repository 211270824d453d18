"""Disturbance observer (Eq. 37, after the paper's Ref. 33), discretised exactly.

    d_hat = z + Q(omega),  z_dot = -L z - L (f + Q(omega)),  Q = c_d omega,  L = c I

with f the modelled angular acceleration without the disturbance (rad/s^2 per axis) and the
state z in x[X_Z:X_Z+3]. docs/control_law.md section 9.
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.layout import X_Z


@njit(cache=True, inline="always", error_model="numpy")
def dob_gain(c, dt):
    """Discrete observer gain c_d = (1 - exp(-c dt)) / dt (-> c as dt -> 0).

    With Q = c_d omega the discrete observer below is exactly a first-order filter of
    bandwidth c on the finite-difference measurement of d, stable for any c dt.
    """
    return (1.0 - math.exp(-c * dt)) / dt


@njit(cache=True, inline="always", error_model="numpy")
def dob_estimate(x, c_d, w0, w1, w2):
    """Eq. 37: d_hat = z + Q(omega), Q = c_d omega (rad/s^2 per axis)."""
    return x[X_Z] + c_d * w0, x[X_Z + 1] + c_d * w1, x[X_Z + 2] + c_d * w2


@njit(cache=True, error_model="numpy")
def dob_update(x, c_d, dt, f0, f1, f2, w0, w1, w2):
    """Eq. 37: z_dot = -L z - L (f + Q(omega)), L = c I, over one step of dt.

    f = Xi^T theta_hat + g_f M is the modelled angular acceleration (rad/s^2) without the
    disturbance over the step. Discretised as z+ = (1 - c_d dt) z - c_d dt (f + c_d omega),
    which gives d_hat+ = e^(-c dt) d_hat + (1 - e^(-c dt)) ((omega+ - omega)/dt - f).
    """
    a = c_d * dt
    x[X_Z] = (1.0 - a) * x[X_Z] - a * (f0 + c_d * w0)
    x[X_Z + 1] = (1.0 - a) * x[X_Z + 1] - a * (f1 + c_d * w1)
    x[X_Z + 2] = (1.0 - a) * x[X_Z + 2] - a * (f2 + c_d * w2)
