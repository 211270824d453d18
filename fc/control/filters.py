"""Signal shaping of the law (deviations: the paper leaves Omega_c_dot and omega_c_dot
undefined and assumes noise-free measurements; docs/control_law.md).

    second_order_phi / second_order_step   the reference prefilter (Omega_c, Omega_c_dot) and
                                           the command filter (omega_c, omega_c_dot): exact
                                           zero-order-hold 2nd-order filters
    lowpass2_step                          the input filters of the measured rates and angles
    input_ok                               the input check both loops run first
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.layout import E_N
from fc.control.linalg3 import PI, wrap_pi


@njit(cache=True, error_model="numpy")
def second_order_phi(dt, wn, zeta):
    """State-transition matrix (phi11, phi12, phi21, phi22) of y'' = -wn^2 y - 2 zeta wn y'
    over dt: the exact (zero-order-hold) discretisation of the 2nd-order filters, stable and
    accurate for any wn dt (a 25 Hz loop with wn 40 rad/s included)."""
    sg = zeta * wn
    E = math.exp(-sg * dt)
    d = 1.0 - zeta * zeta
    if abs(d) < 1e-6:                       # critically damped
        return (E * (1.0 + wn * dt), E * dt, -E * wn * wn * dt, E * (1.0 - wn * dt))
    if d > 0.0:                             # under-damped
        wd = wn * math.sqrt(d)
        c = math.cos(wd * dt)
        sn = math.sin(wd * dt)
    else:                                   # over-damped
        wd = wn * math.sqrt(-d)
        c = math.cosh(wd * dt)
        sn = math.sinh(wd * dt)
    return (E * (c + sg / wd * sn), E * sn / wd, -E * wn * wn / wd * sn,
            E * (c - sg / wd * sn))


@njit(cache=True, error_model="numpy")
def second_order_step(u, phi, x, ix, ixd):
    """One exact step of y'' = wn^2 (u - y) - 2 zeta wn y' (u held) on x[ix], x[ixd]."""
    e = x[ix] - u
    v = x[ixd]
    x[ix] = u + phi[0] * e + phi[1] * v
    x[ixd] = phi[2] * e + phi[3] * v


@njit(cache=True, error_model="numpy")
def lowpass2_step(u, dt, fc_hz, x, i1, i2, wrap):
    """Two exact-discretised 1st-order low-pass sections at ``fc_hz`` (stable for any dt).

    Updates x[i1], x[i2] toward u and returns the output x[i2]; ``fc_hz`` <= 0 passes u
    through (and keeps the states on it). ``wrap``: the signal is an angle taken modulo 2 pi.
    """
    if fc_hz <= 0.0:
        x[i1] = u
        x[i2] = u
        return u
    a = 1.0 - math.exp(-2.0 * PI * fc_hz * dt)
    if wrap:
        x[i1] = wrap_pi(x[i1] + a * wrap_pi(u - x[i1]))
        x[i2] = wrap_pi(x[i2] + a * wrap_pi(x[i1] - x[i2]))
    else:
        x[i1] += a * (u - x[i1])
        x[i2] += a * (x[i1] - x[i2])
    return x[i2]


@njit(cache=True, error_model="numpy")
def input_ok(est, dt):
    """True if every entry of est is finite and 0 < dt <= 1 s (else the step is skipped)."""
    if not (dt > 0.0 and dt <= 1.0):
        return False
    for i in range(E_N):
        if not math.isfinite(est[i]):
            return False
    return True
