"""The fc runs any law with the API of docs/architecture.md section 11 (``--law-module``).

This module doubles as the injected law: ``python -m fc --law-module
tests.hil.test_fc_law_injection`` loads ``AttitudeLaw`` and ``LAW_PARAMS`` from here. The stand-in
law is a proportional alpha loop on both elevons, so the plumbing (parameters reach
``set_param``, the command reaches ``slow_step``, a law fault gives FAILSAFE) can be checked
exactly.
"""
from __future__ import annotations

import math
import os
from collections import namedtuple

import numpy as np
import pytest

_Param = namedtuple("_Param", "name default min max unit group description")
LAW_PARAMS = (
    _Param("CO_ENABLE", 1.0, 0.0, 1.0, "-", "CO", "coordination switch (stand-in)"),
    _Param("FAKE_GAIN", 1.0, 0.0, 10.0, "-", "FAKE", "delta = gain * (alpha_c - alpha)"),
)


class AttitudeLaw:
    """delta_left = delta_right = FAKE_GAIN * (alpha_c - alpha); raises for alpha_c > 15 deg."""

    STATUS_NAMES = ("fake_err_rad", "fake_resets")

    def __init__(self, overrides=None):
        self.gain = 1.0
        self.co = 1.0
        self.cmd = np.zeros(3)
        self.delta_cmd_rad = np.zeros(3)
        self.status = np.zeros(2)
        for k, v in (overrides or {}).items():
            self.set_param(k, v)

    def set_param(self, name, value):
        if name == "FAKE_GAIN":
            self.gain = float(value)
        elif name == "CO_ENABLE":
            self.co = float(value)
        else:
            raise KeyError(name)

    def reset(self, est):
        self.status[1] += 1

    def slow_step(self, est, cmd_rad, dt_s):
        self.cmd[:] = cmd_rad

    def fast_step(self, est, dt_s):
        if self.cmd[0] > math.radians(15.0):
            raise RuntimeError("stand-in law fault")
        err = self.cmd[0] - est[0]
        self.status[0] = err
        self.delta_cmd_rad[0] = self.delta_cmd_rad[1] = self.gain * err


@pytest.mark.hil
def test_injected_law_plumbing_and_law_fault_failsafe(tmp_path):
    from tests.fc_harness import FcProcess, ScriptedPlant, free_udp_port, level_meas
    from tests.fc_harness import mavlink as ML
    from tools.sitl.gcs import ScriptedGcs

    with open(os.path.join(tmp_path, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\nCMD_ALPHA_DEG 2\n")
    gcs_port = free_udp_port()
    with FcProcess(str(tmp_path), "--law-module", "tests.hil.test_fc_law_injection", "--arm",
                   "--flight-mode", "COORDINATED", gcs_ports=(gcs_port,)) as fc:
        gcs = ScriptedGcs(port=gcs_port)
        plant = ScriptedPlant(fc.plant_port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            t = [0.0]

            def step():
                t[0] += 0.002
                return plant.exchange(level_meas(t[0], alpha_deg=0.0))

            ans = step()
            assert (ans.servo1_raw, ans.servo2_raw, ans.servo3_raw) == (1550, 1550, 1500)
            reply = gcs.param_set("FAKE_GAIN", 2.0)
            assert reply.param_value == 2.0
            ans = step()
            assert ans.servo1_raw == 1600                    # 2 * 2 deg = 4 deg = 100 us
            assert gcs.command(ML.MAV_CMD_USER_1, 16.0, 0.0, 0.0).result == \
                ML.MAV_RESULT_ACCEPTED
            for _ in range(6):                               # reaches the law at the next slow tick
                ans = step()
            # FAILSAFE holds the trim the law flew (the running mean of its commands, issue
            # 22), not TRIM_* = 0 deg: between the 1550 and 1600 us flown, and held
            held = (ans.servo1_raw, ans.servo2_raw, ans.servo3_raw)
            assert 1550 <= held[0] <= 1600 and held[1] == held[0] and held[2] == 1500
            for _ in range(5):
                ans = step()
            assert (ans.servo1_raw, ans.servo2_raw, ans.servo3_raw) == held
            text = gcs.wait("STATUSTEXT", 5, cond=lambda m: "law fault" in m.text)
            assert text is not None and text.severity == ML.MAV_SEVERITY_CRITICAL
            assert gcs.wait("HEARTBEAT", 3, cond=lambda m: m.custom_mode & 0xFFFF == 3) is not None
        finally:
            plant.close()
            gcs.close()
        assert fc.stop() == 0
