"""The guidance inside the fc (fc/guided.py, fc/app.py): its rate, its engagement, the
throttle channel by mode and the validation of targets. In process: a FlightController fed
sensor frames directly (no plant process), sockets bound on free loopback ports."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from fc.app import FcConfig, FlightController
from fc.guided import GUIDANCE_HZ, GuidanceRunner
from fc.link import M_T_S, THROTTLE_PWM_MAX_US, THROTTLE_PWM_MIN_US
from fc.modes import FlightMode
from fc.params import build_table
from tests.fc_harness import free_udp_port, level_meas


def _fc(tmp_path, flight_mode="MANUAL", fast_hz=500.0):
    cfg = FcConfig(plant_bind=("127.0.0.1", free_udp_port()), gcs=[("127.0.0.1", free_udp_port())],
                   gcs_bind=("127.0.0.1", free_udp_port()), out=str(tmp_path), arm=True,
                   flight_mode=flight_mode, fast_hz=fast_hz)
    return FlightController(cfg)


def _frames(fc, t0_s, n, **kw):
    """Feed ``n`` frames at the fast rate from ``t0_s``; returns the servo4 PWMs answered."""
    s4 = []
    for k in range(n):
        m = level_meas(t0_s + k / fc.cfg.fast_hz, alpha_deg=3.9, V=2250.0, h=28000.0, **kw)
        fc.meas_scratch[:] = m
        fc.loops.lockstep_frame(int(round(m[M_T_S] * 1e6)), time.monotonic())
        s4.append(fc.pwm_us[3])
    return s4


@pytest.mark.parametrize("fast_hz, div", [(500.0, 10), (1000.0, 20), (250.0, 5)])
def test_guidance_steps_every_div_ticks_from_the_first(fast_hz, div):
    # GIVEN the runner at a fast rate
    r = GuidanceRunner(build_table(), fast_hz)
    assert r.div == div and r.dt_s == pytest.approx(1.0 / GUIDANCE_HZ)
    est = np.zeros(9)
    est[0], est[6], est[7] = 0.068, 2250.0, 28000.0
    meas = level_meas(0.0, alpha_deg=3.9, V=2250.0, h=28000.0)
    r.engage(est, meas, FlightMode.CRUISE)
    # WHEN ticked 3 div times THEN it steps on ticks 0, div, 2 div only
    stepped = [k for k in range(3 * div) if r.tick(est, meas)]
    assert stepped == [0, div, 2 * div]
    assert r.steps == 3


def test_fc_steps_guidance_at_50_hz_in_cruise_and_throttles(tmp_path):
    # GIVEN the fc armed in CRUISE
    fc = _fc(tmp_path, "CRUISE")
    try:
        # WHEN 1 s of frames at 500 Hz arrives
        s4 = _frames(fc, 0.0, 500)
        # THEN the guidance stepped 50 times (+- the frames before the estimate was healthy)
        assert fc.guid.engaged
        assert 48 <= fc.guid.steps <= 50
        # and the throttle goes out on servo4 (1000..2000 us), from the first engaged tick
        assert all(THROTTLE_PWM_MIN_US <= v <= THROTTLE_PWM_MAX_US for v in s4[5:])
        # the targets are the state at engagement: 28 km, course 0, 2250 m/s
        h, chi, v = fc.guidance_targets()
        assert h == pytest.approx(28000.0, abs=1.0) and v == pytest.approx(2250.0, abs=1.0)
        assert chi == pytest.approx(0.0, abs=1e-3)
        # the law's command is the guidance's (near the flown alpha at engagement)
        assert math.degrees(fc.out.cmd_active[0]) == pytest.approx(3.9, abs=0.5)
    finally:
        fc.close()


@pytest.mark.parametrize("mode", ["MANUAL", "COORDINATED", "UNCOORDINATED"])
def test_attitude_modes_send_no_throttle(tmp_path, mode):
    # GIVEN the fc in an attitude mode WHEN frames arrive THEN servo4 stays 0 (no output)
    fc = _fc(tmp_path, mode)
    try:
        assert set(_frames(fc, 0.0, 100)) == {0}
        assert fc.guid.steps == 0
    finally:
        fc.close()


def test_mode_switches_engage_retarget_and_release_the_guidance(tmp_path):
    fc = _fc(tmp_path, "COORDINATED")
    try:
        _frames(fc, 0.0, 50)
        law_resets = fc.planner.ticks
        # COORDINATED -> CRUISE: guidance engaged, the law not reset (same inner law)
        assert fc.request_mode(FlightMode.CRUISE)[0]
        _frames(fc, 0.1, 50)
        assert fc.guid.engaged and fc.guid.mode == FlightMode.CRUISE
        assert fc.planner.ticks > law_resets      # ticks counted on: no re-engagement
        # a target set in CRUISE, then GUIDED: entered holding the current values
        assert fc.set_guidance_targets(h_m=29000.0) is None
        assert fc.request_mode(FlightMode.GUIDED)[0]
        _frames(fc, 0.2, 10)
        assert fc.guidance_targets()[0] == pytest.approx(28000.0, abs=1.0)
        # GUID_INNER_CO 0: the guidance modes fly the uncoordinated law
        assert fc.set_param("GUID_INNER_CO", 0.0) is None
        _frames(fc, 0.22, 5)
        assert fc.params.get("CO_ENABLE") == 0.0 and fc.guid.engaged
        # back to MANUAL: no guidance, no throttle
        assert fc.request_mode(FlightMode.MANUAL)[0]
        assert set(_frames(fc, 0.3, 10)) == {0}
        assert not fc.guid.engaged
    finally:
        fc.close()


@pytest.mark.parametrize("kw, word", [
    ({"h_m": 60000.0}, "GT_ALT"), ({"h_m": 1000.0}, "GT_ALT"), ({"V_m_s": 5000.0}, "GT_SPD"),
    ({"h_m": 20000.0, "V_m_s": 3100.0}, "GE_QBAR"),          # 0.5 rho V^2 above 200 kPa
    ({"h_m": 40000.0, "V_m_s": 1300.0}, "GE_QBAR"),          # below 25 kPa
    ({"chi_rad": math.nan}, "not finite")])
def test_targets_outside_the_envelope_are_refused_and_kept(tmp_path, kw, word):
    fc = _fc(tmp_path, "GUIDED")
    try:
        _frames(fc, 0.0, 20)
        before = fc.guidance_targets()
        reason = fc.set_guidance_targets(**kw)
        assert reason is not None and word in reason
        assert fc.guidance_targets() == before
        assert fc.set_guidance_targets(h_m=30000.0, V_m_s=2350.0) is None
        assert fc.guidance_targets()[0] == 30000.0 and fc.guidance_targets()[2] == 2350.0
    finally:
        fc.close()


def test_the_flight_controller_is_the_vehicle_view_its_ground_station_link_reads(tmp_path):
    from fc.vehicle_view import VehicleView
    fc = _fc(tmp_path)
    try:
        assert isinstance(fc, VehicleView)
        assert fc.gcs.mission is fc.mission
    finally:
        fc.close()
