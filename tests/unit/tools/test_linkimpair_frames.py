"""tools/sitl/linkimpair.py frame delay: SERVO_OUTPUT_RAW held N frames and re-stamped (lockstep)."""
from __future__ import annotations

import os

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from tools.sitl.linkimpair import FrameDelay, Impairment  # noqa: E402


def _servo(mav, stamp, base):
    return mav.servo_output_raw_encode(stamp, 0, base, base + 100, base + 200,
                                       0, 0, 0, 0, 0).pack(mav)


def test_answers_are_delayed_by_n_frames_and_carry_the_current_stamp():
    n = 3
    fd = FrameDelay(n)
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    rx = mavlink.MAVLink(None)
    for k in range(10):
        out, delayed = fd.process(_servo(tx, 5000 + k, 1500 + k))
        assert delayed
        (m,) = rx.parse_buffer(out)
        assert m.time_usec == 5000 + k                   # the frame being answered
        src = max(k - n, 0)                              # the first answer fills the first n
        assert (m.servo1_raw, m.servo2_raw, m.servo3_raw) == (1500 + src, 1600 + src, 1700 + src)
        assert m.get_srcSystem() == 1


def test_other_datagrams_pass_unchanged():
    fd = FrameDelay(2)
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    hb = tx.heartbeat_encode(0, 0, 0, 0, 0).pack(tx)
    assert fd.process(hb) == (hb, False)
    assert fd.process(b"\x00garbage") == (b"\x00garbage", False)


def test_delay_frames_is_validated():
    assert Impairment().is_clean
    assert not Impairment(delay_frames=4).is_clean
    with pytest.raises(ValueError):
        Impairment(delay_frames=-1)
    with pytest.raises(ValueError):
        Impairment(delay_frames=2.5)
