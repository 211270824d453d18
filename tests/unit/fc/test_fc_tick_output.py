"""The fast tick's output (fc/app.py ``_fast_tick``): the surface command it logs
(``out.delta_rad``) and the PWM it sends come from one compiled call (``surfaces_pwm``); the
law's ``delta_cmd_rad`` is checked at start-up. In process, sockets on free loopback ports."""
from __future__ import annotations

import time

import numpy as np
import pytest

import fc.app as app
from fc.app import FcConfig, FlightController
from fc.link import M_T_S, deflection_to_pwm
from tests.fc_harness import free_udp_port, level_meas


def _cfg(tmp_path, flight_mode):
    return FcConfig(plant_bind=("127.0.0.1", free_udp_port()),
                    gcs=[("127.0.0.1", free_udp_port())],
                    gcs_bind=("127.0.0.1", free_udp_port()), out=str(tmp_path), arm=True,
                    flight_mode=flight_mode)


def _tick(fc, t_s, held=False):
    m = level_meas(t_s, alpha_deg=3.9, V=2250.0, h=28000.0)
    fc.meas_scratch[:] = m
    assert fc.intake.take(int(round(m[M_T_S] * 1e6)), time.monotonic())
    fc.mode_ctl.sync()
    fc._fast_tick(True, held)


def test_the_tick_logs_and_sends_the_same_surface_command(tmp_path):
    # GIVEN the fc flying COORDINATED
    fc = FlightController(_cfg(tmp_path, "COORDINATED"))
    try:
        for k in range(5):
            # WHEN it ticks on a frame
            _tick(fc, 0.2 + 0.002 * k)
            # THEN the logged command is the law's, bit for bit, and the PWM its mapping
            assert np.array_equal(fc.out.delta_rad, fc.law.delta_cmd_rad)
            assert fc.pwm_us.tolist() == [deflection_to_pwm(x) for x in fc.out.delta_rad] + [0]
        assert not np.array_equal(fc.out.delta_rad, fc.settings.trim_rad)    # the law flew
        # AND a held tick (no new data) keeps both while the law moves on elsewhere
        before = fc.out.delta_rad.copy()
        fc.law.delta_cmd_rad[:] = 0.3
        _tick(fc, 0.212, held=True)
        assert np.array_equal(fc.out.delta_rad, before)
        assert fc.pwm_us.tolist() == [deflection_to_pwm(x) for x in before] + [0]
        # AND disarmed, the surfaces go to trim
        fc.modes.set_armed(False, data_ok=True)
        _tick(fc, 0.214)
        assert np.array_equal(fc.out.delta_rad, fc.settings.trim_rad)
        assert fc.pwm_us.tolist() == [deflection_to_pwm(x) for x in fc.settings.trim_rad] + [0]
    finally:
        fc.close()


def test_a_law_without_a_float64_3_surface_command_is_refused_at_start(tmp_path, monkeypatch):
    # GIVEN an injected law whose surface command is a list, not a float64[3] array
    law_cls, params = app.load_law_module("fc.control")

    class ListLaw(law_cls):
        def __init__(self, overrides):
            super().__init__(overrides)
            self.delta_cmd_rad = [0.0, 0.0, 0.0]

    monkeypatch.setattr(app, "load_law_module", lambda name: (ListLaw, params))
    # WHEN the fc starts THEN it says what is wrong before binding anything
    with pytest.raises(ValueError, match="delta_cmd_rad must be a float64"):
        FlightController(_cfg(tmp_path, "COORDINATED"))


def test_the_log_row_takes_any_u64_stamp(tmp_path):
    # GIVEN the fc after a tick on an ordinary frame (the row kernel compiled for it)
    fc = FlightController(_cfg(tmp_path, "COORDINATED"))
    try:
        _tick(fc, 0.2)
        # WHEN rows are logged for stamps up to the top of the wire's u64 range
        for stamp in (200_000, 2**63 - 1, 2**63, 2**64 - 2):
            fc.telemetry.log_row(fc.ilog, fc.meas, stamp, 0, 1000, 1.0)
            # THEN each is logged (as the nearest float64), none raises
            row = fc.ilog.chunk[fc.ilog.n - 1]
            assert row[fc.ilog.col["stamp_us"]] == float(stamp)
    finally:
        fc.close()
