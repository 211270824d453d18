"""fc/frame_calls.py - the frame path's compiled calls without numba array records (issue 24).

numba wraps every numpy array passed from Python into a compiled function in an NRT meminfo
record (allocated and freed at each call): 22.6 records per plant frame before this module
(``python -m tools.bench --only allocs``). The entries here take the *addresses* of the fc's
preallocated arrays instead (Python ints, bound once) and view them inside with
``numba.carray`` (a view without a record and without reference counting), then run the same
kernels as the array entries: the same code on the same memory, so the same results.

The arrays behind an address must stay alive and never be rebound while it is used: the
owners (``PlantLink``, ``Estimator``, ``AttitudeLaw``, ``TickOutput``) allocate them once and
keep them; :class:`ArrayAddress` keeps a reference to the array it bound, and checks dtype,
layout and length once at binding (a wrong one raises ``ValueError`` there, never a bad write).
"""
from __future__ import annotations

from numba import carray, njit

import fc.control.carrays as _carrays
import hyfc_wire.codec as _codec
import hyfc_wire.frame_kernels as _frame_kernels
import hyfc_wire.layout as _wire_layout
import hyfc_wire.pwm as _pwm
from fc.control.carrays import ArrayAddress, address_of, f8p, i8p, u8p
from hyfc_wire.frame_kernels import decode_sensor, servo_frame, surfaces_pwm, throttle_pwm
from hyfc_wire.numba_cache import drop_stale

# the entries below compile the frame kernels (and their constants) into their own cache
drop_stale(__file__, [_carrays.__file__, _frame_kernels.__file__, _wire_layout.__file__,
                      _pwm.__file__, _codec.__file__])

__all__ = ["ArrayAddress", "address_of", "decode_sensor_p", "servo_frame_p", "surfaces_pwm_p",
           "surfaces_throttle_pwm_p", "blend3_p", "f8p", "i8p", "u8p"]


@njit(cache=True)
def decode_sensor_p(rx, rx_n, n, plant_sysid, meas, meas_n, gps, gps_n):
    """``hyfc_wire.frame_kernels.decode_sensor`` on the uint8[rx_n] at ``rx``, writing the
    float64[meas_n] at ``meas`` and the float64[gps_n] at ``gps``; returns its stamp (us) or
    its negative reject code."""
    return decode_sensor(carray(u8p(rx), (rx_n,)), n, plant_sysid,
                         carray(f8p(meas), (meas_n,)), carray(f8p(gps), (gps_n,)))


@njit(cache=True)
def servo_frame_p(tx, tx_n, seq, sysid, compid, time_usec, pwm):
    """``hyfc_wire.frame_kernels.servo_frame`` into the uint8[tx_n] at ``tx`` from the
    int64[4] servo values (us) at ``pwm``; returns the frame's length in bytes."""
    return servo_frame(carray(u8p(tx), (tx_n,)), seq, sysid, compid, time_usec,
                       carray(i8p(pwm), (4,)))


@njit(cache=True)
def surfaces_pwm_p(src, delta, throttle_pwm_us, pwm):
    """``hyfc_wire.frame_kernels.surfaces_pwm``: float64[3] ``src`` (rad) into float64[3]
    ``delta`` and int64[4] ``pwm`` (us), all given by address."""
    surfaces_pwm(carray(f8p(src), (3,)), carray(f8p(delta), (3,)), throttle_pwm_us,
                 carray(i8p(pwm), (4,)))


@njit(cache=True)
def surfaces_throttle_pwm_p(src, delta, thr, engaged, pwm):
    """:func:`surfaces_pwm_p` with servo4 = ``throttle_pwm`` of the float64 at ``thr`` (the
    guidance's throttle command, 0..1) when ``engaged``, else 0 (no output): the guidance
    modes' output without a Python value per tick (``throttle_to_pwm`` made 13 Python objects
    of the numpy scalar)."""
    t = throttle_pwm(carray(f8p(thr), (1,))[0]) if engaged else 0
    surfaces_pwm(carray(f8p(src), (3,)), carray(f8p(delta), (3,)), t, carray(i8p(pwm), (4,)))


@njit(cache=True)
def blend3_p(dst, src, k):
    """``dst[i] += k * (src[i] - dst[i])`` for i < 3 (float64[3] both, by address): the
    surface hold's running estimate (fc/mode_control.py ``SurfaceHold.update``), the same
    float64 operations as the Python loop it replaces."""
    d = carray(f8p(dst), (3,))
    s = carray(f8p(src), (3,))
    for i in range(3):
        d[i] += k * (s[i] - d[i])
