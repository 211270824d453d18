"""Unit tier: input limits at the door (issue 22, item 8).

A ground station's numbers are bounded where they come in: GUIDED_CHANGE_HEADING within
+-360 deg, mission waypoint altitudes inside the guidance's limits at upload, a bounded number
of requests for an item the station keeps sending wrong (the upload then ends), and mode
changes rate-limited with a STATUSTEXT.
"""
from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"
from fc.gcs import MODE_BURST, GcsLink  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from fc.mission import RETRIES, Mission  # noqa: E402
from fc.modes import FlightMode  # noqa: E402
from tests.fc_harness import free_udp_port  # noqa: E402
from tests.unit.fc.test_gcs_links import _Vehicle  # noqa: E402
from tests.unit.fc.test_mission_protocol import GCS, _m, _upload, _wp, gcs  # noqa: E402,F401


class _GuidedVehicle(_Vehicle):
    """A vehicle in GUIDED that takes any target (records them)."""

    def __init__(self) -> None:
        super().__init__()
        self.modes.request_mode(FlightMode.GUIDED)
        self.targets: list = []

    def set_guidance_targets(self, h_m=None, chi_rad=None, V_m_s=None):
        self.targets.append((h_m, chi_rad, V_m_s))
        return None


def _link(v) -> GcsLink:
    return GcsLink(v, ("127.0.0.1", free_udp_port()), [])


def _texts(link: GcsLink) -> str:
    """The queued STATUSTEXTs, their chunks joined."""
    return "".join(t[1].decode() for t in link.text_queue)


def test_heading_beyond_360_deg_is_refused_with_a_reason(gcs):
    v = _GuidedVehicle()
    link = _link(v)
    try:
        for deg, result in ((30.0, ML.MAV_RESULT_ACCEPTED), (-360.0, ML.MAV_RESULT_ACCEPTED),
                            (1e9, ML.MAV_RESULT_DENIED), (-361.0, ML.MAV_RESULT_DENIED)):
            m = _m(gcs, "command_long", 1, 1, ML.MAV_CMD_GUIDED_CHANGE_HEADING, 0, 0, deg,
                   0, 0, 0, 0, 0)
            assert link._command_result(m) == result, deg
        assert len(v.targets) == 2                     # the refused ones set nothing
        assert "beyond +-360 deg" in _texts(link)
    finally:
        link.close()


def test_mode_changes_are_rate_limited_with_a_statustext():
    v = _Vehicle()
    link = _link(v)
    try:
        # GIVEN a station asking 100 mode changes at once (COORDINATED <-> UNCOORDINATED)
        answers = [link._request_mode(1.0 if v.modes.mode == 2 else 2.0) for _ in range(100)]
        # THEN the burst is accepted, the rest refused with the reason
        assert sum(ok for ok, _ in answers) == MODE_BURST
        assert link.mode_refused == 100 - MODE_BURST
        assert "refused: more than" in answers[-1][1]
        # a request for the mode it is in is no change: always answered yes
        assert link._request_mode(float(v.modes.mode))[0]
        # FAILSAFE (the operator's stop) is never held back
        assert link._request_mode(float(FlightMode.FAILSAFE))[0]
    finally:
        link.close()


def _mission(home_alt_m=None) -> Mission:
    mis = Mission()
    mis.alt_limits_m = lambda: (15000.0, 40000.0, home_alt_m)
    return mis


def test_mission_altitude_outside_the_guidance_limits_is_refused_at_upload(gcs):
    mis = _mission(home_alt_m=1000.0)
    assert _upload(gcs, mis, [_wp(gcs, 0, alt=28000.0)])[0][3] == ML.MAV_MISSION_ACCEPTED
    for z, frame in ((1e9, ML.MAV_FRAME_GLOBAL), (5000.0, ML.MAV_FRAME_GLOBAL_INT),
                     (39500.0, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)):   # 40.5 km MSL
        out = _upload(gcs, mis, [_wp(gcs, 0, alt=z, frame=frame)])
        assert out[0] == ("ack", *GCS, ML.MAV_MISSION_INVALID_PARAM7, 0), (z, frame)
        assert "GT_ALT_" in out[1][2]
    assert mis.count == 1 and mis.item(0)["z"] == 28000.0          # the mission kept
    # before home is known a relative altitude is bounded by the highest limit
    out = _upload(gcs, _mission(), [_wp(gcs, 0, alt=1e9, frame=ML.MAV_FRAME_GLOBAL_RELATIVE_ALT)])
    assert out[0][3] == ML.MAV_MISSION_INVALID_PARAM7


def test_an_item_sent_again_and_again_ends_the_upload(gcs):
    mis = Mission()
    out = mis.handle(_m(gcs, "mission_count", 1, 1, 2, 0), 0.0)
    out = mis.handle(_wp(gcs, 0), 0.0)
    assert out == [("request", *GCS, 1)]
    # WHEN the station answers the request of item 1 with item 0, again and again
    asked = []
    for k in range(3 * RETRIES):
        out = mis.handle(_wp(gcs, 0), 0.01 * k)
        asked.append(out[0][0])
        if out[0][0] == "ack":
            break
    # THEN item 1 is asked RETRIES more times, then the upload is cancelled (it times out)
    assert asked == ["request"] * RETRIES + ["ack"]
    assert out[0] == ("ack", *GCS, ML.MAV_MISSION_OPERATION_CANCELLED, 0)
    assert not mis.uploading and mis.count == 0
