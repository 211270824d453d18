"""fc/telemetry.py - the flight controller's telemetry snapshot and internals-log rows.

One part of the flight controller (docs/architecture.md, the fc's parts). It reads the other
parts (estimator, modes, plant link, ground-station link counters, loop statistics, law,
guidance) and the newest tick's output (:class:`TickOutput`), and builds what the ground
station gets (NAMED_VALUE_FLOAT, DEBUG_VECT, SYS_STATUS counts, VFR_HUD throttle,
NAV_CONTROLLER_OUTPUT) and the rows of the internals log (fc/internals_log.py). It changes
nothing it reads.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import carray, njit

import fc.control.carrays as _carrays
import fc.estimator as _estimator
import fc.guidance.layout as _guid_layout
import hyfc_wire.layout as _wire_layout
from fc.control.carrays import ArrayAddress, address_of, f8p, i8p
from fc.estimator import E_N, EM_EST, EM_MASKS, EM_N, Estimator
from fc.gcs import GcsLink
from fc.gcs_frames import (DV_CMD, DV_DELTA, DV_EST, DV_GUID, NV_NAME_B, debug_vect_p,
                           named_value_p, nav_output_p)
from fc.guidance.layout import GS_GAM_C, GS_N, TG_N
from fc.guided import GuidanceRunner
from fc.frame_calls import copy_p, int64_at
from fc.internals_log import InternalsLog
from fc.link import M_N, M_T_S, PlantLink
from fc.modes import ModeManager
from fc.scheduler import FrameGate, LoopStats, TickPlanner
from hyfc_wire.numba_cache import drop_stale

__all__ = ["EST_COLS", "FcCounters", "TickOutput", "Telemetry"]

#: the named values (NAMED_VALUE_FLOAT, ``Telemetry.refresh``) before the law's status
_NV_NAMES = (b"GAMMA_DEG", b"LATE_P99", b"LATE_MAX", b"LATE_CNT", b"OVERRUN", b"SKIPPED",
             b"TICK_FALLB", b"GC_US", b"REJ_PLANT", b"GNSS_DROP", b"REJ_GCS", b"REJ_SIGN",
             b"EST_INVAL", b"EST_FLAGS", b"FS_CAUSE", b"DUP_FRAMES", b"FC_STALLS")
_NV_FIXED = len(_NV_NAMES)

EST_COLS = ("alpha_rad", "beta_rad", "mu_rad", "p_rad_s", "q_rad_s", "r_rad_s", "V_m_s",
            "h_m", "gamma_rad")


# fill_row(_p) freeze the estimator's EM_*, the layouts' indices and the address views
drop_stale(__file__, [_estimator.__file__, _carrays.__file__, _wire_layout.__file__,
                      _guid_layout.__file__])


@njit(cache=True)
def fill_row(r, meas, wall_s, stamp_us, mode, armed, healthy, emem, cmd, delta,
             lateness_ns, exec_ns, status, n_status, throttle, limits, tgt):
    """One internals-log row (the columns of :meth:`Telemetry.columns`, in order) into ``r``
    (float64[ncol]) in one compiled call: meas the frame (fc/link.py M_*; its time is
    logged), emem the estimator's buffer (``Estimator.mem``, layout EM_*: the state and the
    invalid/stale masks), cmd/delta float64[3] (rad), status float64[>= n_status] (the law's), tgt float64[>= 3] (the
    guidance's targets); lateness and execution time in ns, logged in us."""
    masks = emem.view(np.int64)[EM_MASKS:EM_MASKS + 2]
    r[0] = meas[M_T_S]
    r[1] = wall_s
    r[2] = stamp_us
    r[3] = np.float64(mode)
    r[4] = 1.0 if armed else 0.0
    r[5] = 1.0 if healthy else 0.0
    r[6] = np.float64(masks[0])
    r[7] = np.float64(masks[1])
    k = 8
    for i in range(E_N):
        r[k + i] = emem[EM_EST + i]
    k += E_N
    for i in range(3):
        r[k + i] = cmd[i]
        r[k + 3 + i] = delta[i]
    r[k + 6] = lateness_ns * 1e-3
    r[k + 7] = exec_ns * 1e-3
    k += 8
    for i in range(min(n_status, status.shape[0])):
        r[k + i] = status[i]
    k += n_status
    r[k] = throttle
    r[k + 1] = np.float64(limits)
    for i in range(3):
        r[k + 2 + i] = tgt[i]


@njit(cache=True)
def fill_row_p(chunk, cursor, dims, meas, wall_s, stamp_us, stamp_at, mode, armed, healthy,
               emem, cmd, delta, lateness_ns, exec_ns, status, throttle, limits, tgt):
    """:func:`fill_row` with its arrays given by address (fc/control/carrays.py): row
    ``cursor[1]`` (fc/internals_log.py ``CUR_ROW`` of the int64 cursor) of the float64[:, ncol]
    at ``chunk``, meas float64[M_N], emem float64[EM_N], cmd/delta/tgt
    float64[3], status float64[status_n]; ``dims`` int64[3] = (ncol, status_n, n_status). The
    stamp is the int64 cell at ``stamp_at`` (as a float) when ``stamp_at`` is not 0, else the
    float ``stamp_us``. (Fewer than 20 arguments: CPython takes the call's argument tuple from
    its free list.)"""
    if stamp_at != 0:
        stamp_us = np.float64(carray(i8p(stamp_at), (1,))[0])
    d = carray(i8p(dims), (3,))
    ncol, status_n, n_status = d[0], d[1], d[2]
    i = carray(i8p(cursor), (2,))[1]
    fill_row(carray(f8p(chunk + i * ncol * 8), (ncol,)), carray(f8p(meas), (M_N,)), wall_s, stamp_us, mode,
             armed, healthy, carray(f8p(emem), (EM_N,)), carray(f8p(cmd), (3,)),
             carray(f8p(delta), (3,)), lateness_ns, exec_ns, carray(f8p(status), (status_n,)),
             n_status, throttle, limits, carray(f8p(tgt), (3,)))


_NO_STATUS = np.zeros(0)


class _OneRow:
    """An internals log of one row (the row kernel's warm-up)."""

    def __init__(self, row: np.ndarray) -> None:
        self._row = row

    def row(self, stamp_us: int | None = None) -> np.ndarray:
        return self._row

    @property
    def chunk_address(self) -> int:
        return address_of(self._row, np.float64, self._row.size)

    @property
    def cursor_address(self) -> int:
        return address_of(_ROW_0, np.int64, 2)

    def take_row(self, stamp_us: int | None = None) -> bool:
        return True


_ROW_0 = np.zeros(2, np.int64)      # a cursor at row 0 (_OneRow's)


@dataclass
class TickOutput:
    """The newest fast tick's output."""

    cmd_active: np.ndarray                  # the law's command, rad: CMD_* or the guidance's
    delta_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))  # surfaces L, R, rudder
    #: servo1..4 [us] (int64[4], written in place by fc.link.pwm_map); servo4: throttle,
    #: 0 = no output
    pwm_us: np.ndarray = field(default_factory=lambda: np.array([1500, 1500, 1500, 0], np.int64))


@dataclass
class FcCounters:
    """Event counters of the process (fc.log at exit, NAMED_VALUE_FLOAT)."""

    duplicate_frames: int = 0       # plant frames repeated (re-requests, link duplicates)
    reordered_frames: int = 0       # real time: late plant frames (reordered), dropped
    plant_resets: int = 0           # plant time went backwards
    law_errors: int = 0             # the law raised (FAILSAFE)
    law_holds: int = 0              # real time: law not stepped on a frozen estimate
    fc_stalls: int = 0              # the fc's own loop stopped > FC_STALL_S (fc/loops.py)
    fc_stall_max_s: float = 0.0     # the longest of them, s (wall clock)
    gc_us: float = 0.0              # last 1 Hz garbage collection, us
    exec_ns_sum: float = 0.0        # tick execution time since the last load figure, ns
    exec_n: float = 0.0             # ticks timed since then (a float: no int object per tick)
    load_permille: int = 0          # SYS_STATUS.load

    def add_exec(self, ns: float) -> None:
        self.exec_ns_sum += ns
        self.exec_n += 1.0

    def roll_load(self, period_ns: int) -> None:
        """The 1 Hz load figure: mean tick execution time over the fast period."""
        if self.exec_n:
            self.load_permille = min(1000, int(1000 * self.exec_ns_sum / self.exec_n / period_ns))
        self.exec_ns_sum = self.exec_n = 0.0


@dataclass
class Telemetry:
    """Builds the telemetry the ground-station link sends and the internals-log rows."""

    out: TickOutput
    counters: FcCounters
    est: Estimator
    modes: ModeManager
    plant: PlantLink
    gcs: GcsLink                # its rejection counters
    stats: LoopStats
    planner: TickPlanner
    gate: FrameGate
    law: object                 # the injected law (fc/control AttitudeLaw or a stand-in)
    status_names: list
    guid: GuidanceRunner
    _nv_name_list: list = field(default_factory=list)   # the named values' names (refresh)
    #: the law's status record as the row kernel reads it: the law's own array, or None when
    #: that is not a contiguous float64 array (then converted per row); empty without one
    _status: np.ndarray | None = None
    _n_status: int = 0
    _emem: np.ndarray | None = None     # the estimator's buffer (state and masks)
    _delta: np.ndarray | None = None    # out.delta_rad
    _tgt: np.ndarray | None = None      # the guidance's targets
    # the DEBUG_VECTs' arrays by address (frame_debug_vector)
    _cmd_dv_at: ArrayAddress = field(default_factory=lambda: ArrayAddress(np.float64, 3))
    _est_dv_at: ArrayAddress = field(default_factory=lambda: ArrayAddress(np.float64, 3))
    _gstatus: np.ndarray | None = None
    _gstatus_mv: memoryview | None = None
    # NAV_CONTROLLER_OUTPUT's arrays by address (frame_nav_output)
    _gstatus_at: ArrayAddress = field(default_factory=lambda: ArrayAddress(np.float64, GS_N))
    _gtgt_at: ArrayAddress = field(default_factory=lambda: ArrayAddress(np.float64, TG_N))
    _est_at: ArrayAddress = field(default_factory=lambda: ArrayAddress(np.float64, E_N))
    # NAMED_VALUE_FLOAT's names (zero-padded, uint8[n, NV_NAME_B]) and values (float64[n]) as
    # of the last refresh(), for frame_named_value; their addresses
    _nv_names: np.ndarray = field(default_factory=lambda: np.zeros((0, NV_NAME_B), np.uint8))
    _nv_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    _nv_names_p: int = 0
    _nv_values_p: int = 0
    # the address of the law's status values in ``_nv_values`` (bound once: an address plus
    # an offset made an int at each refresh, issue 24)
    _nv_status_p: int = 0

    def __post_init__(self) -> None:
        st = getattr(self.law, "status", None) if self.status_names else _NO_STATUS
        ok = (isinstance(st, np.ndarray) and st.dtype == np.float64 and st.ndim == 1
              and st.flags.c_contiguous)
        self._status = st if ok else None
        self._n_status = len(self.status_names)
        self._emem = self.est.mem
        self._delta = self.out.delta_rad
        self._tgt = self.guid.g.tgt
        self._ncol = len(self.columns())
        self._meas_at = ArrayAddress(np.float64, M_N)
        self._cmd_at = ArrayAddress(np.float64, 3)
        self._emem_p = address_of(self._emem, np.float64, EM_N)
        self._delta_p = address_of(self._delta, np.float64, 3)
        self._tgt_p = address_of(self._tgt, np.float64, 3)
        self._status_p = address_of(st, np.float64, 0) if self._status is not None else 0
        # the row kernel's sizes: (columns, the law's status length, status columns logged)
        self._dims = np.array([self._ncol, st.size if self._status is not None else 0,
                               self._n_status], np.int64)
        self._dims_p = address_of(self._dims, np.int64, 3)
        # compile / load the row kernel now (the guidance's command array, which the tick
        # logs in its modes, is a contiguous float64[3] like the settings' one)
        row = np.zeros(len(self.columns()))
        self.log_row(_OneRow(row), np.zeros(M_N), 0, 0, 0, 0.0)
        copy_p(address_of(row, np.float64, 1), address_of(row, np.float64, 1), 0)  # (loaded)

    def skipped_ticks(self) -> int:
        """Fast deadlines skipped (overruns), whichever real-time schedule ran."""
        return self.planner.skipped + self.gate.skipped

    def error_counts(self) -> tuple[int, int, int, int, int]:
        return (self.gcs.rejected_bad + self.gcs.rejected_signing, self.plant.counters.rejected,
                self.est.invalid_frames, self.stats.overruns + self.skipped_ticks(),
                self.stats.late)

    def named_values(self) -> list:
        """NAMED_VALUE_FLOAT (name, value) pairs, as of the last :meth:`refresh` (1 Hz)."""
        return list(zip(self._nv_name_list, self._nv_values.tolist()))

    def refresh(self) -> None:
        """The NAMED_VALUE_FLOAT values of now (1 Hz), written into the array the compiled
        framing reads (``frame_named_value``) without a Python object (issue 24): values read
        as Python floats or small ints, the law's status copied by a compiled call.
        :meth:`named_values` gives the (name, value) pairs from it."""
        if not self._nv_name_list:
            self._init_named()
        v = self._nv_values
        c = self.plant.counters
        st = self.stats
        masks = self.est.masks
        v[0] = math.degrees(self.est.est.item(8))
        v[1] = st.window_p99_us
        v[2] = st.window_max_us
        v[3] = st.late
        v[4] = st.overruns
        v[5] = self.skipped_ticks()
        v[6] = self.gate.fallback_ticks
        v[7] = self.counters.gc_us
        v[8] = c.rejected
        v[9] = c.gnss_rejected
        v[10] = self.gcs.rejected_bad
        v[11] = self.gcs.rejected_signing
        v[12] = self.est.invalid_frames
        v[13] = masks.item(0) | masks.item(1)
        v[14] = self.modes.fs_cause
        v[15] = self.counters.duplicate_frames
        v[16] = self.counters.fc_stalls
        n = len(v) - _NV_FIXED
        if n:
            if self._status is not None:
                copy_p(self._nv_status_p, self._status_p, n)
            else:
                for i in range(n):
                    v[_NV_FIXED + i] = float(self.law.status[i])

    def _init_named(self) -> None:
        """The names of the named values (fixed: the law's status names, up to 16) as a list
        and as the zero-padded table ``frame_named_value`` reads, and the values' array."""
        names = list(_NV_NAMES)
        for n in self.status_names[:16]:      # a law with STATUS_NAMES has status
            names.append(n.upper()[:10].encode("ascii", "replace"))
        self._nv_name_list = names
        self._nv_names = np.zeros((len(names), NV_NAME_B), np.uint8)
        self._nv_values = np.zeros(len(names))
        for i, name in enumerate(names):
            self._nv_names[i, :len(name)] = np.frombuffer(name[:NV_NAME_B], np.uint8)
        self._nv_names_p = address_of(self._nv_names, np.uint8, self._nv_names.size)
        self._nv_values_p = address_of(self._nv_values, np.float64, len(names))
        self._nv_status_p = self._nv_values_p + 8 * _NV_FIXED

    def named_value_count(self) -> int:
        """How many named values :meth:`named_values` gives (0 before the first refresh)."""
        return len(self._nv_values)

    def debug_vectors(self) -> list:
        """CMD_DEG, EST_DEG, DELTA_DEG of the newest tick (built when asked, not from the 1 Hz
        cache: in lockstep the flight log takes them at 10 Hz of sim time)."""
        e = self.est.est
        vec = [
            (b"CMD_DEG", tuple(math.degrees(x) for x in self.out.cmd_active)),
            (b"EST_DEG", (math.degrees(e[0]), math.degrees(e[1]), math.degrees(e[2]))),
            (b"DELTA_DEG", tuple(math.degrees(x) for x in self.out.delta_rad)),
        ]
        if self.modes.guidance_active:
            # x: the envelope limit bitfield in force (fc/guidance/layout.py LIM_*), y: the
            # throttle command (0..1), z: the flight-path angle command (deg)
            vec.append((b"GUID", (float(self.guid.limits), self.guid.throttle(),
                                  math.degrees(self.guid.g.status[GS_GAM_C]))))
        return vec

    def debug_vector_count(self) -> int:
        """How many vectors :meth:`debug_vectors` gives now (GUID in the guidance modes)."""
        return 4 if self.modes.guidance_active else 3

    def frame_debug_vector(self, k: int, tx: int, log_epoch_us: int, log_t_at: int, seq: int,
                           sysid: int, compid: int, time_at: int) -> int:
        """:meth:`debug_vectors`' vector ``k`` as a DEBUG_VECT framed by the compiled kernel
        (fc/gcs_frames.py ``debug_vect_p``, its arguments: the time base in the int64
        cell at ``time_at``) from the arrays it is made of: no
        Python object but the floats of GUID. Bytes written, or 0 (the caller then builds it
        with the codec from :meth:`debug_vectors`)."""
        if k == 0:
            return debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, DV_CMD,
                                self._cmd_dv_at.of(self.out.cmd_active), True, 0.0, 0.0, 0.0)
        if k == 1:
            return debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, DV_EST,
                                self._est_dv_at.of(self.est.est), True, 0.0, 0.0, 0.0)
        if k == 2:
            return debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at,
                                DV_DELTA, self._delta_p, True, 0.0, 0.0, 0.0)
        g = self.guid
        st = g.g.status
        if st is not self._gstatus:             # (bound once: a read of it gives a float)
            self._gstatus, self._gstatus_mv = st, memoryview(st)
        return debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, DV_GUID, 0,
                            False, float(g.limits), g.throttle(),
                            math.degrees(self._gstatus_mv[GS_GAM_C]))

    def frame_named_value(self, k: int, tx: int, log_epoch_us: int, log_t_at: int, seq: int,
                          sysid: int, compid: int, time_at: int) -> int:
        """:meth:`named_values`' ``k``-th pair as NAMED_VALUE_FLOAT framed by the compiled
        kernel (fc/gcs_frames.py ``named_value_p``, its arguments) from the arrays
        :meth:`refresh` keeps beside the list. Bytes written, or 0."""
        if not 0 <= k < len(self._nv_values):
            return 0
        return named_value_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at,
                             self._nv_names_p, self._nv_values_p, k)

    def throttle_percent(self) -> int:
        """VFR_HUD.throttle: the throttle command in %, 0 outside the guidance modes."""
        # (``__round__`` called as a method: ``round`` looked it up as a bound method object,
        # a block per VFR_HUD in the guidance modes, issue 24; the same int)
        return int((100.0 * self.guid.throttle()).__round__()) if self.modes.guidance_active else 0

    def nav_output_active(self) -> bool:
        """Whether NAV_CONTROLLER_OUTPUT is sent (a guidance mode, the guidance engaged)."""
        return self.modes.guidance_active and self.guid.engaged

    def nav_controller_output(self):
        """NAV_CONTROLLER_OUTPUT fields (fc/guided.py ``nav_output``), None outside the
        guidance modes."""
        if not self.nav_output_active():
            return None
        return self.guid.nav_output(self.est.est)

    def frame_nav_output(self, tx: int, log_epoch_us: int, log_t_at: int, seq: int, sysid: int,
                         compid: int) -> int:
        """:meth:`nav_controller_output` framed by the compiled kernel (fc/gcs_frames.py
        ``nav_output_p``, its arguments) from the guidance's arrays and waypoint; bytes
        written, or 0 (outside the guidance modes, or declined: the caller then builds it
        with the codec)."""
        g = self.guid
        if not self.nav_output_active():
            return 0
        wp = g.nav_wp
        if wp is None:
            return nav_output_p(tx, log_epoch_us, log_t_at, seq, sysid, compid,
                                self._gstatus_at.of(g.g.status), self._gtgt_at.of(g.g.tgt),
                                self._est_at.of(self.est.est), False, 0.0, 0.0, 0.0)
        return nav_output_p(tx, log_epoch_us, log_t_at, seq, sysid, compid,
                            self._gstatus_at.of(g.g.status), self._gtgt_at.of(g.g.tgt),
                            self._est_at.of(self.est.est), True, wp[0], wp[1], wp[2])

    # ---------------------------------------------------------------- internals log
    def columns(self) -> list[str]:
        cols = ["t_s", "wall_s", "stamp_us", "mode", "armed", "est_healthy", "est_invalid_mask",
                "est_stale_mask"]
        cols += ["est_" + c for c in EST_COLS]
        cols += ["cmd_alpha_rad", "cmd_beta_rad", "cmd_mu_rad", "delta_left_rad",
                 "delta_right_rad", "delta_rudder_rad", "lateness_us", "exec_us"]
        cols += ["law_" + n for n in self.status_names]
        cols += ["guid_throttle", "guid_limits", "guid_tgt_h_m", "guid_tgt_chi_rad",
                 "guid_tgt_V_m_s"]
        return cols

    def log_row_at(self, ilog: InternalsLog, meas: np.ndarray, stamp_at: int,
                   lateness_ns: float, exec_ns: float, wall_s: float) -> None:
        """:meth:`log_row` of the frame whose stamp is in the int64 cell at ``stamp_at`` (below
        fc/frame_calls.py STAMP_CELL_MAX_US): read by the compiled calls, no int per row."""
        if self._status is None:
            self.log_row(ilog, meas, int64_at(stamp_at), lateness_ns, exec_ns, wall_s)
        elif ilog.take_row_at(stamp_at):
            self._fill_p(ilog, meas, 0.0, stamp_at, lateness_ns, exec_ns, wall_s)

    def _fill_p(self, ilog: InternalsLog, meas: np.ndarray, stamp_us: float, stamp_at: int,
                lateness_ns: float, exec_ns: float, wall_s: float) -> None:
        """The row ``ilog`` took, filled by ``fill_row_p`` (the stamp: ``fill_row_p``'s)."""
        modes = self.modes
        fill_row_p(ilog.chunk_address, ilog.cursor_address, self._dims_p, self._meas_at.of(meas),
                   wall_s, stamp_us, stamp_at, int(modes.mode), modes.armed, self.est.healthy,
                   self._emem_p, self._cmd_at.of(self.out.cmd_active), self._delta_p,
                   float(lateness_ns), float(exec_ns), self._status_p,
                   self.guid.throttle() if modes.guidance_active else math.nan,
                   self.guid.limits, self._tgt_p)

    def log_row(self, ilog: InternalsLog, meas: np.ndarray, stamp_us: int, lateness_ns: float,
                exec_ns: float, wall_s: float) -> None:
        """One internals-log row of the newest tick (dropped when the log is full); ``wall_s``:
        the tick's wall clock (``time.monotonic``, s) as the loop read it: in lockstep the
        frame's arrival, in real time the wake-up. ``lateness_ns``, ``exec_ns``: int or float
        (the kernel takes floats: one specialisation, the same values)."""
        if self._status is not None:
            # by address (fc/control/carrays.py): no array object nor numba record per row,
            # and the row as an index (no address int per row)
            if ilog.take_row(stamp_us):
                self._fill_p(ilog, meas, float(stamp_us), 0, lateness_ns, exec_ns, wall_s)
            return
        r = ilog.row(stamp_us)
        if r is None:
            return
        modes = self.modes
        # the parts' arrays are bound once (__post_init__; they update them in place)
        # the stamp as a float: a u64 stamp beyond the int64 range (the plant's to send) would
        # not convert to the kernel's integer argument
        fill_row(r, meas, wall_s, float(stamp_us), int(modes.mode), modes.armed, self.est.healthy,
                 self._emem, self.out.cmd_active, self._delta, lateness_ns, exec_ns,
                 np.ascontiguousarray(self.law.status, np.float64),
                 self._n_status, self.guid.throttle() if modes.guidance_active else math.nan,
                 self.guid.limits, self._tgt)
