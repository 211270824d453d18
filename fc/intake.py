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

from fc.estimator import Estimator
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
    """Takes plant frames into the estimator; see the module docstring."""

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
    stamp_us: int = 0               # plant time of ``meas``, us
    last_stamp_us: int = -1

    def take(self, stamp: int, now_s: float) -> bool:
        """The frame in ``scratch`` stamped ``stamp`` (plant time, us) arrived at ``now_s``
        (wall clock). False for a repeat or a late frame (the caller answers it or not), else
        True."""
        if stamp == self.last_stamp_us:
            self.counters.duplicate_frames += 1
            return False
        if self.last_stamp_us >= 0 and stamp < self.last_stamp_us:
            if self.last_stamp_us - stamp <= self.late_window_us:
                self.counters.reordered_frames += 1
                return False
            self.counters.plant_resets += 1
            self.event("plant time went backwards: restarting the loops", ML.MAV_SEVERITY_WARNING)
            self.est.reset()
            if self.plant_time_ticks:
                self.planner.next_ns = None     # real time: its deadlines are the wall clock
            self.mode_ctl.restart()
            if self.timeline is not None:
                self.timeline.next = 0          # the command timeline starts over
        self.last_stamp_us = stamp
        self.stamp_us = stamp
        self.est.accept(self.scratch, self.meas)       # meas = scratch, the estimator on it
        self.mode_ctl.on_frame(now_s, stamp * 1e-6)
        if self.timeline is not None:
            self._timeline_due()
        return True

    def _timeline_due(self) -> None:
        for c in self.timeline.due(self.meas[0]):
            for name, value in c.values:
                reason = self.set_param(name, value)
                if reason is not None:
                    self.event(f"timeline t={c.t_s:g}: {reason}", ML.MAV_SEVERITY_WARNING)
                else:
                    self.announce_param(name)
