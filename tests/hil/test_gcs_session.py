"""HIL tier: the ground-station session of issue 12 (modes, per-link rates, STATUSTEXT, INT32).

The fc runs as a process without a plant (nothing here needs one); each ground station is the
harness's scripted one (tools/sitl/gcs.py) with pymavlink's ``development`` codec, which knows
the standard-modes messages (AVAILABLE_MODES 435, CURRENT_MODE 436) and PARAM_ERROR (345)
that QGroundControl and MAVSDK use. A station either listens where the fc sends (a ``--gcs`` output) or sends to
the fc's bind port from its own port (a peer).
"""
from __future__ import annotations

import math
import os
import struct
import time

import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import development as MD  # noqa: E402

from tests.fc_harness import FcProcess, free_udp_port  # noqa: E402
from tools.sitl.gcs import ScriptedGcs  # noqa: E402

pytestmark = pytest.mark.hil

# the wire contract (docs/fc.md sections 5 and 7), literal on purpose
MODES = {"MANUAL": 0x00010000, "COORDINATED": 0x00070001, "UNCOORDINATED": 0x00070002,
         "FAILSAFE": 0x00010003, "CRUISE": 0x00030004, "GUIDED": 0x00060005,
         "MISSION": 0x04040006, "RTL": 0x05040007}
#: MAV_STANDARD_MODE advertised per mode (0: none)
STANDARD = {"CRUISE": 3, "MISSION": 6, "RTL": 5}


def station(fc: FcProcess, bind_port: int | None = None, sysid: int = 255) -> ScriptedGcs:
    """The scripted ground station with the ``development`` codec: listening where the fc sends
    (``bind_port``, a ``--gcs`` output) or, without one, a peer talking to the fc's bind port
    from an ephemeral port (the fc answers it once it has heard it)."""
    peer = None if bind_port else ("127.0.0.1", fc.gcs_bind_port)
    return ScriptedGcs(port=bind_port or 0, sysid=sysid, vehicle=peer, dialect=MD)


@pytest.fixture()
def fc(tmp_path):
    out_port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), gcs_ports=(out_port,)) as proc:
        proc.out_port = out_port
        yield proc


def _bytewise(i: int) -> float:
    return struct.unpack("<f", struct.pack("<i", i))[0]


def _int_of(m) -> int:
    return struct.unpack("<i", struct.pack("<f", m.param_value))[0]


# ------------------------------------------------------------------------------ point 2: modes
def test_modes_are_named_by_available_modes_and_current_mode(fc):
    """QGroundControl's standard-modes requests: every mode with its name and custom_mode;
    CURRENT_MODE follows a change; SET_MODE with the advertised value and DO_SET_MODE with the
    hyfc number both set the mode; HEARTBEAT custom_mode has PX4's main mode byte."""
    gcs = station(fc, fc.out_port)
    try:
        hb = gcs.wait("HEARTBEAT", 10)
        assert hb is not None and hb.custom_mode == MODES["MANUAL"]
        assert (hb.custom_mode >> 16) & 0xFF == 1                     # PX4 MANUAL main mode
        t_asked = time.monotonic()
        ack = gcs.command(MD.MAV_CMD_REQUEST_MESSAGE, MD.MAVLINK_MSG_ID_AVAILABLE_MODES, 0)
        assert ack.result == MD.MAV_RESULT_ACCEPTED
        got = {}
        while len(got) < len(MODES):
            m = gcs.wait("AVAILABLE_MODES", 3.0, t_asked, cond=lambda m: m.mode_index not in got)
            if m is None:
                break
            assert m.number_modes == len(MODES)
            assert m.standard_mode == STANDARD.get(m.mode_name, 0), m
            got[m.mode_index] = (m.mode_name, m.custom_mode)
        assert {name: cm for name, cm in got.values()} == MODES
        assert sorted(got) == list(range(1, len(MODES) + 1))
        # one mode by index (a GCS re-requests what it missed)
        t_asked = time.monotonic()
        gcs.command(MD.MAV_CMD_REQUEST_MESSAGE, MD.MAVLINK_MSG_ID_AVAILABLE_MODES, 3)
        m = gcs.wait("AVAILABLE_MODES", 3, t_asked)
        assert m.mode_index == 3 and m.mode_name == "UNCOORDINATED"
        assert gcs.command(MD.MAV_CMD_REQUEST_MESSAGE, MD.MAVLINK_MSG_ID_AVAILABLE_MODES,
                           9).result == MD.MAV_RESULT_DENIED
        # SET_MODE with the advertised custom_mode (QGroundControl's way)
        gcs.mav.send(MD.MAVLink_set_mode_message(1, MD.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                             MODES["UNCOORDINATED"]))
        cur = gcs.wait("CURRENT_MODE", 3,
                       cond=lambda m: m.custom_mode == MODES["UNCOORDINATED"])
        assert cur is not None and cur.intended_custom_mode == MODES["UNCOORDINATED"]
        assert gcs.wait("HEARTBEAT", 3, cond=lambda m: m.custom_mode == MODES["UNCOORDINATED"])
        # DO_SET_MODE with the hyfc number (``long DO_SET_MODE 1 1``) and with the wire value
        assert gcs.command(MD.MAV_CMD_DO_SET_MODE, 1, 1).result == MD.MAV_RESULT_ACCEPTED
        assert gcs.wait("HEARTBEAT", 3, cond=lambda m: m.custom_mode == MODES["COORDINATED"])
        assert gcs.command(MD.MAV_CMD_DO_SET_MODE, 1, MODES["FAILSAFE"]).result == \
            MD.MAV_RESULT_ACCEPTED
        assert gcs.wait("HEARTBEAT", 3, cond=lambda m: m.custom_mode == MODES["FAILSAFE"])
        # neither a number nor a wire value: refused; a standard mode we advertise is set, one
        # we do not (ORBIT) refused
        assert gcs.command(MD.MAV_CMD_DO_SET_MODE, 1, 0x00070009).result == MD.MAV_RESULT_DENIED
        assert gcs.command(MD.MAV_CMD_DO_SET_STANDARD_MODE, 3).result == MD.MAV_RESULT_ACCEPTED
        assert gcs.wait("HEARTBEAT", 3, cond=lambda m: m.custom_mode == MODES["CRUISE"])
        assert gcs.command(MD.MAV_CMD_DO_SET_STANDARD_MODE, 2).result == MD.MAV_RESULT_DENIED
    finally:
        gcs.close()


# ---------------------------------------------------------------------- point 3: per-link rates
def test_a_rate_request_changes_only_the_link_that_asked(fc):
    """Station A listens on the configured output; station B is a peer. B turns ATTITUDE off,
    then asks 50 Hz (SET_MESSAGE_INTERVAL) and VFR_HUD off (REQUEST_DATA_STREAM): A keeps the
    default 10 Hz ATTITUDE and 4 Hz VFR_HUD throughout."""
    a = station(fc, fc.out_port)
    b = station(fc, sysid=254)
    try:
        assert a.wait("HEARTBEAT", 10) is not None
        b.mav.heartbeat_send(MD.MAV_TYPE_GCS, MD.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        assert b.wait("HEARTBEAT", 5) is not None                     # the fc answers B now
        att = MD.MAVLINK_MSG_ID_ATTITUDE
        t_asked = time.monotonic()
        ack = b.command(MD.MAV_CMD_SET_MESSAGE_INTERVAL, att, -1)
        assert ack.result == MD.MAV_RESULT_ACCEPTED
        mi = b.wait("MESSAGE_INTERVAL", 3, t_asked, cond=lambda m: m.message_id == att)
        assert mi.interval_us == -1
        time.sleep(0.5)                                               # what was in flight
        t0, t1 = _window(2.0)
        assert _count(b, "ATTITUDE", t0, t1) == 0
        assert _count(b, "HEARTBEAT", t0, t1) >= 1                    # the link is alive
        assert _count(a, "ATTITUDE", t0, t1) >= 15                    # 10 Hz default
        # B: 50 Hz ATTITUDE, VFR_HUD off by the legacy stream request
        assert b.command(MD.MAV_CMD_SET_MESSAGE_INTERVAL, att, 20_000).result == \
            MD.MAV_RESULT_ACCEPTED
        b.mav.send(MD.MAVLink_request_data_stream_message(1, 1, MD.MAV_DATA_STREAM_EXTRA2, 0, 0))
        time.sleep(0.5)
        t0, t1 = _window(2.0)
        n_b, n_a = _count(b, "ATTITUDE", t0, t1), _count(a, "ATTITUDE", t0, t1)
        print(f"ATTITUDE in 2 s: B (50 Hz asked) {n_b}, A (default 10 Hz) {n_a}")
        assert n_b >= 60 and 14 <= n_a <= 26
        assert _count(b, "VFR_HUD", t0, t1) == 0 and _count(a, "VFR_HUD", t0, t1) >= 6
        # A's own answer to GET_MESSAGE_INTERVAL is the default
        t_asked = time.monotonic()
        a.command(MD.MAV_CMD_GET_MESSAGE_INTERVAL, att)
        mi = a.wait("MESSAGE_INTERVAL", 3, t_asked, cond=lambda m: m.message_id == att)
        assert mi.interval_us == 100_000
    finally:
        a.close()
        b.close()


def _window(duration_s: float) -> tuple[float, float]:
    """A measurement window of ``duration_s`` from now (monotonic s); returns at its end. The
    stations keep receiving meanwhile (their receive threads)."""
    t0 = time.monotonic()
    time.sleep(duration_s)
    return t0, time.monotonic()


def _count(gcs: ScriptedGcs, mtype: str, t0: float, t1: float) -> int:
    return len(gcs.messages(mtype, t0, t1))


# ------------------------------------------------------------------------- point 4: STATUSTEXT
def test_a_refusal_flood_gives_bounded_statustext_and_log_with_a_summary(fc):
    """600 refused requests in about a second (out-of-range sets with distinct values, unknown
    modes, bad arming): a bounded number of STATUSTEXT and fc.log lines, then summaries."""
    gcs = station(fc, fc.out_port)
    try:
        assert gcs.wait("HEARTBEAT", 10) is not None
        t0 = time.monotonic()
        for i in range(200):
            gcs.mav.send(MD.MAVLink_param_set_message(1, 1, b"CMD_MU_DEG", 100.0 + i,
                                                  MD.MAV_PARAM_TYPE_REAL32))
            gcs.mav.send(MD.MAVLink_command_long_message(1, 1, MD.MAV_CMD_DO_SET_MODE, 0, 1, 42,
                                                     0, 0, 0, 0, 0))
            gcs.mav.send(MD.MAVLink_command_long_message(1, 1, MD.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                                     1, 0, 0, 0, 0, 0, 0))
            time.sleep(0.004)        # ~1.2 s of flood; the fc reads it all (8 per wake-up)
        # the burst ends: the limiter's summaries follow within ~2-3 s (the last of them is
        # the per-text summary of the unknown mode)
        gcs.wait("STATUSTEXT", 10, t0, cond=lambda m: m.text.startswith("unknown mode 42")
                 and "suppressed" in m.text)
        texts = [m.text for m in gcs.messages("STATUSTEXT", t0)]
        acks = len(gcs.messages("COMMAND_ACK", t0))
    finally:
        gcs.close()
    assert fc.stop() == 0
    print(f"{len(texts)} STATUSTEXT for {acks} answered commands: {texts}")
    assert acks >= 300                                  # the flood did reach the fc
    # limiter: burst 10 + 2/s over the flood, plus one summary per text sent and one overall
    assert len(texts) <= 30, texts
    assert any("suppressed" in t for t in texts), texts
    assert any(t.startswith("unknown mode 42") and "suppressed" in t for t in texts), texts
    with open(os.path.join(fc.out, "fc.log")) as f:
        log = f.read().splitlines()
    flood_lines = [ln for ln in log if "STATUSTEXT" in ln or "refused" in ln]
    assert len(flood_lines) <= 30, len(flood_lines)
    assert any("suppressed" in ln for ln in flood_lines)


def test_a_long_statustext_arrives_in_chunks_that_reassemble(fc):
    """Setting CO_ENABLE is refused with a 76-character reason: two chunks, one id."""
    gcs = station(fc, fc.out_port)
    try:
        assert gcs.wait("HEARTBEAT", 10) is not None
        gcs.mav.send(MD.MAVLink_param_set_message(1, 1, b"CO_ENABLE", 0.0, MD.MAV_PARAM_TYPE_INT32))
        first = gcs.wait("STATUSTEXT", 5, cond=lambda m: m.chunk_seq == 0 and m.id != 0)
        assert first is not None
        chunks = {0: first.text}
        while len(chunks[max(chunks)]) == 50:
            k = max(chunks) + 1
            m = gcs.wait("STATUSTEXT", 3,
                         cond=lambda m, k=k: m.id == first.id and m.chunk_seq == k)
            assert m is not None and m.chunk_seq == max(chunks) + 1
            chunks[m.chunk_seq] = m.text
    finally:
        gcs.close()
    text = "".join(chunks[k] for k in sorted(chunks))
    assert len(chunks) == 2 and len(chunks[0]) == 50
    assert text == ("refused: CO_ENABLE follows the flight mode: set COORDINATED or "
                    "UNCOORDINATED")


# -------------------------------------------------------------------------- point 5: parameters
def test_integer_options_are_int32_bytewise_and_refusals_answered_at_once(fc):
    gcs = station(fc, fc.out_port)
    try:
        assert gcs.wait("HEARTBEAT", 10) is not None
        t_asked = time.monotonic()
        ack = gcs.command(MD.MAV_CMD_REQUEST_MESSAGE, MD.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        av = gcs.wait("AUTOPILOT_VERSION", 3, t_asked)
        assert ack.result == 0
        assert av.capabilities & MD.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
        assert not av.capabilities & MD.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
        gcs.mav.send(MD.MAVLink_param_request_read_message(1, 1, b"CO_FAC_EQ", -1))
        pv = gcs.wait("PARAM_VALUE", 3, cond=lambda m: m.param_id == "CO_FAC_EQ")
        assert pv.param_type == MD.MAV_PARAM_TYPE_INT32 and _int_of(pv) == 19
        gcs.mav.send(MD.MAVLink_param_request_read_message(1, 1, b"FS_TIMEOUT_S", -1))
        pv = gcs.wait("PARAM_VALUE", 3, cond=lambda m: m.param_id == "FS_TIMEOUT_S")
        assert pv.param_type == MD.MAV_PARAM_TYPE_REAL32 and pv.param_value == pytest.approx(0.5)
        # set an integer bytewise (MAVSDK, QGroundControl) and as a plain REAL32 (MAVProxy)
        gcs.mav.send(MD.MAVLink_param_set_message(1, 1, b"CO_FAC_EQ", _bytewise(14),
                                              MD.MAV_PARAM_TYPE_INT32))
        pv = gcs.wait("PARAM_VALUE", 3, cond=lambda m: m.param_id == "CO_FAC_EQ")
        assert _int_of(pv) == 14
        gcs.mav.param_set_send(1, 1, b"CO_FAC_EQ", 19.0, MD.MAV_PARAM_TYPE_REAL32)
        pv = gcs.wait("PARAM_VALUE", 3, cond=lambda m: m.param_id == "CO_FAC_EQ")
        assert _int_of(pv) == 19
        # refusals: PARAM_ERROR then PARAM_VALUE with the old value, at once
        for name, value, ptype, code in (
                (b"CO_FAC_EQ", _bytewise(99), MD.MAV_PARAM_TYPE_INT32,
                 MD.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE),
                (b"FS_TIMEOUT_S", 1000.0, MD.MAV_PARAM_TYPE_REAL32,
                 MD.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE),
                (b"FS_TIMEOUT_S", _bytewise(3), MD.MAV_PARAM_TYPE_INT32, 7),      # wrong type
                (b"CO_ENABLE", _bytewise(0), MD.MAV_PARAM_TYPE_INT32,
                 MD.MAV_PARAM_ERROR_READ_ONLY)):
            t0 = time.monotonic()
            gcs.mav.send(MD.MAVLink_param_set_message(1, 1, name, value, ptype))
            err = gcs.wait("PARAM_ERROR", 2, cond=lambda m, n=name: m.param_id == n.decode())
            pv = gcs.wait("PARAM_VALUE", 2, cond=lambda m, n=name: m.param_id == n.decode())
            dt = time.monotonic() - t0
            assert err is not None and err.error == code, (name, err)
            assert pv is not None and dt < 1.0, (name, dt)
            old = {b"CO_FAC_EQ": 19, b"FS_TIMEOUT_S": 0.5, b"CO_ENABLE": 1}[name]
            got = _int_of(pv) if pv.param_type == MD.MAV_PARAM_TYPE_INT32 else pv.param_value
            assert got == pytest.approx(old), name
        gcs.mav.send(MD.MAVLink_param_set_message(1, 1, b"NO_SUCH_PARAM", 1.0,
                                              MD.MAV_PARAM_TYPE_REAL32))
        err = gcs.wait("PARAM_ERROR", 2, cond=lambda m: m.param_id == "NO_SUCH_PARAM")
        assert err is not None and err.error == MD.MAV_PARAM_ERROR_DOES_NOT_EXIST
        assert math.isfinite(err.param_index)
    finally:
        gcs.close()
