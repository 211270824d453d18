"""The plant's MAVLink link: lean framing identical to pymavlink's codec, strict
acceptance of servo frames, robustness against malformed datagrams (loopback sockets)."""
import math
import os
import socket
import time

import numpy as np
import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

from plant_sim.link import PlantLink, PwmMap  # noqa: E402

DEG = math.pi / 180.0


@pytest.fixture()
def pair():
    fc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc.bind(("127.0.0.1", 0))
    fc.settimeout(2.0)
    link = PlantLink(fc.getsockname(), ("127.0.0.1", 0), PwmMap(1000, 1500, 2000, 20.0 * DEG))
    try:
        yield link, fc
    finally:
        link.close()
        fc.close()


def test_sensor_datagram_is_three_codec_frames(pair):
    link, fc = pair
    assert link.lean
    rng = np.random.default_rng(3)
    parser = mavlink.MAVLink(None)
    ref = mavlink.MAVLink(None, srcSystem=2, srcComponent=1)
    for i in range(50):
        meas = rng.normal(size=14)
        if i % 5 == 0:
            meas[:] = 0.0           # exercises MAVLink 2 trailing-zero truncation
        meas[13] = abs(meas[13])
        stamp = int(rng.integers(0, 2**40)) if i % 5 else 0
        link.build_sensors(stamp, meas, 37.0)
        assert link.send_sensors()
        data, addr = fc.recvfrom(2048)
        assert addr == link.local_addr
        msgs = parser.parse_buffer(data)
        assert [m.get_type() for m in msgs] == ["ATTITUDE", "AOA_SSA", "VFR_HUD"]
        att, aoa, hud = msgs
        assert att.get_srcSystem() == 2 and att.get_srcComponent() == 1
        assert aoa.time_usec == stamp and att.time_boot_ms == (stamp // 1000) % 2**32
        assert att.roll == pytest.approx(meas[1], rel=1e-6, abs=1e-30)
        assert aoa.AOA == pytest.approx(meas[7] / DEG, rel=1e-6, abs=1e-30)
        assert hud.alt == pytest.approx(meas[10], rel=1e-6, abs=1e-30)
        assert hud.throttle == 37
        # byte-identical to the codec's own message objects
        ref.seq = att.get_seq()
        expect = b""
        for m in (ref.attitude_encode(att.time_boot_ms, meas[1], meas[2], meas[3], meas[4], meas[5], meas[6]),
                  ref.aoa_ssa_encode(stamp, meas[7] / DEG, meas[8] / DEG),
                  ref.vfr_hud_encode(meas[9], meas[12], hud.heading, 37, meas[10], meas[11])):
            expect += m.pack(ref)
            ref.seq = (ref.seq + 1) & 0xFF
        assert data == expect


def _servo(sysid, stamp, s1, s2, s3, seq=0):
    m = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
    m.seq = seq
    return m.servo_output_raw_encode(stamp, 0, s1, s2, s3, 0, 0, 0, 0, 0).pack(m)


def _poll_until(link, want, n_expected_datagrams):
    deadline = time.monotonic() + 2.0
    res = (0, False)
    while link.rx_datagrams < n_expected_datagrams and time.monotonic() < deadline:
        link.wait_readable(0.05)
        acc, match = link.poll_for(want)
        res = (res[0] + acc, res[1] or match)
    return res


def test_servo_frames_accepted_only_from_fc_and_sysid(pair):
    link, fc = pair
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    other.bind(("127.0.0.1", 0))
    try:
        other.sendto(_servo(1, 2000, 2000, 2000, 2000), link.local_addr)     # foreign address
        fc.sendto(_servo(9, 2000, 2000, 2000, 2000), link.local_addr)        # wrong system id
        fc.sendto(_servo(1, 1000, 1000, 1000, 1000), link.local_addr)        # stale stamp
        fc.sendto(_servo(1, 2000, 1750, 0, 1250), link.local_addr)           # the answer
        acc, match = _poll_until(link, 2000, 4)
    finally:
        other.close()
    assert match and acc == 2
    assert link.rejected_source == 1 and link.rejected_sysid == 1
    assert link.cmd_rad[0] == pytest.approx(10.0 * DEG)
    assert link.cmd_rad[1] == 0.0            # channel value 0: keep the previous command
    assert link.cmd_rad[2] == pytest.approx(-10.0 * DEG)


def test_decode_fast_path_agrees_with_codec_and_rejects_damage(pair):
    link, _ = pair
    rng = np.random.default_rng(11)
    for _ in range(200):
        s = [int(v) for v in rng.integers(0, 2500, size=3)]
        stamp = int(rng.integers(0, 2**32))
        frame = _servo(1, stamp, *s, seq=int(rng.integers(0, 256)))
        assert link.decode_servo(frame) == (1, stamp, s[0], s[1], s[2], 0)
        bad = bytearray(frame)
        bad[int(rng.integers(1, len(bad)))] ^= 1 << int(rng.integers(0, 8))
        got = link.decode_servo(bytes(bad))
        assert got is None                                  # every byte after the magic is CRC-covered
    two = _servo(1, 5, 1500, 1500, 1500) * 2
    assert link.decode_servo(two) is None                  # general parser handles these
    assert link.decode_servo(_servo(1, 5, 1500, 1500, 1500)[:-1]) is None


def test_malformed_input_never_raises_and_is_counted(pair):
    link, fc = pair
    rng = np.random.default_rng(5)
    good = _servo(1, 4000, 1600, 1400, 1500)
    sent = 0
    for i in range(300):
        if i % 3 == 0:
            data = bytes(rng.integers(0, 256, size=int(rng.integers(1, 300)), dtype=np.uint8))
        elif i % 3 == 1:
            b = bytearray(good)
            for _ in range(3):
                b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
            data = bytes(b)
        else:
            data = b"\xfd" + bytes(rng.integers(0, 256, size=int(rng.integers(0, 20)), dtype=np.uint8))
        fc.sendto(data, link.local_addr)
        sent += 1
    fc.sendto(good, link.local_addr)
    acc, match = _poll_until(link, 4000, sent + 1)
    assert match
    assert link.rx_datagrams == sent + 1
    assert link.rejected_malformed + link.ignored_messages + link.rejected_sysid + acc >= sent // 2
    assert link.cmd_rad[0] == pytest.approx(4.0 * DEG)
