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

The plant link's receive and answer (:func:`recv_sensor_p`, :func:`send_servo_p`) also call
libc's ``recvfrom``/``sendto`` from compiled code on the socket's descriptor, with the source
and destination as ``sockaddr_in`` bytes: no Python object per datagram (``socket``'s
``recvfrom_into`` makes the source's address string and port int for every datagram). They
count datagrams, frames and outputs in the link's int64 counters (``LinkCounters.hot``) and
return a small code, so nothing crosses back into Python but the frame's stamp. numba resolves
the two libc symbols in the process (``types.ExternalFunction``); with NUMBA_DISABLE_JIT they
cannot run and the link uses ``socket``'s calls (``FAST_IO`` False).
"""
from __future__ import annotations

import ctypes

from numba import carray, njit, types
from numba.core import config as _numba_config

import fc.control.carrays as _carrays
import hyfc_wire.codec as _codec
import hyfc_wire.frame_kernels as _frame_kernels
import hyfc_wire.layout as _wire_layout
import hyfc_wire.pwm as _pwm
from fc.control.carrays import ArrayAddress, address_of, f8p, i8p, u4p, u8p
from hyfc_wire.frame_kernels import decode_sensor, servo_frame, surfaces_pwm, throttle_pwm
from hyfc_wire.numba_cache import drop_stale

# the entries below compile the frame kernels (and their constants) into their own cache
drop_stale(__file__, [_carrays.__file__, _frame_kernels.__file__, _wire_layout.__file__,
                      _pwm.__file__, _codec.__file__])

__all__ = ["ArrayAddress", "address_of", "decode_sensor_p", "servo_frame_p", "surfaces_pwm_p",
           "surfaces_throttle_pwm_p", "blend3_p", "copy_p", "count_p", "recv_sensor_p", "send_servo_p", "send_servo_at_p",
           "intake_p", "int64_at", "FAST_IO", "RX_FRAME", "RX_FRAME_BIG", "RX_NONE", "RX_OTHER", "RX_REJECTED", "HOT_DATAGRAMS", "HOT_FRAMES", "HOT_OUTPUTS",
           "HOT_EMPTY_READS", "HOT_N", "IO_LEN", "IO_STAMP", "IO_N", "STAMP_CELL_MAX_US",
           "INTAKE_NEW", "INTAKE_DUPLICATE", "INTAKE_LATE", "INTAKE_RESTART", "IN_LAST", "IN_STAMP",
           "IN_N", "SOCKADDR_IN_B", "f8p", "i8p", "u4p",
           "u8p"]

#: the link's counters the compiled calls keep (``LinkCounters.hot``, int64[HOT_N])
HOT_DATAGRAMS = 0       # datagrams received
HOT_FRAMES = 1          # complete sensor frames accepted
HOT_OUTPUTS = 2         # SERVO_OUTPUT_RAW sent
HOT_EMPTY_READS = 3     # receives that found nothing waiting (or failed)
HOT_N = 4
#: the receive's result beside its code (int64[IO_N])
IO_LEN = 0              # length of the datagram received (bytes, cut at the buffer's length)
IO_STAMP = 1            # the stamp of the frame received (us): the frame's stamp cell
IO_N = 2
#: stamps below this (us) are kept in int64 cells through the frame path (the intake, the tick
#: planner, the answer, the internals row, the .tlog's schedule: every sum and product there
#: stays in int64, the planner's ``_SAFE_US``); a stamp at or beyond it (a faulty plant's u64)
#: takes the Python-int path, as before the cells
STAMP_CELL_MAX_US = (1 << 61) // 1000
#: recv_sensor_p's codes
RX_FRAME = 0            # a frame, decoded; its stamp in ``io[IO_STAMP]``
RX_FRAME_BIG = 1        # the same, its stamp at or beyond STAMP_CELL_MAX_US
RX_NONE = -1            # nothing waiting (or the receive failed: as ``UdpEndpoint.recv_into``)
RX_OTHER = -2           # a datagram whose source is not the locked peer (or none is locked yet)
RX_REJECTED = -3        # from the peer, but the compiled decoder rejected it (the general parser's)
SOCKADDR_IN_B = 16      # sizeof(struct sockaddr_in)
_MSG_DONTWAIT = 0x40    # Linux
#: the libc calls can be compiled (not under NUMBA_DISABLE_JIT, where kernels run as Python)
FAST_IO = not _numba_config.DISABLE_JIT
_recvfrom = types.ExternalFunction("recvfrom", types.intp(
    types.intc, types.CPointer(types.uint8), types.uintp, types.intc, types.CPointer(types.uint8),
    types.CPointer(types.uint32)))
_sendto = types.ExternalFunction("sendto", types.intp(
    types.intc, types.CPointer(types.uint8), types.uintp, types.intc, types.CPointer(types.uint8),
    types.uint32))


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


@njit(cache=True)
def copy_p(dst, src, n):
    """The float64[n] at ``src`` copied to the float64[n] at ``dst`` (by address)."""
    d = carray(f8p(dst), (n,))
    s = carray(f8p(src), (n,))
    for i in range(n):
        d[i] = s[i]


@njit(cache=True)
def count_p(counter):
    """``counter += 1`` on the int64 at ``counter`` (a count kept beyond CPython's cached
    small ints without an int object per step)."""
    carray(i8p(counter), (1,))[0] += 1


@njit(cache=True)
def recv_sensor_p(fd, rx, rx_n, sa, salen, peer, locked, plant_sysid, meas, meas_n, gps, gps_n,
                  hot, io):
    """One datagram from the non-blocking UDP socket ``fd`` into the uint8[rx_n] at ``rx``
    (libc ``recvfrom``), its source's sockaddr_in into the uint8[16] at ``sa`` (its length
    through the uint32 at ``salen``); when ``locked`` and it came from the sockaddr_in at
    ``peer`` (family, port, address), ``decode_sensor`` of it as :func:`decode_sensor_p`.
    Counts in int64 ``hot`` (HOT_*), the length in int64 ``io[IO_LEN]``. Returns RX_FRAME (the
    frame's stamp, us, in ``io[IO_STAMP]``: no Python int for it; counted in HOT_FRAMES;
    RX_FRAME_BIG for a stamp at or beyond STAMP_CELL_MAX_US), or RX_NONE, RX_OTHER or
    RX_REJECTED."""
    h = carray(i8p(hot), (HOT_N,))
    ln = carray(u4p(salen), (1,))
    ln[0] = SOCKADDR_IN_B
    n = _recvfrom(fd, u8p(rx), rx_n, _MSG_DONTWAIT, u8p(sa), u4p(salen))
    if n < 0:
        h[HOT_EMPTY_READS] += 1
        return RX_NONE
    h[HOT_DATAGRAMS] += 1
    carray(i8p(io), (IO_N,))[IO_LEN] = n
    if not locked or ln[0] != SOCKADDR_IN_B:
        return RX_OTHER
    src = carray(u8p(sa), (SOCKADDR_IN_B,))
    want = carray(u8p(peer), (SOCKADDR_IN_B,))
    for i in range(8):                      # family, port, IPv4 address (the rest is zero)
        if src[i] != want[i]:
            return RX_OTHER
    stamp = decode_sensor(carray(u8p(rx), (rx_n,)), n, plant_sysid,
                          carray(f8p(meas), (meas_n,)), carray(f8p(gps), (gps_n,)))
    if stamp < 0:
        return RX_REJECTED
    carray(i8p(io), (IO_N,))[IO_STAMP] = stamp
    h[HOT_FRAMES] += 1
    return RX_FRAME if stamp < STAMP_CELL_MAX_US else RX_FRAME_BIG


@njit(cache=True)
def _send_servo(fd, tx, tx_n, seq, sysid, compid, time_usec, pwm, peer, hot):
    n = servo_frame(carray(u8p(tx), (tx_n,)), seq, sysid, compid, time_usec,
                    carray(i8p(pwm), (4,)))
    if _sendto(fd, u8p(tx), n, 0, u8p(peer), SOCKADDR_IN_B) < 0:
        return False
    carray(i8p(hot), (HOT_N,))[HOT_OUTPUTS] += 1
    return True


@njit(cache=True)
def send_servo_p(fd, tx, tx_n, seq, sysid, compid, time_usec, pwm, peer, hot):
    """:func:`servo_frame_p` into the uint8[tx_n] at ``tx``, sent to the sockaddr_in at
    ``peer`` with libc ``sendto`` on ``fd``. Counts it in int64 ``hot[HOT_OUTPUTS]`` when sent;
    returns True if it was."""
    return _send_servo(fd, tx, tx_n, seq, sysid, compid, time_usec, pwm, peer, hot)


@njit(cache=True)
def send_servo_at_p(fd, tx, tx_n, seq, sysid, compid, stamp, pwm, peer, hot):
    """:func:`send_servo_p` echoing the stamp in the int64 cell at ``stamp`` (us, >= 0) mod
    2^32: no Python int for it."""
    t = carray(i8p(stamp), (1,))[0] & 0xFFFFFFFF
    return _send_servo(fd, tx, tx_n, seq, sysid, compid, t, pwm, peer, hot)


def int64_at(addr: int) -> int:
    """The int64 at ``addr`` as a Python int (a cell read outside the compiled calls: the
    exceptional paths)."""
    return ctypes.c_int64.from_address(addr).value


#: the frame intake's stamps (fc/intake.py ``FrameIntake``, int64[IN_N])
IN_LAST = 0             # the newest frame's stamp taken (us), -1 before the first
IN_STAMP = 1            # the stamp of ``meas`` (us), 0 before the first
IN_N = 2
#: intake_p's verdicts
INTAKE_NEW, INTAKE_DUPLICATE, INTAKE_LATE, INTAKE_RESTART = 0, 1, 2, 3


@njit(cache=True)
def intake_p(stamp, st, late_window_us):
    """``FrameIntake.take``'s stamp checks on the stamp in the int64 cell at ``stamp`` and the
    intake's int64[IN_N] at ``st``: INTAKE_DUPLICATE (the newest stamp again) or INTAKE_LATE (at
    most ``late_window_us`` older) leave the state; INTAKE_NEW or INTAKE_RESTART (plant time
    went further back) take the stamp as the newest and as ``meas``'s."""
    t = carray(i8p(stamp), (1,))[0]
    s = carray(i8p(st), (IN_N,))
    last = s[IN_LAST]
    if t == last:
        return INTAKE_DUPLICATE
    verdict = INTAKE_NEW
    if last >= 0 and t < last:
        if last - t <= late_window_us:
            return INTAKE_LATE
        verdict = INTAKE_RESTART
    s[IN_LAST] = t
    s[IN_STAMP] = t
    return verdict
