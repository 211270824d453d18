"""HIL: the guidance modes flown by the fc process over real UDP in lockstep, commanded by a
pymavlink ground station (COMMAND_LONG), the cruise scenario's plant in the loop
(tests/fc_harness.py ClosedLoop: the in-process PlantSim, throttle from servo4).

Sim times are short (CI): each check is that the vehicle moves toward the target at the
rate the guidance's limits allow, not that it settles (tools/sitl/closed_loop/guided.py and the 1-hour
runs in docs/guidance.md measure settling)."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

from tests.fc_harness import ClosedLoop, FcProcess, free_udp_port, mavlink as ML
from tools.sitl.gcs import ScriptedGcs

pytestmark = pytest.mark.hil

FRAME_HZ = 500
CRUISE, GUIDED, COORDINATED = 4, 5, 1


def _vehicle(tmp_path, *args):
    out = str(tmp_path)
    gcs_port = free_udp_port()
    # long data-loss timeout: the test talks to the fc between bursts of frames; the
    # prefilter on (the guidance's default shaping); COORDINATED's command = the trim alpha of
    # the cruise scenario (its round Earth: 3.5635 deg, plant_sim/scenarios/cruise.toml)
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\nREF_PF_EN 1\nCMD_ALPHA_DEG 3.5635\n")
    fc = FcProcess(out, "--arm", *args, gcs_ports=(gcs_port,))
    return fc, gcs_port


class _Rec:
    """Truth samples every 10 frames (50 Hz): t, h, V, chi, alpha, mu."""

    def __init__(self, loop):
        self.loop = loop
        self.rows = []
        self.k = 0

    def __call__(self):
        if self.k % 10 == 0:
            t = self.loop.truth
            self.rows.append((t("t_s"), t("h_m"), t("V_m_s"), t("chi_rad"), t("alpha_rad"),
                              t("mu_rad")))
        self.k += 1
        return False

    def since(self, t0):
        a = np.array(self.rows)
        return a[a[:, 0] >= t0 - 1e-9]


def _mode(gcs, mode):
    ack = gcs.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)
    assert ack is not None and ack.result == ML.MAV_RESULT_ACCEPTED


def test_guided_changes_from_a_ground_station_are_followed(tmp_path):
    fc, gcs_port = _vehicle(tmp_path, "--flight-mode", "GUIDED")
    with fc:
        gcs = ScriptedGcs(port=gcs_port)
        loop = ClosedLoop(fc.plant_port, scenario="cruise", seed=1)
        rec = _Rec(loop)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            loop.run(FRAME_HZ, rec)                                      # 1 s holding
            h0, v0, chi0 = loop.truth("h_m"), loop.truth("V_m_s"), loop.truth("chi_rad")
            # WHEN the ground station asks +500 m, +10 deg, +50 m/s
            for cmd, p in ((ML.MAV_CMD_GUIDED_CHANGE_ALTITUDE, (28500.0,)),
                           (ML.MAV_CMD_GUIDED_CHANGE_HEADING, (0, 10.0)),
                           (ML.MAV_CMD_GUIDED_CHANGE_SPEED, (0, 2300.0))):
                ack = gcs.command(cmd, *p)
                assert ack is not None and ack.result == ML.MAV_RESULT_ACCEPTED, (cmd, ack)
            # and targets outside the envelope: DENIED with a STATUSTEXT, targets kept
            for cmd, p, word in ((ML.MAV_CMD_GUIDED_CHANGE_ALTITUDE, (60000.0,), "GT_ALT"),
                                 (ML.MAV_CMD_DO_CHANGE_SPEED, (0, 5000.0), "GT_SPD"),
                                 (ML.MAV_CMD_DO_CHANGE_ALTITUDE, (20000.0, 0), "GE_QBAR")):
                ack = gcs.command(cmd, *p)
                assert ack is not None and ack.result == ML.MAV_RESULT_DENIED, (cmd, ack)
                assert gcs.wait("STATUSTEXT", 5, cond=lambda m, w=word: w in m.text) is not None
            t_cmd = loop.truth("t_s")
            loop.run(20 * FRAME_HZ, rec)                                 # 20 s of sim time
            # THEN NAV_CONTROLLER_OUTPUT reports the targets, VFR_HUD a throttle
            # (messages queued before the flight may still carry the 500 m of the start)
            nav = gcs.wait("NAV_CONTROLLER_OUTPUT", 5, cond=lambda m: 0.0 < m.alt_error < 500.0)
            assert nav is not None and nav.nav_bearing == 10
            hud = gcs.wait("VFR_HUD", 5)
            assert hud is not None and 0 < hud.throttle <= 100
            assert loop.servo4 >= 1000
        finally:
            loop.close()
            gcs.close()
        assert fc.stop() == 0
    r = rec.since(t_cmd)
    h, v = r[:, 1], r[:, 2]
    chi = np.degrees(np.unwrap(r[:, 3]) - chi0)
    # each moved toward its target at about its limit's pace (in 20 s: altitude +25 m/s
    # climb demand after the 0.3 deg/s flight-path ramp; bank ramps to 30 deg at 3 deg/s,
    # then 0.14 deg/s of turn; speed reference +1.5 m/s^2) and none went past it
    assert h[-1] - h0 > 200.0 and h.max() < 28500.0
    assert chi[-1] > 0.7 and chi.max() < 10.0
    assert v[-1] - v0 > 10.0 and v.max() < 2300.0
    # the bank stayed inside its envelope limit (GE_MU_MAX 30 deg; the command stops at
    # 29.8 deg, GE_MU_MARGIN inside) and alpha in its range
    assert np.degrees(np.abs(r[:, 5])).max() < 30.0
    assert 0.0 < np.degrees(r[:, 4]).min() and np.degrees(r[:, 4]).max() < 10.0


def test_mode_changes_in_flight_have_no_transient(tmp_path):
    """COORDINATED (trim alpha) -> CRUISE -> GUIDED -> CRUISE, 4 s apart: after each switch
    alpha stays within 0.2 deg and mu within 0.5 deg of their value at the switch over the
    next 4 s, altitude within 10 m, speed within 4 m/s (measured, seed 1: 0.05 deg, 0.29 deg,
    1.2 m, 2.3 m/s: the throttle starts at the guidance's feed-forward, not the plant's) (the guidance engages from the state,
    the law runs on)."""
    fc, gcs_port = _vehicle(tmp_path, "--flight-mode", "COORDINATED")
    with fc:
        gcs = ScriptedGcs(port=gcs_port)
        loop = ClosedLoop(fc.plant_port, scenario="cruise", seed=1)
        rec = _Rec(loop)
        switches = []
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            loop.run(2 * FRAME_HZ, rec)
            for mode in (CRUISE, GUIDED, CRUISE):
                _mode(gcs, mode)
                switches.append(loop.truth("t_s"))
                loop.run(4 * FRAME_HZ, rec)
            hb = gcs.wait("HEARTBEAT", 5, cond=lambda m: m.custom_mode & 0xFFFF == CRUISE)
            assert hb is not None
        finally:
            loop.close()
            gcs.close()
        assert fc.stop() == 0
    for t0 in switches:
        r = rec.since(t0)
        r = r[r[:, 0] <= t0 + 4.0]
        d = r - r[0]
        assert np.degrees(np.abs(d[:, 4])).max() < 0.2, f"alpha jump after t={t0:.1f} s"
        assert np.degrees(np.abs(d[:, 5])).max() < 0.5, f"mu jump after t={t0:.1f} s"
        assert np.abs(d[:, 1]).max() < 10.0, f"altitude deviation after t={t0:.1f} s"
        assert np.abs(d[:, 2]).max() < 4.0, f"speed deviation after t={t0:.1f} s"
