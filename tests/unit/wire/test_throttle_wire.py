"""Throttle on SERVO_OUTPUT_RAW servo4 (docs/wire.md s. 3): fc.link packs it, plant_sim.link
decodes it, over loopback UDP between the two real links."""
from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from fc.link import PlantLink as FcPlantLink, UdpEndpoint, _pwm4, throttle_to_pwm  # noqa: E402
from hyfc_wire.frame_kernels import servo_frame  # noqa: E402
from plant_sim.link import PlantLink, PwmMap  # noqa: E402

DEG = math.pi / 180.0


@pytest.fixture()
def links():
    ep = UdpEndpoint("127.0.0.1", 0)
    fc = FcPlantLink(ep, plant_sysid=2)
    plant = PlantLink(ep.address, ("127.0.0.1", 0), PwmMap(1000, 1500, 2000, 20.0 * DEG))
    try:
        yield fc, plant
    finally:
        plant.close()
        ep.close()


def _exchange(fc, plant, stamp_us, pwm):
    """Plant sends one sensor frame, the fc answers with ``pwm``; returns whether the plant
    applied the answer (lockstep poll on the stamp)."""
    meas = np.zeros(14)
    meas[9] = 2250.0
    plant.build_sensors(stamp_us, meas, 42.0)
    assert plant.send_sensors()
    got = -1
    deadline = time.monotonic() + 2.0
    while got < 0 and time.monotonic() < deadline:
        got = fc.read_frame(np.zeros(14))
    assert got == stamp_us
    assert fc.send_servo(got, pwm)
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        plant.wait_readable(0.05)
        _acc, match = plant.poll_for(stamp_us % (1 << 32))
        if match:
            return True
    return False


def test_servo4_round_trip_fc_to_plant(links):
    fc, plant = links
    assert fc._fast and plant.lean        # the compiled and lean paths are the ones tested
    # GIVEN no throttle channel (the paper's 3-channel answer): the plant has no throttle
    assert _exchange(fc, plant, 2000, (1500, 1600, 1400))
    assert plant.cmd_throttle == -1.0
    assert plant.cmd_rad[1] == pytest.approx(4.0 * DEG)
    # WHEN the fc sends a throttle on servo4, THEN the plant latches it
    assert _exchange(fc, plant, 4000, (1500, 1500, 1500, throttle_to_pwm(0.65)))
    assert plant.cmd_throttle == pytest.approx(0.65)
    # a later frame with servo4 = 0 (no output) keeps the last throttle
    assert _exchange(fc, plant, 6000, (1500, 1500, 1500, 0))
    assert plant.cmd_throttle == pytest.approx(0.65)
    assert _exchange(fc, plant, 8000, (1500, 1500, 1500, 2000))
    assert plant.cmd_throttle == 1.0


def test_servo4_bytes_match_codec_and_three_channels_are_unchanged(links):
    fc, plant = links
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    for seq, s4 in ((0, 0), (9, 1422), (200, 2000)):
        codec.seq = seq
        ref = codec.servo_output_raw_encode(123456, 0, 1500, 1510, 1490, s4, 0, 0, 0, 0).pack(codec)
        assert _framed(fc, seq, 123456, (1500, 1510, 1490, s4)) == ref
        assert plant.decode_servo(ref) == (1, 123456, 1500, 1510, 1490, s4)
    # servo4 = 0 truncates to the very bytes a 3-channel frame had before the throttle existed
    assert _framed(fc, 5, 77, (1500, 1500, 1500, 0)) == _framed(fc, 5, 77, (1500, 1500, 1500))


def _framed(fc, seq, stamp_us, pwm_us) -> bytes:
    """The SERVO_OUTPUT_RAW bytes the fc's compiled framing gives for ``send_servo``."""
    n = servo_frame(fc._tx_u8, seq, fc.sysid, fc.compid, stamp_us, _pwm4(pwm_us))
    return bytes(fc._tx_u8[:n])


def test_general_parser_path_decodes_servo4(links):
    fc, plant = links
    plant.lean = False            # force pymavlink's parser (the fallback path)
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frame = codec.servo_output_raw_encode(3000, 0, 1500, 1500, 1500, 1250, 0, 0, 0, 0).pack(codec)
    assert fc.endpoint.send(frame, plant.local_addr)        # from the fc's own address
    match = False
    deadline = time.monotonic() + 2.0
    while not match and time.monotonic() < deadline:
        plant.wait_readable(0.05)
        match = plant.poll_for(3000)[1]
    assert match and plant.cmd_throttle == pytest.approx(0.25)
