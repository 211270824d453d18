"""The real-time loop's progress line (plant_sim/process.py ``_realtime``): its real-time
factor is sim time over the wall time since the run began, also after the schedule was
re-based by a resync (issue 21 item 9: it printed 4080, 137, ... after each resync).

The loop runs in process on a scripted clock and a stand-in link: no socket, no waiting.
"""
import logging
import re
import types

import numpy as np

from plant_sim import process
from plant_sim.scenario import load
from plant_sim.sim import PlantSim


class _Clock:
    """perf_counter stand-in: each call advances half a frame; one call stalls ``stall_s``."""

    def __init__(self, step_s: float, stall_at_call: int, stall_s: float):
        self.t = 100.0
        self.calls = 0
        self.step_s, self.stall_at, self.stall_s = step_s, stall_at_call, stall_s

    def __call__(self) -> float:
        self.calls += 1
        self.t += self.step_s + (self.stall_s if self.calls == self.stall_at else 0.0)
        return self.t


class _Link:
    """The members of plant_sim.link.PlantLink the real-time loop uses; the fc answers every
    frame with the trim."""

    def __init__(self, trim):
        self.cmd_rad = np.array(trim)
        self.cmd_throttle = -1.0
        self.cmd_count = 0

    def poll_latest(self):
        self.cmd_count += 1

    def wait_readable(self, timeout_s):
        pass

    def build_sensors(self, *args):
        pass

    def send_sensors(self):
        pass


class _Writer:
    def __init__(self, n):
        self._row = np.zeros(n)

    def row(self):
        return self._row


def test_progress_rtf_counts_from_the_run_start_across_a_resync(monkeypatch, capsys):
    # GIVEN the real-time loop at 500 Hz whose clock stalls 1 s (a resync) after about 0.2 s
    sc = load("paper")
    sim = PlantSim(sc, seed=0)
    clock = _Clock(0.5 * sim.frame_dt_s, stall_at_call=200, stall_s=1.0)
    monkeypatch.setattr(process, "time", types.SimpleNamespace(perf_counter=clock))
    cfg = process.RunConfig(mode="realtime", progress_every_s=0.02)
    stats = process.RunStats()
    stop = types.SimpleNamespace(requested=False, signal_name="")
    # WHEN it flies 300 frames (0.6 s of sim)
    process._realtime(sim, _Link(sim.trim_rad), _Writer(sim.TRUTH_N), cfg, stats, stop, 300, sc,
                      logging.getLogger("test"))
    lines = re.findall(r"PROGRESS t_s=([\d.]+) rtf=([\d.]+)", capsys.readouterr().out)
    # THEN it resynced once, and every progress line's factor is sim time over the time since
    # the start: about 1 before the stall, below 1 after it (never the jump to >> 1)
    assert stats.resyncs == 1 and stats.frames == 300
    rtf = [float(r) for _, r in lines]
    t_s = [float(t) for t, _ in lines]
    assert len(rtf) > 10 and any(t > 0.3 for t in t_s)
    assert max(rtf) < 1.2, rtf
    after = [r for t, r in zip(t_s, rtf) if t > 0.3]
    assert after and max(after) < 0.7, after
