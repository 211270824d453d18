"""fc/mission.py: the mission protocol state machine alone (no sockets, no clock).

GIVEN a ground station's messages (built and packed with a real MAVLink codec) WHEN the state
machine handles them THEN its outputs are the spec's answers and the stored mission changes
only on a complete, valid upload.
"""
import math

import pytest

from fc.link import mavlink as ML, new_codec
from fc.mission import CMD_CHANGE_SPEED, CMD_WAYPOINT, Mission, encode

GCS = (255, 190)


@pytest.fixture()
def gcs():
    return new_codec(*GCS)


def _m(gcs, name, *args, **kw):
    msg = getattr(gcs, name + "_encode")(*args, **kw)
    msg.pack(gcs)                      # sets the header (source system/component)
    return msg


def _wp(gcs, seq, lat=35.0, lon=-117.0, alt=28000.0, frame=ML.MAV_FRAME_GLOBAL, cmd=CMD_WAYPOINT,
        p=(0.0, 0.0, 0.0, math.nan)):
    return _m(gcs, "mission_item_int", 1, 1, seq, frame, cmd, 0, 1, *p,
              int(round(lat * 1e7)), int(round(lon * 1e7)), alt, 0)


def _upload(gcs, mis, items, t=0.0):
    """Answer every request with the requested item; returns the final outputs."""
    out = mis.handle(_m(gcs, "mission_count", 1, 1, len(items), 0), t)
    while out and out[0][0] == "request":
        out = mis.handle(items[out[0][3]], t)
    return out


def _three(gcs):
    return [_wp(gcs, 0, 35.3), _wp(gcs, 1, 35.0, p=(2.0, 2300.0, -1.0, 0.0), cmd=CMD_CHANGE_SPEED,
                                     frame=ML.MAV_FRAME_MISSION),
            _wp(gcs, 2, 35.6, -116.9, 2000.0, frame=ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)]


def test_upload_requests_each_item_and_acks(gcs):
    items = _three(gcs)
    items[1] = _wp(gcs, 1, cmd=CMD_CHANGE_SPEED, frame=ML.MAV_FRAME_MISSION,
                   p=(0.0, 2300.0, -1.0, 0.0))
    mis = Mission()
    out = mis.handle(_m(gcs, "mission_count", 1, 1, 3, 0), 0.0)
    assert out == [("request", *GCS, 0)]
    out = mis.handle(items[0], 0.1)
    assert out == [("request", *GCS, 1)]
    assert mis.count == 0                       # nothing replaced before the end
    out = mis.handle(items[1], 0.2)
    out = mis.handle(items[2], 0.3)
    assert out[0] == ("ack", *GCS, ML.MAV_MISSION_ACCEPTED, 0)
    assert ("current",) in out
    assert mis.count == 3 and mis.current == 0 and mis.uploads_ok == 1
    assert mis.item(2)["frame"] == ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    assert mis.item(2)["x"] == 356000000 and mis.item(1)["param2"] == 2300.0


def test_download_returns_what_was_uploaded(gcs):
    items = _three(gcs)
    items[1] = _wp(gcs, 1, cmd=CMD_CHANGE_SPEED, frame=ML.MAV_FRAME_MISSION, p=(0.0, 2300.0, -1.0, 0.0))
    mis = Mission()
    _upload(gcs, mis, items)
    assert mis.handle(_m(gcs, "mission_request_list", 1, 1, 0), 1.0) == [("count", *GCS, 3, 0)]
    fc = new_codec(1, 1)
    for seq, sent in enumerate(items):
        out = mis.handle(_m(gcs, "mission_request_int", 1, 1, seq, 0), 1.0)
        got = encode(fc, mis, out[0], active=False)
        assert got.get_type() == "MISSION_ITEM_INT"
        for f in ("seq", "frame", "command", "x", "y", "z", "param1", "param2"):
            assert getattr(got, f) == getattr(sent, f), f
    out = mis.handle(_m(gcs, "mission_request_int", 1, 1, 3, 0), 1.0)
    assert out == [("ack", *GCS, ML.MAV_MISSION_INVALID_SEQUENCE, 0)]


@pytest.mark.parametrize("item, code", [
    (dict(cmd=ML.MAV_CMD_NAV_LOITER_UNLIM), ML.MAV_MISSION_UNSUPPORTED),
    (dict(cmd=ML.MAV_CMD_NAV_TAKEOFF), ML.MAV_MISSION_UNSUPPORTED),
    (dict(frame=ML.MAV_FRAME_LOCAL_NED), ML.MAV_MISSION_UNSUPPORTED_FRAME),
    (dict(lat=95.0), ML.MAV_MISSION_INVALID_PARAM5_X),
    (dict(lon=-190.0), ML.MAV_MISSION_INVALID_PARAM6_Y),
    (dict(alt=math.nan), ML.MAV_MISSION_INVALID_PARAM7),
    (dict(cmd=CMD_CHANGE_SPEED, p=(0.0, -5.0, -1.0, 0.0)), ML.MAV_MISSION_INVALID_PARAM2),
    (dict(cmd=CMD_CHANGE_SPEED, p=(3.0, 2300.0, -1.0, 0.0)), ML.MAV_MISSION_INVALID_PARAM1),
])
def test_refused_item_gets_its_error_and_keeps_the_mission(gcs, item, code):
    mis = Mission()
    _upload(gcs, mis, [_wp(gcs, 0, 35.1)])
    assert mis.count == 1
    out = _upload(gcs, mis, [_wp(gcs, 0, 35.2), _wp(gcs, 1, **item)])
    assert out[0] == ("ack", *GCS, code, 0)
    assert mis.count == 1 and mis.item(0)["x"] == 351000000 and not mis.uploading


def test_out_of_range_sequence_is_refused(gcs):
    mis = Mission()
    mis.handle(_m(gcs, "mission_count", 1, 1, 2, 0), 0.0)
    out = mis.handle(_wp(gcs, 5), 0.0)
    assert out[0] == ("ack", *GCS, ML.MAV_MISSION_INVALID_SEQUENCE, 0)
    assert mis.count == 0 and not mis.uploading


def test_out_of_order_item_is_requested_again(gcs):
    mis = Mission()
    mis.handle(_m(gcs, "mission_count", 1, 1, 3, 0), 0.0)
    mis.handle(_wp(gcs, 0), 0.0)
    assert mis.handle(_wp(gcs, 2), 0.1) == [("request", *GCS, 1)]
    assert mis.handle(_wp(gcs, 0), 0.2) == [("request", *GCS, 1)]
    assert mis.uploading


def test_timeout_retries_then_cancels_and_keeps_mission(gcs):
    mis = Mission(retry_s=1.0, retries=3)
    _upload(gcs, mis, [_wp(gcs, 0, 35.1)])
    mis.handle(_m(gcs, "mission_count", 1, 1, 2, 0), 10.0)
    mis.handle(_wp(gcs, 0, 35.2), 10.0)           # item 1 never comes
    assert mis.tick(10.5) == []
    resent = [mis.tick(11.0 + k) for k in range(3)]
    assert resent == [[("request", *GCS, 1)]] * 3
    out = mis.tick(14.0)
    assert out[0] == ("ack", *GCS, ML.MAV_MISSION_OPERATION_CANCELLED, 0)
    assert mis.count == 1 and mis.item(0)["x"] == 351000000 and mis.uploads_failed == 1
    assert mis.tick(20.0) == []


def test_other_partner_denied_during_upload_and_count_limits(gcs):
    other = new_codec(254, 190)
    mis = Mission(capacity=4)
    mis.handle(_m(gcs, "mission_count", 1, 1, 2, 0), 0.0)
    out = mis.handle(_m(other, "mission_count", 1, 1, 1, 0), 0.0)
    assert out == [("ack", 254, 190, ML.MAV_MISSION_DENIED, 0)]
    assert mis.handle(_wp(other, 0), 0.0) == []   # not its upload: ignored
    out = Mission(capacity=4).handle(_m(gcs, "mission_count", 1, 1, 5, 0), 0.0)
    assert out == [("ack", *GCS, ML.MAV_MISSION_NO_SPACE, 0)]
    out = mis.handle(_m(gcs, "mission_count", 1, 1, 3, ML.MAV_MISSION_TYPE_FENCE), 0.0)
    assert out == [("ack", *GCS, ML.MAV_MISSION_UNSUPPORTED, ML.MAV_MISSION_TYPE_FENCE)]


def test_legacy_mission_item_float_degrees(gcs):
    mis = Mission()
    mis.handle(_m(gcs, "mission_count", 1, 1, 1, 0), 0.0)
    out = mis.handle(_m(gcs, "mission_item", 1, 1, 0, ML.MAV_FRAME_GLOBAL, CMD_WAYPOINT, 0, 1,
                        0, 0, 0, 0, 35.25, -117.5, 29000.0, 0), 0.0)
    assert out[0][3] == ML.MAV_MISSION_ACCEPTED
    assert mis.item(0)["x"] == 352500000 and mis.item(0)["y"] == -1175000000


def test_clear_set_current_advance_and_states(gcs):
    mis = Mission()
    assert mis.current_fields(False)[2] == ML.MISSION_STATE_NO_MISSION
    _upload(gcs, mis, [_wp(gcs, 0), _wp(gcs, 1), _wp(gcs, 2)])
    assert mis.current_fields(True) == (0, 3, ML.MISSION_STATE_ACTIVE, 1)
    ok, out = mis.set_current(2)
    assert ok and mis.current == 2 and out == [("current",)]
    ok, out = mis.set_current(3)
    assert not ok and out[0][0] == "text" and mis.current == 2
    assert mis.advance(1) == []                   # not the current item
    assert mis.advance(2) == [("reached", 2), ("current",)]
    assert mis.finished and mis.current_fields(True)[2] == ML.MISSION_STATE_COMPLETE
    out = mis.handle(_m(gcs, "mission_clear_all", 1, 1, 0), 0.0)
    assert out[0] == ("ack", *GCS, ML.MAV_MISSION_ACCEPTED, 0) and mis.count == 0
    assert mis.handle(_m(gcs, "mission_request_list", 1, 1, 0), 0.0) == [("count", *GCS, 0, 0)]
    # fence and rally lists are empty (QGroundControl asks for them on connect)
    assert mis.handle(_m(gcs, "mission_request_list", 1, 1, 1), 0.0) == [("count", *GCS, 0, 1)]
