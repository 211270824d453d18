"""HIL tier: the fc process seen by a pymavlink ground station, plant in the loop (loopback UDP).

One fc process (lockstep, real law) for the module; the plant is the in-process PlantSim
driven by the test over the wire contract (tests/fc_harness.py ClosedLoop).
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import pytest

from tests.fc_harness import ClosedLoop, FcProcess, free_udp_port, mavlink as ML
from tools.sitl.gcs import ScriptedGcs

pytestmark = pytest.mark.hil


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("fc_gcs"))
    gcs_port = free_udp_port()
    # the test talks to the GCS between bursts of plant frames: a long data-loss timeout
    # keeps the failsafe (tests/hil/test_fc_failsafe.py) out of this module
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\n")
    fc = FcProcess(out, gcs_ports=(gcs_port,))
    with fc:
        gcs = ScriptedGcs(port=gcs_port)
        loop = ClosedLoop(fc.plant_port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None, "no heartbeat from the fc"
            loop.run(50)
            yield fc, gcs, loop
        finally:
            loop.close()
            gcs.close()


def test_heartbeat_identifies_a_fixed_wing_generic_autopilot(vehicle):
    _, gcs, _ = vehicle
    hb = gcs.wait("HEARTBEAT", 5)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert hb.type == ML.MAV_TYPE_FIXED_WING and hb.autopilot == ML.MAV_AUTOPILOT_GENERIC
    assert hb.base_mode & ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


def test_full_parameter_list_has_consistent_count_and_indices(vehicle):
    _, gcs, _ = vehicle
    from fc.params import build_table
    expected = build_table().names
    gcs.mav.param_request_list_send(1, 1)
    seen = {}
    while len(seen) < len(expected):
        m = gcs.wait("PARAM_VALUE", 5)
        assert m is not None, f"list stalled after {len(seen)} of {len(expected)}"
        assert m.param_count == len(expected)
        integer = build_table().defs[m.param_index].integer
        assert m.param_type == (ML.MAV_PARAM_TYPE_INT32 if integer else ML.MAV_PARAM_TYPE_REAL32)
        seen[m.param_index] = m.param_id
    assert [seen[i] for i in range(len(expected))] == expected


def test_read_by_name_and_by_index(vehicle):
    _, gcs, _ = vehicle
    by_name = gcs.param_get("FS_TIMEOUT_S")
    assert by_name is not None and by_name.param_value == pytest.approx(30.0)   # from the file
    gcs.mav.param_request_read_send(1, 1, b"", by_name.param_index)
    by_index = gcs.wait("PARAM_VALUE", 5, cond=lambda m: m.param_index == by_name.param_index)
    assert by_index.param_id == "FS_TIMEOUT_S"


def test_refused_set_sends_old_value_and_statustext(vehicle):
    _, gcs, _ = vehicle
    old = gcs.param_get("CMD_MU_DEG").param_value
    reply = gcs.param_set("CMD_MU_DEG", 500.0)
    assert reply.param_value == old
    text = gcs.wait("STATUSTEXT", 5, cond=lambda m: "CMD_MU_DEG" in m.text)
    assert text is not None and "outside" in text.text
    reply = gcs.param_set("CMD_MU_DEG", float("nan"))
    assert reply.param_value == old


def test_trim_parameter_takes_effect_in_manual_output(vehicle):
    _, gcs, loop = vehicle
    ack = gcs.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 0)
    assert ack.result == ML.MAV_RESULT_ACCEPTED
    assert gcs.param_set("TRIM_RUD_DEG", 2.0).param_value == pytest.approx(2.0)
    loop.run(5)
    assert loop.outputs[-1][2] == 1550            # 2 deg = 50 us above trim (wire.md 3)
    assert gcs.param_set("TRIM_RUD_DEG", 0.0).param_value == 0.0
    loop.run(5)
    assert loop.outputs[-1] == (1500, 1500, 1500)


def test_commands_get_acks_and_answers(vehicle):
    _, gcs, _ = vehicle
    assert gcs.command(12345).result == ML.MAV_RESULT_UNSUPPORTED
    ack = gcs.command(ML.MAV_CMD_REQUEST_MESSAGE, ML.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert ack.result == ML.MAV_RESULT_ACCEPTED
    av = gcs.wait("AUTOPILOT_VERSION", 5)
    assert av.capabilities & ML.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert av.capabilities & ML.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    ack = gcs.command(ML.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)
    assert ack.result == ML.MAV_RESULT_ACCEPTED and gcs.wait("AUTOPILOT_VERSION", 5)
    ack = gcs.command(ML.MAV_CMD_SET_MESSAGE_INTERVAL, ML.MAVLINK_MSG_ID_ATTITUDE, 50_000)
    assert ack.result == ML.MAV_RESULT_ACCEPTED
    mi = gcs.wait("MESSAGE_INTERVAL", 5, cond=lambda m: m.message_id == ML.MAVLINK_MSG_ID_ATTITUDE)
    assert mi.interval_us == 50_000
    gcs.mav.mission_request_list_send(1, 1)
    assert gcs.wait("MISSION_COUNT", 5).count == 0
    gcs.mav.request_data_stream_send(1, 1, ML.MAV_DATA_STREAM_EXTRA2, 4, 1)
    assert gcs.wait("VFR_HUD", 5) is not None


def test_sys_status_is_healthy_with_data(vehicle):
    _, gcs, loop = vehicle
    loop.run(10)
    st = gcs.wait("SYS_STATUS", 5)
    assert st.onboard_control_sensors_health & ML.MAV_SYS_STATUS_AHRS
    assert st.onboard_control_sensors_health & ML.MAV_SYS_STATUS_GEOFENCE   # absent = healthy


def test_mode_arm_and_attitude_command_are_followed(vehicle):
    """COORDINATED + armed from the GCS, then alpha_c/mu_c by MAV_CMD_USER_1: the plant follows."""
    _, gcs, loop = vehicle
    assert gcs.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 1).result == 0
    assert gcs.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == ML.MAV_RESULT_ACCEPTED
    hb = gcs.wait("HEARTBEAT", 5, cond=lambda m: m.custom_mode & 0xFFFF == 1
                  and m.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED)
    assert hb is not None
    ack = gcs.command(ML.MAV_CMD_USER_1, 5.0, 0.0, 4.0)
    assert ack.result == ML.MAV_RESULT_ACCEPTED
    assert gcs.param_get("CMD_ALPHA_DEG").param_value == pytest.approx(5.0)
    loop.run(int(6.0 / loop.sim.frame_dt_s))
    alpha = math.degrees(loop.truth("alpha_rad"))
    mu = math.degrees(loop.truth("mu_rad"))
    beta = math.degrees(loop.truth("beta_rad"))
    print(f"after 6 s: alpha {alpha:.3f} beta {beta:.3f} mu {mu:.3f} deg")
    assert abs(alpha - 5.0) < 0.5 and abs(mu - 4.0) < 1.0 and abs(beta) < 1.0
    dv = gcs.wait("DEBUG_VECT", 5, cond=lambda m: m.name == "CMD_DEG" and abs(m.x - 5.0) < 1e-4)
    assert dv is not None and dv.z == pytest.approx(4.0)
    # out-of-limit attitude command: refused, nothing changes
    assert gcs.command(ML.MAV_CMD_USER_1, 80.0, float("nan"), float("nan")).result == \
        ML.MAV_RESULT_DENIED
    assert gcs.param_get("CMD_ALPHA_DEG").param_value == pytest.approx(5.0)


def test_law_parameter_takes_effect_and_mode_switch_in_flight(vehicle):
    _, gcs, loop = vehicle
    gcs.command(ML.MAV_CMD_DO_SET_MODE, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 1)
    gcs.command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    gcs.command(ML.MAV_CMD_USER_1, 8.0, 0.0, -10.0)     # a large step: the surfaces work hard
    loop.run(200)
    assert max(abs(u - 1500) for pwm in loop.outputs[-200:] for u in pwm) > 60
    assert gcs.param_set("ACT_MAX", 2.0).param_value == pytest.approx(2.0)
    loop.outputs.clear()
    loop.run(200)
    assert max(abs(u - 1500) for pwm in loop.outputs[20:] for u in pwm) <= 50   # 2 deg
    assert gcs.param_set("ACT_MAX", 20.0).param_value == pytest.approx(20.0)
    # SET_MODE message (not a command): UNCOORDINATED while flying; CO_ENABLE follows
    gcs.mav.set_mode_send(1, ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 2)
    assert gcs.wait("HEARTBEAT", 5, cond=lambda m: m.custom_mode & 0xFFFF == 2) is not None
    assert gcs.param_get("CO_ENABLE").param_value == 0.0
    assert gcs.param_set("CO_ENABLE", 1.0).param_value == 0.0           # mode-driven: refused
    gcs.command(ML.MAV_CMD_USER_1, 5.0, 0.0, 0.0)
    loop.run(int(4.0 / loop.sim.frame_dt_s))
    assert abs(math.degrees(loop.truth("alpha_rad")) - 5.0) < 0.5


def test_qgroundcontrol_connect_sequence_completes(vehicle):
    """The requests QGC's InitialConnectStateMachine sends all get an answer (shared mavlink.md 3)."""
    _, gcs, _ = vehicle
    for msg_id in (300, 395):   # PROTOCOL_VERSION, COMPONENT_METADATA: not provided
        ack = gcs.command(ML.MAV_CMD_REQUEST_MESSAGE, msg_id)
        assert ack is not None and ack.result == ML.MAV_RESULT_UNSUPPORTED
    for mission_type in (ML.MAV_MISSION_TYPE_MISSION, ML.MAV_MISSION_TYPE_FENCE,
                         ML.MAV_MISSION_TYPE_RALLY):
        gcs.mav.mission_request_list_send(1, 0, mission_type)
        mc = gcs.wait("MISSION_COUNT", 5, cond=lambda m, t=mission_type: m.mission_type == t)
        assert mc is not None and mc.count == 0
    gcs.mav.param_request_list_send(1, 0)         # to component 0 (all), as QGC does
    first = gcs.wait("PARAM_VALUE", 5, cond=lambda m: m.param_index == 0)
    assert first is not None
    # COMMAND_INT goes through the command handler (a reposition without a GNSS fix: DENIED)
    gcs.mav.command_int_send(1, 1, 0, ML.MAV_CMD_DO_REPOSITION, 0, 0, 0, 0, 0, 0, 0, 0, 0)
    ack = gcs.wait("COMMAND_ACK", 5, cond=lambda m: m.command == ML.MAV_CMD_DO_REPOSITION)
    assert ack.result == ML.MAV_RESULT_DENIED
    # a request addressed to another vehicle is not ours to answer
    gcs.mav.command_long_send(7, 1, ML.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
    assert gcs.wait("COMMAND_ACK", 1.0,
                    cond=lambda m: m.command == ML.MAV_CMD_REQUEST_MESSAGE) is None
    ack = gcs.command(ML.MAV_CMD_GET_MESSAGE_INTERVAL, ML.MAVLINK_MSG_ID_HEARTBEAT)
    assert ack.result == ML.MAV_RESULT_ACCEPTED
    mi = gcs.wait("MESSAGE_INTERVAL", 5, cond=lambda m: m.message_id == 0)
    assert mi.interval_us == 1_000_000


def test_stream_rates_follow_set_message_interval(vehicle):
    _, gcs, _ = vehicle
    att = ML.MAVLINK_MSG_ID_ATTITUDE
    assert gcs.command(ML.MAV_CMD_SET_MESSAGE_INTERVAL, att, -1).result == ML.MAV_RESULT_ACCEPTED
    gcs.wait("HEARTBEAT", 3)                       # let what was in flight arrive
    gcs.drain()
    assert gcs.wait("ATTITUDE", 1.5) is None       # disabled
    assert gcs.command(ML.MAV_CMD_SET_MESSAGE_INTERVAL, att, 20_000).result == \
        ML.MAV_RESULT_ACCEPTED                     # 50 Hz
    first = gcs.wait("ATTITUDE", 3)
    assert first is not None
    # live streams are paced by the wall clock (docs/fc.md section 7; in lockstep the messages
    # carry sim time, which stands still here: no frames are exchanged during this test)
    n, t0 = 0, time.monotonic()
    while time.monotonic() - t0 < 1.0:
        m = gcs.wait("ATTITUDE", 3)
        assert m is not None
        n += 1
    assert n >= 25, f"{n} ATTITUDE in one wall-clock second at a 50 Hz setting"
    gcs.command(ML.MAV_CMD_SET_MESSAGE_INTERVAL, att, 0)   # back to the default


def test_logs_after_clean_shutdown(vehicle):
    """Runs last in this module: it stops the fc."""
    fc, gcs, loop = vehicle
    loop.run(10)
    assert fc.stop() == 0, fc.stderr
    from fc.internals_log import load
    log = load(fc.out)
    assert len(log["t_s"]) > 1000 and "est_mu_rad" in log and "law_sigma_alpha_rad" in log
    assert set(log["mode"]) >= {0.0, 1.0}
    with open(os.path.join(fc.out, "fc.log")) as f:
        text = f.read()
    assert "exit: frames" in text
    # mavlogdump.py, as the module of this interpreter (its bin/ may not be on PATH)
    out = subprocess.run([sys.executable, "-m", "pymavlink.tools.mavlogdump", "--types",
                          "HEARTBEAT,PARAM_SET", os.path.join(fc.out, "fc.tlog")],
                         capture_output=True, text=True, timeout=60)
    assert "HEARTBEAT" in out.stdout and "PARAM_SET" in out.stdout
    assert os.path.exists(os.path.join(fc.out, "params.parm"))
