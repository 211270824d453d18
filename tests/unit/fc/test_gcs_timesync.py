"""Unit tier: the TIMESYNC service (fc/gcs_timesync.py): a request in, the answer out."""
from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"
from fc.gcs_timesync import TimesyncTargeted, answer, request_targets  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from tests.fc_harness import received  # noqa: E402


def test_a_request_is_answered_with_our_time_and_its_own_ts1_mirrored_to_the_requester():
    # GIVEN a request (tc1 = 0) with the requester's time in ts1 (ns)
    req = received(ML.MAVLink_timesync_message(0, 123_456_789_012))
    # WHEN the fc's time base reads 5.5 s
    reply = answer(req, 5_500_000_000, sysid=1, compid=1)
    # THEN tc1 = our time (ns), ts1 mirrored, targeted at the requester (current common.xml)
    assert reply.tc1 == 5_500_000_000 and reply.ts1 == 123_456_789_012
    assert (reply.target_system, reply.target_component) == (255, 190)
    # and on the wire it is a TIMESYNC that a reader with the old dialect decodes, and whose
    # extension bytes carry the targets
    back = received(reply, sysid=1, compid=1)
    assert back.get_type() == "TIMESYNC" and back.tc1 == 5_500_000_000
    assert request_targets(back) == (255, 190)


def test_an_answer_or_a_request_for_another_system_is_not_answered():
    assert answer(received(ML.MAVLink_timesync_message(7, 8)), 1, 1, 1) is None   # tc1 != 0
    other = received(TimesyncTargeted(0, 99, 42, 1))
    assert request_targets(other) == (42, 1)
    assert answer(other, 1, sysid=1, compid=1) is None
    mine = received(TimesyncTargeted(0, 99, 1, 1))
    assert answer(mine, 1, sysid=1, compid=1).ts1 == 99
