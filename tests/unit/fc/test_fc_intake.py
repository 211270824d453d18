"""fc/intake.py FrameIntake: one frame intake for lockstep and real time. In process: a
FlightController fed sensor frames directly (no plant process), sockets on free loopback ports."""
from __future__ import annotations

import math
import time

import pytest

from fc.app import FcConfig, FlightController
from fc.link import M_T_S
from tests.fc_harness import free_udp_port, level_meas


def _fc(tmp_path, mode):
    tl = tmp_path / "timeline.toml"
    tl.write_text("[[command]]\nt_s = 0.0\nalpha_deg = 1.0\n[[command]]\nt_s = 0.02\n"
                  "alpha_deg = 3.0\n")
    cfg = FcConfig(mode=mode, plant_bind=("127.0.0.1", free_udp_port()),
                   gcs=[("127.0.0.1", free_udp_port())], gcs_bind=("127.0.0.1", free_udp_port()),
                   out=str(tmp_path / "run"), arm=True, flight_mode="COORDINATED",
                   timeline=str(tl))
    return FlightController(cfg)


def _take(fc, t_s):
    m = level_meas(t_s, alpha_deg=3.9, V=2250.0, h=28000.0)
    fc.meas_scratch[:] = m
    return fc.intake.take(int(round(m[M_T_S] * 1e6)), time.monotonic())


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_plant_time_going_backwards_restarts_the_loops_in_both_timing_modes(tmp_path, mode):
    # GIVEN the fc flying COORDINATED on frames from 0.2 s, its timeline past both commands
    fc = _fc(tmp_path, mode)
    try:
        fc.planner.anchor(time.monotonic_ns())     # as the real-time loop does (wall clock)
        for k in range(20):
            assert _take(fc, 0.2 + 0.002 * k)
        fc.mode_ctl.sync()
        assert fc.mode_ctl.engaged and fc.est.healthy
        assert fc.params.get("CMD_ALPHA_DEG") == pytest.approx(3.0)
        # WHEN the same stamp comes again THEN it is counted and dropped
        assert not _take(fc, 0.238)
        assert fc.counters.duplicate_frames == 1
        # WHEN plant time goes back to 0 (a restarted plant)
        assert _take(fc, 0.0)
        # THEN the estimator, the law's engagement and the timeline started over (alike in
        # both timing modes), the lockstep planner too (real time: its deadlines are wall clock)
        assert fc.counters.plant_resets == 1
        assert fc.params.get("CMD_ALPHA_DEG") == pytest.approx(1.0)
        assert fc.meas_stamp_us == 0
        assert not fc.mode_ctl.engaged
        assert fc.est.good_t.max() == 0.0  # the estimator took the frame at t = 0 afresh
        assert (fc.planner.next_ns is None) == (mode == "lockstep")
        fc.mode_ctl.sync()                 # the next tick re-engages at the new state
        assert fc.mode_ctl.engaged or fc.mode_ctl.reset_pending
        assert math.isfinite(fc.est.est[0]) and fc.est.est[0] > 0.0
    finally:
        fc.close()


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_a_reordered_frame_is_dropped_in_real_time_and_a_restart_in_lockstep(tmp_path, mode):
    # GIVEN the fc flying on 40 ms of frames
    fc = _fc(tmp_path, mode)
    try:
        for k in range(20):
            assert _take(fc, 0.002 * k)
        fc.mode_ctl.sync()
        assert fc.mode_ctl.engaged
        # WHEN a frame 10 ms older than the newest arrives
        took = _take(fc, 0.028)
        if mode == "realtime":
            # THEN in real time the link reordered it: dropped, counted, the loops run on
            assert not took and fc.counters.reordered_frames == 1
            assert fc.counters.plant_resets == 0 and fc.mode_ctl.engaged
            assert fc.meas_stamp_us == 38000
        else:
            # THEN in lockstep (one frame in flight) the plant restarted
            assert took and fc.counters.plant_resets == 1 and not fc.mode_ctl.engaged
            assert fc.meas_stamp_us == 28000
    finally:
        fc.close()
