"""The data-loss FAILSAFE (fc/mode_control.py, fc/app.py ``_fast_tick``; issue 22): the surfaces
held at the trim the law flew (not the TRIM_* defaults of 0 deg), recovery into the mode flown
before with its guidance targets, judged on plant time (a frozen plant is recovered from at
once). In process, an fc on free loopback ports fed frames by hand; wall and plant times are
passed explicitly."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.app import FcConfig, FlightController
from fc.link import M_T_S
from fc.mode_control import SurfaceHold
from fc.modes import FlightMode
from tests.fc_harness import free_udp_port, level_meas

DT = 0.002          # the fast period at 500 Hz, s
#: how far from the 0 deg TRIM_* defaults the trim flown (and held) must be for the test to
#: tell the two apart (deg; the flight below flies 0.28 deg)
HELD_MIN_DEG = 0.1


def _fc(tmp_path, flight_mode="CRUISE"):
    cfg = FcConfig(plant_bind=("127.0.0.1", free_udp_port()), gcs=[("127.0.0.1", free_udp_port())],
                   gcs_bind=("127.0.0.1", free_udp_port()), out=str(tmp_path), arm=True,
                   flight_mode=flight_mode)
    return FlightController(cfg)


def _frame(fc, t_s, wall_s, h=28000.0):
    """One plant frame at plant time ``t_s`` arriving at wall time ``wall_s``, then a tick."""
    m = level_meas(t_s, alpha_deg=3.9, V=2250.0, h=h)
    fc.meas_scratch[:] = m
    assert fc.intake.take(int(round(m[M_T_S] * 1e6)), wall_s)
    fc.mode_ctl.sync()
    fc._fast_tick(True, False)


def _fly(fc, t0_s, seconds, wall0_s, h=28000.0):
    """Frames every DT for ``seconds`` from plant time t0 / wall time wall0 (the same pace);
    returns the surface commands sent (n, 3) rad."""
    out = []
    for k in range(int(round(seconds / DT))):
        _frame(fc, t0_s + k * DT, wall0_s + k * DT, h)
        out.append(fc.out.delta_rad.copy())
    return np.array(out)


def _lose_data(fc, wall_s):
    """No frame since ``wall_s`` - FS_TIMEOUT_S: the housekeeping's check declares the loss."""
    fc.mode_ctl.check_data(wall_s)
    fc.mode_ctl.sync()
    assert fc.modes.mode == FlightMode.FAILSAFE and fc.modes.data_lost


def test_surface_hold_is_a_running_mean_then_a_low_pass():
    hold = SurfaceHold(tau_s=1.0)
    trim = np.array([0.01, 0.02, 0.0])
    assert hold.hold_rad(trim) is trim                     # nothing flown: the parameters
    for v in (0.1, 0.2, 0.3):
        hold.update(np.array([v, v, -v]), 0.1)
    assert hold.hold_rad(trim) == pytest.approx([0.2, 0.2, -0.2])     # the mean so far
    for _ in range(1000):                                   # 10 s at a new command
        hold.update(np.array([0.05, 0.06, 0.0]), 0.01)
    assert hold.hold_rad(trim) == pytest.approx([0.05, 0.06, 0.0], abs=1e-4)
    hold.clear()
    assert hold.hold_rad(trim) is trim


def test_failsafe_holds_the_trim_flown_and_recovers_into_cruise_with_its_targets(tmp_path):
    # GIVEN the fc flying CRUISE for 1.5 s (TRIM_* at their defaults, 0 deg)
    fc = _fc(tmp_path)
    try:
        flown = _fly(fc, 0.2, 1.5, 100.0)
        assert fc.modes.mode == FlightMode.CRUISE and fc.guid.engaged
        assert not np.any(fc.settings.trim_rad)                     # TRIM_* = 0 deg
        targets = fc.guid.targets()
        lo, hi = flown.min(axis=0), flown.max(axis=0)               # what the law flew
        # the trim flown is the running mean of the commands (TRIM_EST_TAU_S 3 s > the 1.5 s
        # flown): away from 0 deg (0.28 deg in the elevons with the schedule's gains read at
        # qbar x SCH_AUTH; above 0.5 deg before them). (Not the last command: with the frame
        # frozen at one attitude the law's commands settle on for seconds)
        assert np.max(np.abs(flown.mean(axis=0))) > math.radians(HELD_MIN_DEG)
        t_last = 0.2 + (len(flown) - 1) * DT
        # WHEN the plant data stops (FS_TIMEOUT_S of wall clock) and the fc ticks on, held
        _lose_data(fc, 101.5 + 0.6)
        for _ in range(10):
            fc._fast_tick(False, True)
        # THEN the surfaces are held at the trim the law flew, not at the 0 deg defaults
        held = fc.out.delta_rad.copy()
        assert np.all((held >= lo - 1e-9) & (held <= hi + 1e-9)), (held, lo, hi)
        assert np.max(np.abs(held - fc.settings.trim_rad)) > math.radians(HELD_MIN_DEG)
        # WHEN data comes back 2 s of plant time later (the vehicle flew on without the fc,
        # 30 m lower), THEN FAILSAFE holds for FS_RECOVER_S of plant time, then CRUISE again
        t_back = t_last + 2.0
        during = _fly(fc, t_back, 0.1, 104.0, h=27970.0)
        assert fc.modes.mode == FlightMode.FAILSAFE
        assert np.array_equal(during[-1], held)
        _fly(fc, t_back + 0.1, 0.2, 104.1, h=27970.0)
        assert fc.modes.mode == FlightMode.CRUISE and fc.guid.engaged and fc.mode_ctl.engaged
        # AND the guidance resumed its targets (it did not take the lower altitude as new ones)
        assert fc.guid.targets() == pytest.approx(targets)
    finally:
        fc.close()


def test_after_a_plant_freeze_the_fc_recovers_at_once_without_failsafe_trim(tmp_path):
    # GIVEN the fc flying CRUISE
    fc = _fc(tmp_path)
    try:
        flown = _fly(fc, 0.2, 1.0, 100.0)
        t_next = 0.2 + len(flown) * DT
        law_state = fc.law.kernel_args() if hasattr(fc.law, "kernel_args") else None
        # WHEN the plant freezes for 3 s of wall clock (its time does not advance): FAILSAFE
        _lose_data(fc, 101.0 + 3.0)
        # THEN the next frame (the next plant stamp) ends the FAILSAFE at once: the law
        # answers it, no FS_RECOVER_S of trim is applied to a flight that never stopped
        _frame(fc, t_next, 104.0)
        assert fc.modes.mode == FlightMode.CRUISE and not fc.modes.data_lost
        assert np.array_equal(fc.out.delta_rad, fc.law.delta_cmd_rad)
        assert law_state is None or fc.mode_ctl.engaged
    finally:
        fc.close()
