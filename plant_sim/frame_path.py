"""The plant's lockstep frame in one compiled call, arrays given by address (issue 24).

Per lockstep frame k the plant process used to make five compiled calls from Python (decode the
servo datagram, the sensor framing, ``PlantSim.frame``), each wrapping its numpy arguments in a
numba runtime record (allocated, reference counted and freed per call), plus the PWM map, the
truth log's ``row()`` and the socket calls in Python. :func:`lockstep_frame_p` does all of it in
one call whose only arguments are ints: the address of an int64 table that holds the addresses
of the plant's preallocated arrays (bound once, :class:`FramePath`), the frame index and a mode.
Inside, the arrays are ``numba.carray`` views (no record, no reference count), and the same
kernels run on the same memory in the same order as the Python path, so the bytes sent, the
state and the truth rows are the same:

0. (``MODE_WAIT``) libc ``poll`` until the socket is readable, at most ``wait_ms``;
1. (``MODE_RECV``) one datagram from the socket with libc ``recvfrom`` (``MSG_DONTWAIT``), its
   source checked against the fc's ``sockaddr_in``;
2. (``MODE_DECODE``) ``hyfc_wire.frame_kernels.decode_servo`` of it, the system id, the stamp
   against frame k's (``round(k frame_dt 1e6) mod 2^32``); a match is latched as
   ``PlantLink._apply`` does (PWM -> rad through MIN/TRIM/MAX, servo4 -> throttle, a channel 0
   keeps its command) straight into the state's command slots;
3. ``sim.frame_kernel``: the truth row at t_k (into the truth log's block, with its decimation),
   two RK4 steps, the sensors at t_k+1;
4. (``MODE_ENCODE``) ``sensor_frame`` of frame k+1 (no GNSS sample) into the link's send buffer
   and (``MODE_SEND``) libc ``sendto`` to the fc.

Whatever the kernel cannot decide returns to Python with a code (:data:`R_*`): a datagram the
compiled decoder rejects (the codec's general parser takes it, as before), no datagram, a
truth block to flush, clipped aerodynamics, a framing value the codec would refuse, a failed
send. Frames with a GNSS event (a capture or a sample to send) are framed in Python
(``GnssSensor`` is Python), the kernel called without ``MODE_ENCODE``.

The counters the kernel keeps live in the int64 table's cells and are added to the Python
objects' counters when the path is left (:meth:`FramePath.leave`).
"""
from __future__ import annotations

import ctypes
import socket
import sys

import numpy as np
from numba import carray, njit, types
from numba.core import config as _numba_config
from numba.extending import intrinsic

import hyfc_wire.codec as _codec_mod
import hyfc_wire.frame_kernels as _fk_mod
import hyfc_wire.layout as _layout_mod
import hyfc_wire.pwm as _pwm_mod
from hyfc_wire.frame_kernels import SENSOR_FRAME_MAX_B, SV_N, decode_servo, sensor_frame
from hyfc_wire.layout import G_N
from hyfc_wire.numba_cache import drop_stale
from hyfc_wire.pwm import THROTTLE_PWM_MAX_US, THROTTLE_PWM_MIN_US
from plant_sim import _jitcache
from plant_sim import dynamics as dy
from plant_sim import sensors as se
from plant_sim.sensors import M_N, RING_N
from plant_sim.sim import TRUTH_N, truth_kernel

# the kernels it calls (and their constants) are compiled into this module's cache
drop_stale(__file__, [_jitcache._HERE / f for f in _jitcache.KERNEL_SOURCES]
           + [_fk_mod.__file__, _codec_mod.__file__, _pwm_mod.__file__, _layout_mod.__file__])

__all__ = ["FramePath", "lockstep_frame_p", "physics_loop", "warm_up", "sockaddr_in", "FAST_IO",
           "MODE_RECV", "MODE_DECODE", "MODE_ENCODE", "MODE_SEND", "MODE_WAIT", "MODE_FRAME",
           "R_NONE", "R_SOURCE", "R_FALLBACK", "R_SYSID", "R_STALE",
           "B_CLIP", "B_FLUSH", "B_ENCODE_REFUSED", "B_SEND_FAILED"]


# ---- int64 pointers from addresses (compiled code), as fc/control/carrays.py (the plant does
# not import the fc)
def _pointer_cast(elem):
    def cast(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None
        sig = types.CPointer(elem)(addr)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
        return sig, codegen
    return cast


#: the libc calls and address casts can be compiled (not under NUMBA_DISABLE_JIT)
FAST_IO = not _numba_config.DISABLE_JIT
if FAST_IO:
    _f8p = intrinsic(_pointer_cast(types.float64))
    _i8p = intrinsic(_pointer_cast(types.int64))
    _u8p = intrinsic(_pointer_cast(types.uint8))
    _u64p = intrinsic(_pointer_cast(types.uint64))
    _u4p = intrinsic(_pointer_cast(types.uint32))
else:
    def _cast(ct):
        return lambda a: ctypes.cast(int(a), ctypes.POINTER(ct))
    _f8p, _i8p, _u8p = _cast(ctypes.c_double), _cast(ctypes.c_int64), _cast(ctypes.c_uint8)
    _u64p, _u4p = _cast(ctypes.c_uint64), _cast(ctypes.c_uint32)

_recvfrom = types.ExternalFunction("recvfrom", types.intp(
    types.intc, types.CPointer(types.uint8), types.uintp, types.intc, types.CPointer(types.uint8),
    types.CPointer(types.uint32)))
_sendto = types.ExternalFunction("sendto", types.intp(
    types.intc, types.CPointer(types.uint8), types.uintp, types.intc, types.CPointer(types.uint8),
    types.uint32))
_poll = types.ExternalFunction("poll", types.intc(types.CPointer(types.uint8), types.uint64,
                                                  types.intc))
_errno_location = types.ExternalFunction("__errno_location", types.CPointer(types.intc)())
_POLLIN = 1
POLLFD_B = 8            # sizeof(struct pollfd): int fd, short events, short revents
_MSG_DONTWAIT = 0x40    # Linux
_ECONNREFUSED = 111     # Linux: ICMP port unreachable from an earlier send (the drain skips it)
_EAGAIN = 11
_EINTR = 4
SOCKADDR_IN_B = 16
_U32 = 1 << 32

# ---- modes (bits of lockstep_frame_p's ``mode``)
MODE_RECV = 1           # receive one datagram first (libc recvfrom; else it is in rx already)
MODE_DECODE = 2         # decode the datagram in rx (else the command is latched in x already)
MODE_ENCODE = 4         # frame the sensors of frame k+1 (without GNSS) into the send buffer
MODE_SEND = 8           # and send them (libc sendto)
MODE_WAIT = 16          # before the receive, wait up to ``wait_ms`` for a datagram (libc poll)
#: the lockstep's ordinary frame
MODE_FRAME = MODE_WAIT | MODE_RECV | MODE_DECODE | MODE_ENCODE | MODE_SEND

# ---- codes (< 0: nothing stepped) and bits of the result (>= 0: the frame ran)
R_NONE = -1             # nothing received (the wait timed out or was interrupted by a signal;
#                         EAGAIN, EINTR; another receive error is counted malformed)
R_SOURCE = -2           # a datagram from another address than the fc's (counted)
R_FALLBACK = -3         # a datagram the compiled decoder rejects: the codec's general parser
R_SYSID = -4            # a SERVO_OUTPUT_RAW from another system id (counted)
R_STALE = -5            # a SERVO_OUTPUT_RAW with another frame's stamp (accepted, counted)
B_CLIP = 1              # the aerodynamic inputs were clipped in this frame
B_FLUSH = 2             # the truth log's block is full: flush it before the next frame
B_ENCODE_REFUSED = 4    # a value the codec's struct refuses: frame k+1 in Python (raises)
B_SEND_FAILED = 8       # sendto failed: send again from Python (counts or raises as before)

# ---- the int64 table (addresses, sizes, constants, cells)
A_X, A_P, A_W, A_RING, A_RING_COUNT, A_RNG, A_MEAS_WORK, A_MEAS = range(8)
A_RX, A_TX, A_REC, A_BLOCK, A_DISCARD, A_SA, A_SALEN, A_PEER, A_F = range(8, 17)
A_POLLFD = 46           # struct pollfd of the socket (uint8[POLLFD_B])
C_P_N, C_RX_N, C_TX_N, C_BLOCK_ROWS, C_N_SUB, C_FD, C_SYSID, C_COMPID, C_FC_SYSID = range(17, 26)
C_FULL_ROWS, C_EVERY = 26, 27        # truth decimation (C_FULL_ROWS -1: every row)
# cells the kernel writes
C_SEQ = 28              # MAVLink sequence of the next frame sent
C_OUT_LEN = 29          # length of the sensor datagram in the send buffer
C_RX_LEN = 30           # length of the datagram received
C_T_OFFERED, C_T_FILL, C_T_ROWS, C_T_DECIMATED = 31, 32, 33, 34   # TruthWriter's counts
# counts added to the Python objects' at leave()
C_FRAMES = 35           # frames run (sim.frames)
C_CLIPS = 36            # of which clipped (sim.clip_frames)
C_SENT = 37             # sensor datagrams sent (link.frames_sent)
C_RX = 38               # datagrams received (link.rx_datagrams)
C_SOURCE = 39           # link.rejected_source
C_SYSID_REJ = 40        # link.rejected_sysid
C_ACCEPTED = 41         # link.cmd_count
C_APPLIED = 42          # link.applied_count
C_MALFORMED = 43        # link.rejected_malformed (a receive error)
C_STAMP = 44            # the last applied stamp (link.cmd_stamp_u32)
C_THR_SET = 45          # 1 once a servo4 value was latched
A_N = 47
_COUNTS = range(C_FRAMES, C_MALFORMED + 1)
# the float64 table
F_TRIM, F_MIN, F_MAX, F_UP, F_DOWN, F_THR_SCALE, F_FRAME_DT = range(7)
F_N = 7


@njit(cache=True)
def _to_rad(f, pwm):
    """``hyfc_wire.pwm.PwmMap.to_rad`` with the map in ``f`` (the same operations)."""
    if pwm < f[F_MIN]:
        pwm = np.int64(f[F_MIN])
    elif pwm > f[F_MAX]:
        pwm = np.int64(f[F_MAX])
    d = pwm - np.int64(f[F_TRIM])
    return d * f[F_UP] if d >= 0 else d * f[F_DOWN]


@njit(cache=True)
def _throttle_from_pwm(pwm):
    """``hyfc_wire.pwm.throttle_from_pwm`` (the same operations)."""
    fr = (pwm - THROTTLE_PWM_MIN_US) / (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)
    return 0.0 if fr < 0.0 else 1.0 if fr > 1.0 else fr


@njit(cache=True, nogil=True)
def lockstep_frame_p(a, k, mode, wait_ms):
    """Frame ``k`` of the lockstep loop over the arrays of the int64 table at address ``a``
    (:class:`FramePath`): see the module's docstring for the steps ``mode`` selects
    (``wait_ms``: the longest wait of ``MODE_WAIT``, ms). Returns an ``R_*`` code (< 0, the
    frame did not run) or the ``B_*`` bits of a frame that ran. Runs without the GIL (it
    touches no Python object): a thread of the same process, such as a test's fc stand-in,
    runs while it waits in ``poll``, as during ``select``."""
    t = carray(_i8p(a), (A_N,))
    f = carray(_f8p(t[A_F]), (F_N,))
    x = carray(_f8p(t[A_X]), (dy.X_N,))
    stamp_k = np.int64(np.rint(k * f[F_FRAME_DT] * 1e6))
    if mode & MODE_WAIT:
        # poll(): the socket readable within wait_ms; 0 (timed out) or -1 (a signal): Python
        # decides (stop, re-request); select() before did the same with us timeouts
        if _poll(_u8p(t[A_POLLFD]), 1, wait_ms) <= 0:
            return R_NONE
    if mode & MODE_RECV:
        ln = carray(_u4p(t[A_SALEN]), (1,))
        while True:
            ln[0] = SOCKADDR_IN_B
            n = _recvfrom(t[C_FD], _u8p(t[A_RX]), t[C_RX_N], _MSG_DONTWAIT, _u8p(t[A_SA]),
                          _u4p(t[A_SALEN]))
            if n >= 0:
                break
            e = _errno_location()[0]
            if e == _ECONNREFUSED:
                continue
            if e != _EAGAIN and e != _EINTR:
                t[C_MALFORMED] += 1
            return R_NONE
        t[C_RX] += 1
        t[C_RX_LEN] = n
        if ln[0] != SOCKADDR_IN_B:
            t[C_SOURCE] += 1
            return R_SOURCE
        src = carray(_u8p(t[A_SA]), (SOCKADDR_IN_B,))
        want = carray(_u8p(t[A_PEER]), (SOCKADDR_IN_B,))
        for i in range(8):                  # family, port, IPv4 address
            if src[i] != want[i]:
                t[C_SOURCE] += 1
                return R_SOURCE
    if mode & MODE_DECODE:
        rec = carray(_i8p(t[A_REC]), (SV_N,))
        if not decode_servo(carray(_u8p(t[A_RX]), (t[C_RX_N],)), t[C_RX_LEN], rec):
            return R_FALLBACK
        if rec[0] != t[C_FC_SYSID]:
            t[C_SYSID_REJ] += 1
            return R_SYSID
        t[C_ACCEPTED] += 1
        if rec[1] != stamp_k % _U32:
            return R_STALE
        # PlantLink._apply, latched as the loop latches link.cmd_rad / cmd_throttle
        for c in range(3):
            if rec[2 + c] != 0:
                x[dy.X_CMD_L + c] = _to_rad(f, rec[2 + c])
        if rec[5] != 0:
            x[dy.X_CMD_THR] = _throttle_from_pwm(rec[5])
            t[C_THR_SET] = 1
        t[C_STAMP] = rec[1]
        t[C_APPLIED] += 1
    # the truth row at t_k (TruthWriter.row's choice), then the frame
    res = 0
    ko = t[C_T_OFFERED]
    t[C_T_OFFERED] = ko + 1
    full = t[C_FULL_ROWS]
    if full >= 0 and ko >= full and (ko - full) % t[C_EVERY] != 0:
        t[C_T_DECIMATED] += 1
        row = carray(_f8p(t[A_DISCARD]), (TRUTH_N,))
    else:
        row = carray(_f8p(t[A_BLOCK] + 8 * TRUTH_N * t[C_T_FILL]), (TRUTH_N,))
        t[C_T_FILL] += 1
        t[C_T_ROWS] += 1
        if t[C_T_FILL] == t[C_BLOCK_ROWS]:
            res |= B_FLUSH
    p = carray(_f8p(t[A_P]), (t[C_P_N],))
    w = carray(_f8p(t[A_W]), (dy.W_N,))
    meas = carray(_f8p(t[A_MEAS]), (M_N,))
    truth_kernel(x, p, w, meas, row)
    flags = dy.advance_frame_latched(x, p, w, t[C_N_SUB])
    se.measure(x, p, carray(_f8p(t[A_RING]), (RING_N, M_N)), carray(_i8p(t[A_RING_COUNT]), (1,)),
               carray(_u64p(t[A_RNG]), (1,)), carray(_f8p(t[A_MEAS_WORK]), (8,)), meas)
    t[C_FRAMES] += 1
    if flags:
        t[C_CLIPS] += 1
        res |= B_CLIP
    if mode & MODE_ENCODE:
        tx = carray(_u8p(t[A_TX]), (t[C_TX_N],))
        stamp1 = np.int64(np.rint((k + 1) * f[F_FRAME_DT] * 1e6))
        seq = t[C_SEQ]
        pos = sensor_frame(tx, seq, t[C_SYSID], t[C_COMPID], stamp1, meas,
                           x[dy.X_THRUST] * f[F_THR_SCALE], w[0:G_N], False)
        if pos < 0:
            return res | B_ENCODE_REFUSED
        t[C_SEQ] = (seq + 3) & 0xFF
        t[C_OUT_LEN] = pos
        if mode & MODE_SEND:
            if _sendto(t[C_FD], _u8p(t[A_TX]), pos, 0, _u8p(t[A_PEER]), SOCKADDR_IN_B) < 0:
                return res | B_SEND_FAILED
            t[C_SENT] += 1
    return res


@njit(cache=True)
def physics_loop(a, n):
    """``n`` frames of :func:`lockstep_frame_p` in mode 0 (no wire: truth row, physics,
    sensors) from inside numba: the frame's floor without a Python call (tools.bench plant).
    Needs a truth log that keeps no row (else a full block would need Python)."""
    for _ in range(n):
        lockstep_frame_p(a, 0, 0, 0)


def warm_up() -> None:
    """Load :func:`lockstep_frame_p` from numba's cache (or compile it) now, not at the first
    frame: the signature the process calls it with (four int64)."""
    if FAST_IO:
        lockstep_frame_p.compile((types.int64, types.int64, types.int64, types.int64))


def _addr(arr: np.ndarray, dtype, n: int) -> int:
    """The data address of a C-contiguous writable ``dtype`` array of at least ``n`` items."""
    if (arr.dtype != np.dtype(dtype) or not arr.flags.c_contiguous or not arr.flags.writeable
            or arr.size < n):
        raise ValueError(f"need a writable C-contiguous {np.dtype(dtype)}[>= {n}] array")
    return int(arr.__array_interface__["data"][0])


def sockaddr_in(addr) -> np.ndarray:
    """(dotted IPv4, port) as the uint8[16] sockaddr_in libc's calls take (family in host
    order, port and address in network order, zero padding)."""
    sa = np.zeros(SOCKADDR_IN_B, np.uint8)
    sa[0:2] = np.frombuffer(socket.AF_INET.to_bytes(2, sys.byteorder), np.uint8)
    sa[2:4] = np.frombuffer(int(addr[1]).to_bytes(2, "big"), np.uint8)
    sa[4:8] = np.frombuffer(socket.inet_aton(socket.gethostbyname(addr[0])), np.uint8)
    return sa


class FramePath:
    """The addresses of the plant's arrays bound once for :func:`lockstep_frame_p`.

    ``sim`` (PlantSim), ``link`` (PlantLink, lean framing), ``writer`` (TruthWriter or any
    object with its ``block``, ``block_rows``, ``_discard``, ``full_rows``, ``every`` and
    counts), ``thr_scale`` (VFR_HUD's throttle % per N of thrust). ``enter()`` copies the Python
    side's counts and sequence into the table, ``leave()`` copies them back (the counts the
    kernel made added to the Python objects'); between the two, only the kernel changes them.
    The arrays must stay bound (the objects keep them for their life)."""

    def __init__(self, sim, link, writer, thr_scale: float):
        self.sim, self.link, self.writer = sim, link, writer
        t = self.table = np.zeros(A_N, np.int64)
        self.f = np.zeros(F_N)
        self._sa = np.zeros(SOCKADDR_IN_B, np.uint8)
        self._salen = np.zeros(1, np.uint32)
        self._peer = sockaddr_in(link.fc_addr)
        t[A_X] = _addr(sim.x, np.float64, dy.X_N)
        t[A_P] = _addr(sim.p, np.float64, len(sim.p))
        t[C_P_N] = len(sim.p)
        t[A_W] = _addr(sim.w, np.float64, dy.W_N)
        t[A_RING] = _addr(sim.ring, np.float64, RING_N * M_N)
        t[A_RING_COUNT] = _addr(sim.ring_count, np.int64, 1)
        t[A_RNG] = _addr(sim.rng_state, np.uint64, 1)
        t[A_MEAS_WORK] = _addr(sim.meas_work, np.float64, 8)
        t[A_MEAS] = _addr(sim.last_meas, np.float64, M_N)
        t[A_RX] = _addr(link._rx_np, np.uint8, 1)
        t[C_RX_N] = len(link._rx_np)
        t[A_TX] = _addr(link._out_np, np.uint8, SENSOR_FRAME_MAX_B)
        t[C_TX_N] = len(link._out_np)
        t[A_REC] = _addr(link._servo_rec, np.int64, SV_N)
        t[A_BLOCK] = _addr(writer.block, np.float64, writer.block_rows * TRUTH_N)
        t[C_BLOCK_ROWS] = writer.block_rows
        t[A_DISCARD] = _addr(writer._discard, np.float64, TRUTH_N)
        t[A_SA] = _addr(self._sa, np.uint8, SOCKADDR_IN_B)
        t[A_SALEN] = _addr(self._salen, np.uint32, 1)
        t[A_PEER] = _addr(self._peer, np.uint8, SOCKADDR_IN_B)
        t[A_F] = _addr(self.f, np.float64, F_N)
        self._pollfd = np.zeros(POLLFD_B, np.uint8)       # {int fd; short events, revents}
        self._pollfd[0:4] = np.frombuffer(int(link.sock.fileno()).to_bytes(4, sys.byteorder),
                                          np.uint8)
        self._pollfd[4:6] = np.frombuffer(_POLLIN.to_bytes(2, sys.byteorder), np.uint8)
        t[A_POLLFD] = _addr(self._pollfd, np.uint8, POLLFD_B)
        t[C_N_SUB] = sim.n_sub
        t[C_FD] = link.sock.fileno()
        mav = link.mav
        t[C_SYSID], t[C_COMPID], t[C_FC_SYSID] = mav.srcSystem, mav.srcComponent, link.fc_sysid
        t[C_FULL_ROWS] = -1 if writer.full_rows is None else writer.full_rows
        t[C_EVERY] = writer.every
        pwm = link.pwm
        self.f[:] = (pwm.pwm_trim, pwm.pwm_min, pwm.pwm_max, pwm._up, pwm._down, thr_scale,
                     sim.frame_dt_s)
        self.addr = int(t.__array_interface__["data"][0])

    def enter(self) -> None:
        """The Python objects' sequence, send length and truth counts into the table."""
        t, w, link = self.table, self.writer, self.link
        t[C_SEQ] = link.mav.seq
        t[C_OUT_LEN] = link._out_len
        t[C_T_OFFERED], t[C_T_FILL], t[C_T_ROWS], t[C_T_DECIMATED] = (
            w.offered, w.fill, w.rows, w.decimated)
        t[C_THR_SET] = 0
        t[C_STAMP] = -1
        for i in _COUNTS:
            t[i] = 0

    def leave(self) -> None:
        """The table back into the Python objects (sequence, send length, truth counts, the
        link's and the sim's counters, the last applied command); the counts zeroed."""
        t, w, link, sim = self.table, self.writer, self.link, self.sim
        v = t.tolist()
        link.mav.seq = v[C_SEQ]
        link._out_len = v[C_OUT_LEN]
        w.offered, w.fill, w.rows, w.decimated = (v[C_T_OFFERED], v[C_T_FILL], v[C_T_ROWS],
                                                  v[C_T_DECIMATED])
        sim.frames += v[C_FRAMES]
        sim.clip_frames += v[C_CLIPS]
        link.frames_sent += v[C_SENT]
        link.rx_datagrams += v[C_RX]
        link.rejected_source += v[C_SOURCE]
        link.rejected_sysid += v[C_SYSID_REJ]
        link.cmd_count += v[C_ACCEPTED]
        link.applied_count += v[C_APPLIED]
        link.rejected_malformed += v[C_MALFORMED]
        x = sim.x
        link.cmd_rad[:] = x[dy.X_CMD_L:dy.X_CMD_L + 3].tolist()
        if v[C_THR_SET]:
            link.cmd_throttle = float(x[dy.X_CMD_THR])
        if v[C_STAMP] >= 0:
            link.cmd_stamp_u32 = v[C_STAMP]
        for i in _COUNTS:
            t[i] = 0
        t[C_THR_SET] = 0
        t[C_STAMP] = -1

    def flush_truth(self) -> None:
        """The truth block is full (``B_FLUSH``): write it (TruthWriter.flush) and restart it."""
        t, w = self.table, self.writer
        w.fill = int(t[C_T_FILL])
        w.flush()
        t[C_T_FILL] = w.fill

    def set_rx_len(self, n: int) -> None:
        """Say that the receive buffer holds an ``n``-byte datagram (``MODE_DECODE`` without
        ``MODE_RECV``: benchmarks, replays)."""
        self.table[C_RX_LEN] = n

    def rx_len(self) -> int:
        """Length of the datagram the last receive put in the link's receive buffer."""
        return int(self.table[C_RX_LEN])
