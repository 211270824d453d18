"""tools.sitl.gcs.ScriptedGcs with ``record``: the rig's waits, against a stand-in vehicle socket."""
from __future__ import annotations

import socket

from tools.sitl.gcs import ScriptedGcs, mavlink


class _Null:
    def write(self, _b):
        return None


def test_recording_gcs_waits_and_answers_through_its_codec():
    # GIVEN a recording ground station without heartbeats and a vehicle (system 1) socket
    gcs = ScriptedGcs(port=0, heartbeat=False, record=True)
    veh = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    veh.bind(("127.0.0.1", 0))
    veh.settimeout(5.0)
    mav = mavlink.MAVLink(_Null(), srcSystem=1, srcComponent=1)
    try:
        # WHEN the vehicle sends a heartbeat, a counter and a text, and a stranger a heartbeat
        stranger = mavlink.MAVLink(_Null(), srcSystem=7, srcComponent=1)
        veh.sendto(stranger.heartbeat_encode(1, 3, 0, 11, 4).pack(stranger),
                   ("127.0.0.1", gcs.port))
        for msg in (mav.heartbeat_encode(1, 3, 0, 42, 4),
                    mav.named_value_float_encode(0, b"LATE_CNT", 3.0),
                    mav.statustext_encode(4, b"FAILSAFE: plant data lost")):
            veh.sendto(msg.pack(mav), ("127.0.0.1", gcs.port))
        # THEN the waits see the vehicle's messages only
        assert gcs.heartbeat_mode(5.0) == 42
        assert gcs.wait_named("LATE_CNT", lambda v: v >= 3.0, 5.0) == 3.0
        assert gcs.wait_text("FAILSAFE", 5.0) == "FAILSAFE: plant data lost"
        assert gcs.find(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 11) is None
        # AND pymavlink's generated senders reach the vehicle, from system 250
        gcs.conn.mav.param_request_read_send(1, 1, b"FS_TIMEOUT_S", -1)
        data, _ = veh.recvfrom(2048)
        (m,) = mav.parse_buffer(data)
        assert m.get_type() == "PARAM_REQUEST_READ" and m.get_srcSystem() == 250
    finally:
        gcs.close()
        veh.close()
