"""fc/fused.py - one compiled call per lockstep frame in the common case (issue 24).

After ``PlantLink.read_frame_at`` has decoded a frame into the intake's ``scratch`` and left its
stamp in the link's int64 cell, :func:`frame_step_p` does in one compiled call what
``RunLoops.lockstep_frame_at`` does through about eight compiled calls and the Python between
them: the intake's stamp verdict (``intake_p``), the estimator (``accept_entry``), the tick
planner (``_due_at_p``, ``_slow_due_p``), per due tick the law's slow and fast kernels
(``slow_entry``, ``fast_entry``), the failsafe hold's running trim (``SurfaceHold.update``)
and the surfaces' PWM (``surfaces_pwm``), the SERVO_OUTPUT_RAW framed and sent (libc
``sendto``), and the internals-log row (``_keep_at_p``, ``_take_row_p``, ``fill_row_p``).
The same kernels on the same memory in the same order: the same results.

Its arguments are the address of one int64 context array (``C_*`` cells: the parts' array
addresses and constants, bound once by :class:`FusedFrame`; ``F_*`` cells are float64 in the
same buffer), the frame's arrival time (wall clock, s: the row's ``wall_s``) and the answer's
sequence number: three arguments to unbox per frame.

:meth:`FusedFrame.ready` says in Python whether the frame may take this path. In a guidance mode
(CRUISE, GUIDED, MISSION, RTL, the guidance engaged) the step flies the guidance's command and
throttle on the ticks where the guidance is not due (its count stepped in its int64 cell); a
frame with a guidance step due on one of its ticks is taken (intake, estimator, planner) and
its ticks, answer and row are left to Python (FUSED_TICKS): the guidance step, CRUISE's course
and the navigators stay Python's, on one frame in ``div`` (10 at 500 Hz). Everything else
takes the unfused path, unchanged: a guidance mode whose guidance is not engaged, FAILSAFE
while armed (the hold's trim), a mode change to act on (``modes.changes`` not yet seen by
``ModeControl``), the law's reset pending, plant data lost (its recovery is bookkeeping in
Python), a command of the timeline due at this frame, a stamp or deadline beyond the int64 cells, a law other than the
built-in ``fc.control`` one, the answer not sent by libc (no ``FAST_IO``: NUMBA_DISABLE_JIT, or
a socket that is not plain IPv4), or a law without a status record. A law fault cannot happen
on this path: the built-in law's kernels are compiled without bounds checks and with numpy's
error model, so they raise nothing (a NaN flies as it does today); with NUMBA_BOUNDSCHECK on the
path is off (an IndexError must reach ``_fast_tick``'s handler). The compiled call returns a
code: a duplicate, a late frame or a restart (the intake's verdicts) leave everything after the
verdict to Python, which then does exactly what ``take_at`` does after it; ROW_SLOW leaves the
row to ``Telemetry.log_row_at``'s chunk hand-over (a full chunk, or none free).
"""
from __future__ import annotations

import math

import numpy as np
from numba import carray, njit, types
from numba.core import config as _numba_config

import fc.control as _fc_control
import fc.estimator as _estimator
import fc.frame_calls as _frame_calls
import fc.internals_log as _internals_log
import fc.scheduler as _scheduler
import fc.telemetry as _telemetry
import hyfc_wire.frame_kernels as _frame_kernels
import hyfc_wire.layout as _wire_layout
import hyfc_wire.pwm as _pwm
import hyfc_wire.codec as _codec
from fc.control import kernels as _K
from fc.control.carrays import address_of, f8p, i8p
from fc.control.kernels import MEM_DELTA, fast_entry, slow_entry
from fc.control.layout import E_N
from fc.estimator import EM_EST, EM_N, accept_entry
from fc.frame_calls import (FAST_IO, INTAKE_NEW, RX_FRAME, _send_servo, intake_p,
                            recv_sensor_p)
from fc.internals_log import CUR_DECIMATED, _count_p, _keep_at_p, _take_row_p
from fc.link import M_N, M_T_S, MAX_DATAGRAM_B, SERVO_FRAME_MAX_B
from fc.mode_control import HOLD_FLOWN, HOLD_N
from fc.modes import FlightMode
from fc.scheduler import _due_at_p, _slow_due_p
from fc.telemetry import fill_row_p
from hyfc_wire.frame_kernels import GR_N, GR_PRESENT, surfaces_pwm, throttle_pwm
from hyfc_wire.numba_cache import drop_stale

__all__ = ["EXCHANGE_DONE", "EXCHANGE_VERDICT", "FusedFrame", "frame_step_p", "frame_rx_step_p",
           "FUSED_RX", "FUSED_DONE", "FUSED_HEALTHY", "FUSED_SEND_FAILED", "FUSED_TICKED",
           "FUSED_ROW_SLOW", "FUSED_TICKS", "FUSED_VERDICT"]

# numba's cache checks only this file: the step inlines the kernels of all these
_law_files = [str(p) for p in __import__("pathlib").Path(_fc_control.__file__).parent.glob("*.py")]
drop_stale(__file__, _law_files + [_estimator.__file__, _frame_calls.__file__,
                                   _internals_log.__file__, _scheduler.__file__,
                                   _telemetry.__file__, _frame_kernels.__file__,
                                   _wire_layout.__file__, _pwm.__file__, _codec.__file__])

# ---- the context (int64 cells; F_* are float64 cells of the same buffer)
C_STAMP = 0             # address of the frame's stamp cell (PlantLink.stamp_cell_at, us)
C_INTAKE = 1            # the intake's int64[IN_N] (FrameIntake._st)
C_LATE_WIN = 2          # the intake's late window (us)
C_SCRATCH = 3           # float64[M_N] the decoded frame (FrameIntake.scratch)
C_MEAS = 4              # float64[M_N] meas
C_EMEM = 5              # float64[EM_N] the estimator's buffer
C_PLANNER = 6           # the tick planner's int64 state
C_PERIOD_NS = 7         # fast period (ns)
C_MAX_CATCHUP = 8       # the planner's catch-up limit (ticks)
C_RATIO = 9             # fast ticks per slow tick
C_LAW_MEM = 10          # float64[law mem] the law's packed buffer (kernels.MEM_*)
C_LAW_MEM_N = 11        # its length
C_CMD = 12              # float64[3] the attitude command (ProcessSettings.cmd_rad, rad)
C_HOLD = 13             # float64[HOLD_N] the failsafe hold's cells (SurfaceHold.cells)
C_TRIM = 14             # float64[3] TRIM_* (rad): the surfaces when the law is not active
C_DELTA = 15            # float64[3] TickOutput.delta_rad (rad)
C_PWM = 16              # int64[4] TickOutput.pwm_us (us)
C_FD = 17               # the plant socket's descriptor
C_TX = 18               # uint8[SERVO_FRAME_MAX_B] the answer's buffer
C_SYSID = 19
C_COMPID = 20
C_PEER = 21             # uint8[16] the plant's sockaddr_in
C_HOT = 22              # int64[HOT_N] LinkCounters.hot
C_LAW_ON = 23           # 1: the law flies (law_active), 0: the surfaces at TRIM_*
C_MODE = 24             # the flight mode (int), logged
C_ARMED = 25            # 1 armed, logged
C_ROW_CMD = 26          # float64[3] the command the row logs (TickOutput.cmd_active)
C_TGT = 27              # float64[3] the guidance's targets (telemetry's copy)
C_STATUS = 28           # float64[] the law's status
C_DIMS = 29             # int64[3] the row's dims (telemetry)
C_KS = 30               # int64[KS_N] the internals log's decimation state
C_FULL_ON = 31          # 1: rows decimated after the full-rate span
C_FULL_US = 32          # the full-rate span (us)
C_TAIL_US = 33          # the tail's row period (us)
C_CURSOR = 34           # int64[CUR_N] the internals log's row cursor
C_CHUNK = 35            # float64[rows, ncol] the chunk being filled (0: none)
C_CHUNK_ROWS = 36       # rows per chunk
C_TS = 37               # 2 cells: a struct timespec for clock_gettime
F_SLOW_DT = 39          # slow period (s)
F_FAST_DT = 40          # fast period (s)
F_TAU = 41              # the hold's time constant (s)
F_LIMITS = 42           # the guidance's limit bits, logged (as the float the row takes)
C_FUSED_N = 43          # frames the step took all the way (fc.log at exit)
C_RX = 44               # uint8[C_RX_N] the link's receive buffer
C_RX_N = 45
C_SA = 46               # uint8[16] the last datagram's source (sockaddr_in)
C_SALEN = 47            # uint32[1] its length
C_PLANT_SYSID = 48
C_GPS = 49              # float64[GR_N] the frame's raw GPS_INPUT fields
C_IO = 50               # int64[IO_N] the receive's length and stamp
F_TL_NEXT = 51          # sensor time of the timeline's next command (s; inf: none)
F_NOW = 52              # frame_rx_step_p: the frame's arrival (CLOCK_MONOTONIC, s)
C_GUID = 53             # 1: the guidance flies (a guidance mode, engaged): its command, throttle
C_GCOUNT = 54           # int64[1] the guidance's tick count (GuidanceRunner.count)
C_GDIV = 55             # fast ticks per guidance step (GuidanceRunner.div)
C_THR = 56              # float64 the guidance's throttle command, 0..1 (its out[GO_THR])
C_TICKS = 57            # FUSED_TICKS: the ticks the planner made due, to run unfused
C_N = 58

# ---- frame_step_p's code: the intake's verdict in the low bits, flags above
FUSED_VERDICT = 0xF     # INTAKE_DUPLICATE / _LATE / _RESTART: nothing done after the verdict
FUSED_DONE = 0          # the frame went all the way (verdict INTAKE_NEW)
#: (in the verdict's bits) the frame taken (intake, estimator, planner) but a guidance step is
#: due on one of its ticks: the C_TICKS ticks, the answer and the row are left to Python
FUSED_TICKS = 0x8
FUSED_HEALTHY = 0x10    # the estimator's verdict (Estimator.healthy)
FUSED_SEND_FAILED = 0x20  # sendto failed (counted in Python: endpoint.send_errors)
FUSED_TICKED = 0x40     # at least one fast tick ran
FUSED_ROW_SLOW = 0x80   # the row kept but not taken: the chunk is full or none is free
#: frame_rx_step_p: the receive's code + 8 in the low byte (``RX_*``), nothing stepped: not
#: a frame from the locked peer, a big stamp, or a frame to take unfused (RX_FRAME: a GNSS
#: sample in it, or a command of the timeline due)
FUSED_RX = 0x100

_CLOCK_MONOTONIC = 1    # Linux (time.perf_counter's clock)
_clock_gettime = types.ExternalFunction("clock_gettime", types.intc(
    types.intc, types.CPointer(types.int64)))


@njit(cache=True, inline="always")
def _now_ns(ts):
    _clock_gettime(_CLOCK_MONOTONIC, i8p(ts))
    t = carray(i8p(ts), (2,))
    return t[0] * 1_000_000_000 + t[1]


@njit(cache=True, error_model="numpy")
def frame_step_p(ctx, now_s, seq):
    """The lockstep frame at the context ``ctx`` (int64[C_N] by address, module docstring),
    arrived at ``now_s`` (wall clock, s), answered with sequence number ``seq``. Returns the
    intake's verdict when it is not INTAKE_NEW (nothing else done), else FUSED_DONE with the
    FUSED_* flags."""
    return _frame_step(ctx, now_s, seq, _now_ns(ctx + 8 * C_TS))


@njit(cache=True, error_model="numpy")
def frame_rx_step_p(ctx, seq):
    """:func:`frame_step_p` from the receive: one datagram from the plant socket
    (``recv_sensor_p``, libc ``recvfrom``, counted there), and when it is a frame of the
    locked peer with no GNSS sample and no timeline command due, its step, arrived now (its
    time in ``F_NOW``, s, as ``time.monotonic`` gives it). Otherwise FUSED_RX with the
    receive's code (module docstring)."""
    c = carray(i8p(ctx), (C_N,))
    f = carray(f8p(ctx), (C_N,))
    t0 = _now_ns(ctx + 8 * C_TS)
    rx = recv_sensor_p(c[C_FD], c[C_RX], c[C_RX_N], c[C_SA], c[C_SALEN], c[C_PEER], True,
                       c[C_PLANT_SYSID], c[C_SCRATCH], M_N, c[C_GPS], GR_N, c[C_HOT], c[C_IO])
    if rx != RX_FRAME:
        return FUSED_RX | (rx + 8)
    t = _now_ns(ctx + 8 * C_TS)
    # time.monotonic's conversion (CPython _PyTime_AsSecondsDouble)
    now_s = np.float64(t // 1_000_000_000) if t % 1_000_000_000 == 0 else np.float64(t) / 1e9
    f[F_NOW] = now_s
    if carray(f8p(c[C_GPS]), (GR_N,))[GR_PRESENT] != 0.0 \
            or carray(f8p(c[C_SCRATCH]), (M_N,))[M_T_S] + 1e-9 >= f[F_TL_NEXT]:
        return FUSED_RX | (RX_FRAME + 8)
    return _frame_step(ctx, now_s, seq, t0)


@njit(cache=True, error_model="numpy")
def _frame_step(ctx, now_s, seq, t0):
    c = carray(i8p(ctx), (C_N,))
    f = carray(f8p(ctx), (C_N,))
    stamp_at = c[C_STAMP]
    verdict = intake_p(stamp_at, c[C_INTAKE], c[C_LATE_WIN])
    if verdict != INTAKE_NEW:
        return verdict
    meas = carray(f8p(c[C_MEAS]), (M_N,))
    emem = carray(f8p(c[C_EMEM]), (EM_N,))
    healthy = accept_entry(carray(f8p(c[C_SCRATCH]), (M_N,)), meas, emem)
    n = _due_at_p(c[C_PLANNER], stamp_at, c[C_PERIOD_NS], c[C_MAX_CATCHUP])
    guid = c[C_GUID] != 0
    if guid and n > 0:
        # the guidance steps on a tick that starts with its count at 0 (GuidanceRunner.tick):
        # none of this frame's n ticks may (else Python flies them: its navigators and
        # CRUISE's course run before the step); their counts stepped as tick() steps them
        gcount = carray(i8p(c[C_GCOUNT]), (1,))
        c0 = gcount[0]
        if c0 == 0 or c0 + n > c[C_GDIV]:
            c[C_TICKS] = n
            return FUSED_TICKS | FUSED_HEALTHY if healthy else FUSED_TICKS
        gcount[0] = c0 + n if c0 + n < c[C_GDIV] else 0
    thr_pwm = throttle_pwm(carray(f8p(c[C_THR]), (1,))[0]) if guid else 0
    est = emem[EM_EST:EM_EST + E_N]
    mem = carray(f8p(c[C_LAW_MEM]), (c[C_LAW_MEM_N],))
    cmd = carray(f8p(c[C_CMD]), (3,))
    hold = carray(f8p(c[C_HOLD]), (HOLD_N,))
    delta = carray(f8p(c[C_DELTA]), (3,))
    pwm = carray(i8p(c[C_PWM]), (4,))
    law_on = c[C_LAW_ON] != 0
    slow_dt = f[F_SLOW_DT]
    fast_dt = f[F_FAST_DT]
    k = n
    while k:
        slow = _slow_due_p(c[C_PLANNER], c[C_RATIO])
        if law_on:
            # FlightController._fast_tick: the law, its fresh command into the hold, the PWM
            if slow:
                slow_entry(est, cmd, slow_dt, mem)
            fast_entry(est, fast_dt, mem)
            src = mem[MEM_DELTA:MEM_DELTA + 3]
            fl = hold[HOLD_FLOWN] + fast_dt             # SurfaceHold.update
            hold[HOLD_FLOWN] = fl
            tau = f[F_TAU]
            g = fast_dt / (tau if tau < fl else fl)
            for i in range(3):
                hold[i] += g * (src[i] - hold[i])
            surfaces_pwm(src, delta, thr_pwm, pwm)
        else:
            surfaces_pwm(carray(f8p(c[C_TRIM]), (3,)), delta, 0, pwm)
        k -= 1
    c[C_FUSED_N] += 1
    code = FUSED_DONE
    if healthy:
        code |= FUSED_HEALTHY
    t = carray(i8p(stamp_at), (1,))[0] & 0xFFFFFFFF
    if not _send_servo(c[C_FD], c[C_TX], SERVO_FRAME_MAX_B, seq, c[C_SYSID], c[C_COMPID], t,
                       c[C_PWM], c[C_PEER], c[C_HOT]):
        code |= FUSED_SEND_FAILED
    if n == 0:
        return code
    code |= FUSED_TICKED
    if c[C_FULL_ON] != 0 and not _keep_at_p(c[C_KS], stamp_at, c[C_FULL_US], c[C_TAIL_US]):
        _count_p(c[C_CURSOR], CUR_DECIMATED)
        return code
    if c[C_CHUNK] == 0 or not _take_row_p(c[C_CURSOR], c[C_CHUNK_ROWS]):
        return code | FUSED_ROW_SLOW
    exec_ns = np.float64(_now_ns(ctx + 8 * C_TS) - t0)
    fill_row_p(c[C_CHUNK], c[C_CURSOR], c[C_DIMS], c[C_MEAS], now_s, 0.0, stamp_at,
               c[C_MODE], c[C_ARMED] != 0, healthy, c[C_EMEM], c[C_ROW_CMD], c[C_DELTA], 0.0,
               exec_ns, c[C_STATUS], carray(f8p(c[C_THR]), (1,))[0] if guid else math.nan,
               f[F_LIMITS], c[C_TGT])
    return code


_FAILSAFE = FlightMode.FAILSAFE
_INF = math.inf
#: FusedFrame.exchange's codes beside read_frame_at's (FRAME_AT, FRAME_BIG, FRAME_NONE): the
#: frame answered; this plus the intake's verdict
EXCHANGE_DONE = 8
EXCHANGE_VERDICT = 16


class FusedFrame:
    """The fused lockstep frame of one FlightController (module docstring): the context built
    once, :meth:`ready` per frame, :meth:`step` to run it and finish what stays in Python."""

    def __init__(self, fc) -> None:
        from fc.control.law import AttitudeLaw      # (the built-in law only)
        self.fc = fc
        self.ctx = np.zeros(C_N, np.int64)
        self.ctx_f = self.ctx.view(np.float64)
        self.ctx_p = address_of(self.ctx, np.int64, C_N)
        #: whether this controller can take the fused path at all (module docstring)
        self.enabled = bool(
            FAST_IO and not _numba_config.BOUNDSCHECK and fc.cfg.mode == "lockstep"
            and type(fc.law) is AttitudeLaw and fc.plant._fast_io and fc.telemetry._status is not None)
        self._changes = -1          # modes.changes the mode cells were written for
        self._mode_ok = False       # the mode (at _changes) flies the fused path
        self._law_on = False
        self._guid = False          # the guidance flies (the context's C_GUID)
        self._chunk = None          # the ilog.chunk whose address the context holds
        if not self.enabled:
            return
        c = self.ctx
        intake, plant, planner, law, est = fc.intake, fc.plant, fc.planner, fc.law, fc.est
        tel, ilog = fc.telemetry, fc.ilog
        c[C_STAMP] = plant.stamp_cell_at
        c[C_INTAKE] = intake._st_p
        c[C_LATE_WIN] = intake.late_window_us
        c[C_SCRATCH] = address_of(intake.scratch, np.float64, M_N)
        c[C_MEAS] = address_of(intake.meas, np.float64, M_N)
        c[C_EMEM] = address_of(est.mem, np.float64, EM_N)
        c[C_PLANNER] = planner._st_p
        c[C_PERIOD_NS] = planner.period_ns
        c[C_MAX_CATCHUP] = planner.max_catchup
        c[C_RATIO] = planner.ratio
        c[C_LAW_MEM] = law._mem_p
        c[C_LAW_MEM_N] = law._mem_n
        c[C_CMD] = address_of(fc.settings.cmd_rad, np.float64, 3)
        c[C_HOLD] = address_of(fc.mode_ctl.hold.cells, np.float64, HOLD_N)
        c[C_TRIM] = address_of(fc.settings.trim_rad, np.float64, 3)
        c[C_DELTA] = address_of(fc.out.delta_rad, np.float64, 3)
        c[C_PWM] = address_of(fc.out.pwm_us, np.int64, 4)
        c[C_FD] = plant._fd
        c[C_TX] = plant._tx_addr
        c[C_SYSID] = plant.sysid
        c[C_COMPID] = plant.compid
        c[C_PEER] = plant._peer_sa_addr
        self._hot = plant.counters.hot
        c[C_HOT] = address_of(self._hot, np.int64, self._hot.size)
        c[C_RX] = plant._rx_addr
        c[C_RX_N] = MAX_DATAGRAM_B
        c[C_SA] = plant._sa_addr
        c[C_SALEN] = plant._salen_addr
        c[C_PLANT_SYSID] = plant.plant_sysid
        c[C_GPS] = plant._gps_raw_addr
        c[C_IO] = plant._io_addr
        c[C_TGT] = tel._tgt_p
        c[C_STATUS] = tel._status_p
        c[C_DIMS] = tel._dims_p
        c[C_KS] = ilog._ks_p
        c[C_FULL_ON] = 0 if ilog._full_us is None else 1
        c[C_FULL_US] = ilog._full_us or 0
        c[C_TAIL_US] = ilog._tail_us
        c[C_CURSOR] = ilog.cursor_address
        c[C_CHUNK_ROWS] = ilog._chunk_rows
        guid = fc.guid
        c[C_GCOUNT] = guid.count_addr
        c[C_GDIV] = guid.div
        c[C_THR] = guid.throttle_addr
        f = self.ctx_f
        f[F_SLOW_DT] = planner.slow_dt_s
        f[F_FAST_DT] = planner.fast_dt_s
        f[F_TAU] = fc.mode_ctl.hold.tau_s
        # the step loaded now (from numba's cache), not in the first frame: on a spare context
        # whose stamp cell is its own intake state (a repeat), so it returns at the verdict
        spare = np.zeros(C_N, np.int64)
        st = np.zeros(2, np.int64)            # IN_LAST = IN_STAMP = 0: stamp 0 is a repeat
        spare[C_STAMP] = address_of(st, np.int64, 2)
        spare[C_INTAKE] = spare[C_STAMP]
        frame_step_p(address_of(spare, np.int64, C_N), 0.0, 0)
        # the receive's entry too: on a spare socket with nothing waiting (RX_NONE, counted in
        # a spare counter array)
        import socket
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.bind(("127.0.0.1", 0))
            spare_hot = np.zeros(self._hot.size, np.int64)
            spare[:] = c
            spare[C_FD] = sock.fileno()
            spare[C_HOT] = address_of(spare_hot, np.int64, spare_hot.size)
            frame_rx_step_p(address_of(spare, np.int64, C_N), 0)

    @property
    def ticks(self) -> int:
        """FUSED_TICKS: the fast ticks the planner made due for the frame, to run unfused."""
        return self.ctx.item(C_TICKS)

    @property
    def frames(self) -> int:
        """Frames the fused step took all the way (verdict INTAKE_NEW)."""
        return self.ctx.item(C_FUSED_N)

    def _refresh_mode(self) -> None:
        """The mode cells for ``modes.changes`` (a mode or arming change since the last)."""
        fc = self.fc
        modes = fc.modes
        self._changes = modes.changes
        self._law_on = modes.law_active
        self._mode_ok = not (modes.armed and modes.mode == _FAILSAFE)
        c = self.ctx
        c[C_LAW_ON] = 1 if self._law_on else 0
        c[C_MODE] = int(modes.mode)
        c[C_ARMED] = 1 if modes.armed else 0
        self._set_guidance(fc.guid.engaged)

    def _set_guidance(self, engaged: bool) -> None:
        """The cells that depend on whether the guidance flies (``engaged`` in a guidance mode;
        ``_ready`` takes the unfused path while a guidance mode flies without it, or it flies
        outside one): the law's command and the row's (``_fast_tick``: the guidance's, else
        CMD_* while the law flies, else whatever the last tick left), the throttle."""
        fc = self.fc
        self._guid = engaged
        c = self.ctx
        c[C_GUID] = 1 if engaged else 0
        law_cmd = fc.guid.cmd_rad if engaged else fc.settings.cmd_rad
        c[C_CMD] = address_of(law_cmd, np.float64, 3)
        cmd = law_cmd if self._law_on else fc.out.cmd_active
        c[C_ROW_CMD] = address_of(cmd, np.float64, 3)
        self.ctx_f[F_LIMITS] = float(fc.guid.limits)

    def ready(self) -> bool:
        """Whether the frame ``read_frame_at`` just answered FRAME_AT for may take
        :meth:`step` (module docstring); False: the unfused path."""
        if not self._ready():
            return False
        tl = self.fc.intake.timeline
        return tl is None or tl.next >= len(tl.commands) \
            or tl.commands[tl.next].t_s > self.fc.meas_scratch.item(M_T_S) + 1e-9
        # (a command due at this frame: Timeline.due's test)

    def ready_rx(self) -> bool:
        """Whether the next plant datagram may be read by :meth:`exchange` (module docstring;
        the timeline's test is the compiled step's, on the frame)."""
        if not self._ready() or self.fc.plant.endpoint.stamped:
            return False
        tl = self.fc.intake.timeline
        self.ctx_f[F_TL_NEXT] = _INF if tl is None or tl.next >= len(tl.commands) \
            else tl.commands[tl.next].t_s
        return True

    def _ready(self) -> bool:
        if not self.enabled:
            return False
        fc = self.fc
        modes = fc.modes
        mc = fc.mode_ctl
        if modes.changes != self._changes:
            self._refresh_mode()
        if not self._mode_ok or modes.changes != mc.changes_seen or mc.reset_pending \
                or modes.data_lost:
            return False
        plant = fc.plant
        if fc.intake._big is not None or fc.planner._big_next is not None \
                or fc.ilog._ks_big is not None or plant.peer is None \
                or plant.peer is not plant._peer_sa_of or plant.counters.hot is not self._hot:
            return False
        guid = fc.guid
        if guid.engaged != modes.guidance_active:
            return False                # (a guidance mode not engaged yet, or the reverse)
        if guid.engaged != self._guid:
            self._set_guidance(guid.engaged)
        if self._guid:
            self.ctx_f[F_LIMITS] = guid.limits          # (stepped by the last guidance step)
        ilog = fc.ilog
        chunk = ilog.chunk              # (a new chunk after a hand-over, or None: none free)
        if chunk is not self._chunk:
            self._chunk = chunk
            self.ctx[C_CHUNK] = 0 if chunk is None else ilog.chunk_address
        return True

    def step(self, now_s: float, t_exec: float, perf_counter) -> int:
        """The fused frame arrived at ``now_s`` (wall clock, s); ``t_exec`` the
        ``perf_counter`` reading the exchange started at (the row's exec time when the row
        falls back). Returns the intake's verdict when it is not INTAKE_NEW (the caller takes
        the unfused path from the verdict on), FUSED_TICKS (the frame taken, a guidance step
        due: the caller runs the :attr:`ticks` ticks, the answer and the row), else
        FUSED_DONE."""
        code = frame_step_p(self.ctx_p, now_s, self.fc.plant._tx_codec.seq)
        return self._finish(code, now_s, t_exec, perf_counter)

    def exchange(self, t_exec: float, perf_counter) -> int:
        """The next plant datagram read and, when it may be, stepped in one compiled call
        (:func:`frame_rx_step_p`). Returns EXCHANGE_DONE (answered), FRAME_NONE (no frame: read
        as ``read_frame_at`` reads), FRAME_AT or FRAME_BIG (``read_frame_at``'s codes: a frame
        read, to take unfused) or EXCHANGE_VERDICT + the intake's verdict (the unfused path
        from the verdict on; + FUSED_TICKS: the ticks on, as :meth:`step`)."""
        plant = self.fc.plant
        code = frame_rx_step_p(self.ctx_p, plant._tx_codec.seq)
        if code & FUSED_RX:
            return plant.read_frame_after((code & 0xFF) - 8, self.fc.meas_scratch)
        plant.frame_rx_ns = plant.endpoint.rx_ns        # (read_frame_at's bookkeeping)
        plant.ended = False
        v = self._finish(code, self.ctx_f.item(F_NOW), t_exec, perf_counter)
        return EXCHANGE_DONE if v == FUSED_DONE else EXCHANGE_VERDICT + v

    def _finish(self, code: int, now_s: float, t_exec: float, perf_counter) -> int:
        """After the compiled step's ``code``: the Python state the unfused path keeps beside
        the compiled one; the verdict (not INTAKE_NEW) or FUSED_DONE."""
        v = code & FUSED_VERDICT
        if v and v != FUSED_TICKS:
            return v
        fc = self.fc
        plant = fc.plant
        fc.est.healthy = code & FUSED_HEALTHY != 0
        intake = fc.intake
        fc.mode_ctl.on_frame(now_s, intake.meas.item(M_T_S))   # (bookkeeping only here)
        if v:
            return FUSED_TICKS          # (the ticks, the answer and the row: Python's)
        if code & FUSED_TICKED and self._law_on:
            fc.out.cmd_active = fc.guid.cmd_rad if self._guid else fc.settings.cmd_rad
        plant._sent(code & FUSED_SEND_FAILED == 0)
        if code & FUSED_ROW_SLOW:
            ilog = fc.ilog
            if ilog._next_row():
                fc.telemetry._fill_p(ilog, intake.meas, 0.0, plant.stamp_cell_at, 0,
                                     (perf_counter() - t_exec) * 1e9, now_s)
        return FUSED_DONE
