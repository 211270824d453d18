"""fc/intake.py - the flight controller's frame intake, one path for both timing modes.

One part of the flight controller (docs/architecture.md, the fc's parts). The run loops read a
plant frame into ``scratch`` (fc/link.py ``PlantLink.read_frame``) and hand its stamp to
:meth:`FrameIntake.take`, in lockstep and in real time alike:

- a repeat of the newest stamp (the plant re-sent it, or the link duplicated it) is counted
  and dropped;
- a frame at most ``late_window_us`` older than the newest is a late one (the link reordered
  it): counted and dropped. The window is 0 in lockstep, where one frame is in flight at a
  time, and :data:`REORDER_WINDOW_US` in real time;
- plant time going further back (a plant restarted) restarts the loops: the estimator, the
  tick planner (lockstep: its deadlines are plant time), law and guidance engagement (reset
  at the new state, fc/mode_control.py) and the command timeline;
- otherwise the frame becomes ``meas``: the estimator, the failsafe bookkeeping and the
  command timeline (``--timeline``) take it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from fc.control.carrays import address_of
from fc.estimator import Estimator
from fc.frame_calls import (IN_LAST, IN_N, IN_STAMP, INTAKE_DUPLICATE, INTAKE_LATE,
                            INTAKE_RESTART, STAMP_CELL_MAX_US, int64_at, intake_p)
from fc.link import M_T_S
from fc.link import mavlink as ML
from fc.mode_control import ModeControl
from fc.scheduler import TickPlanner
from fc.telemetry import FcCounters
from fc.timeline import Timeline

__all__ = ["FrameIntake", "REORDER_WINDOW_US"]

#: Real time: a frame at most this much older than the newest (plant time, us) was reordered on
#: the link and is dropped; further back, the plant restarted (docs/fc.md, timing).
REORDER_WINDOW_US = 100_000


@dataclass
class FrameIntake:
    """Takes plant frames into the estimator; see the module docstring.

    The newest stamp and ``meas``'s (``last_stamp_us``, ``stamp_us``) live in an int64 array
    checked and stepped by a compiled call (:meth:`take_at`, issue 24: no Python int per
    frame), read and assigned as ints. A stamp at or beyond STAMP_CELL_MAX_US (a faulty
    plant's u64) is kept as a Python int (``_big``) until a smaller one is taken."""

    meas: np.ndarray                # the newest frame (fc/link.py M_*), updated in place
    scratch: np.ndarray             # where the loops read the next frame
    est: Estimator
    mode_ctl: ModeControl
    planner: TickPlanner
    plant_time_ticks: bool          # lockstep: the planner's deadlines are plant time
    counters: FcCounters
    timeline: Timeline | None       # the --timeline commands, by plant time
    set_param: Callable[[str, float], str | None]
    announce_param: Callable[[str], None]
    event: Callable[[str, int], None]
    late_window_us: int = 0         # see the module docstring

    def __post_init__(self) -> None:
        self._st = np.zeros(IN_N, np.int64)
        self._st[IN_LAST] = -1
        #: the address of the int64 holding ``stamp_us`` (the compiled readers of the stamp)
        self.stamp_at = address_of(self._st, np.int64, IN_N) + 8 * IN_STAMP
        self._st_p = self.stamp_at - 8 * IN_STAMP
        self._big: int | None = None    # the newest stamp when beyond the cell (see above)

    @property
    def stamp_us(self) -> int:
        """Plant time of ``meas``, us (0 before the first frame)."""
        return self._big if self._big is not None else self._st.item(IN_STAMP)

    @property
    def last_stamp_us(self) -> int:
        """The newest stamp taken, us (-1 before the first frame)."""
        return self._big if self._big is not None else self._st.item(IN_LAST)

    @property
    def stamp_big(self) -> bool:
        """Whether ``stamp_us`` is beyond the int64 cell at ``stamp_at`` (a Python int)."""
        return self._big is not None

    def take(self, stamp: int, now_s: float) -> bool:
        """The frame in ``scratch`` stamped ``stamp`` (plant time, us) arrived at ``now_s``
        (wall clock). False for a repeat or a late frame (the caller answers it or not), else
        True."""
        last = self.last_stamp_us
        if stamp == last:
            self.counters.duplicate_frames += 1
            return False
        if last >= 0 and stamp < last:
            if last - stamp <= self.late_window_us:
                self.counters.reordered_frames += 1
                return False
            self._restart()
        if 0 <= stamp < STAMP_CELL_MAX_US:
            self._st[IN_LAST] = stamp
            self._st[IN_STAMP] = stamp
            self._big = None
        else:
            self._big = stamp
        self.est.accept(self.scratch, self.meas)       # meas = scratch, the estimator on it
        self.mode_ctl.on_frame(now_s, stamp * 1e-6)
        if self.timeline is not None:
            self._timeline_due()
        return True

    def take_at(self, stamp_at: int, now_s: float) -> bool:
        """:meth:`take` of the frame whose stamp is in the int64 cell at ``stamp_at`` (below
        STAMP_CELL_MAX_US: fc/link.py ``read_frame_at``), checked by a compiled call; its
        plant time (s) read from ``scratch`` as a float (the decoder wrote stamp x 1e-6)."""
        if self._big is not None:
            return self.take(int64_at(stamp_at), now_s)
        return self.after_verdict(intake_p(stamp_at, self._st_p, self.late_window_us), now_s)

    def after_verdict(self, verdict: int, now_s: float) -> bool:
        """:meth:`take_at` after ``intake_p``'s ``verdict`` (it has stepped the stamps): the
        counters, the restart, the estimator and the rest (also the fused frame's way back,
        fc/fused.py, when the verdict is not INTAKE_NEW)."""
        if verdict == INTAKE_DUPLICATE:
            self.counters.duplicate_frames += 1
            return False
        if verdict == INTAKE_LATE:
            self.counters.reordered_frames += 1
            return False
        if verdict == INTAKE_RESTART:
            self._restart()
        t_s = self.scratch.item(M_T_S)
        self.est.accept(self.scratch, self.meas)       # meas = scratch, the estimator on it
        self.mode_ctl.on_frame(now_s, t_s)
        if self.timeline is not None:
            self._timeline_due()
        return True

    def _restart(self) -> None:
        """Plant time went back beyond the late window (a plant restarted): the loops restart."""
        self.counters.plant_resets += 1
        self.event("plant time went backwards: restarting the loops", ML.MAV_SEVERITY_WARNING)
        self.est.reset()
        if self.plant_time_ticks:
            self.planner.next_ns = None     # real time: its deadlines are the wall clock
        self.mode_ctl.restart()
        if self.timeline is not None:
            self.timeline.next = 0          # the command timeline starts over

    def _timeline_due(self) -> None:
        for c in self.timeline.due(self.meas[0]):
            for name, value in c.values:
                reason = self.set_param(name, value)
                if reason is not None:
                    self.event(f"timeline t={c.t_s:g}: {reason}", ML.MAV_SEVERITY_WARNING)
                else:
                    self.announce_param(name)
