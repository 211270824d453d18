"""fc/link.py: the never-raising decoder, plant-link filtering (loopback UDP); the PWM map is
tested with the contract (tests/test_wire_contract.py)."""
from __future__ import annotations

import functools
import math
import os
import select

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fc.link import PlantLink, UdpEndpoint, decode_datagram, load_signing_key, new_codec
from tests.fc_harness import ScriptedPlant, level_meas


@functools.cache
def _good_frame_bytes() -> bytes:
    plant = ScriptedPlant(9)   # only used to build bytes
    try:
        return plant.frame_bytes(level_meas(1.0))
    finally:
        plant.close()
@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_decoder_never_raises_on_garbage(data):
    # GIVEN one codec (as the fc's plant link keeps one) and a datagram of arbitrary bytes
    mav = new_codec(1)
    # WHEN it is decoded (decode_datagram must not raise)
    msgs, n_bad = decode_datagram(mav, data)
    # THEN whatever came out is real messages, and bytes without a MAVLink start byte give none
    assert n_bad >= 0 and all(m.get_type() != "BAD_DATA" for m in msgs)
    if 0xFD not in data and 0xFE not in data:
        assert msgs == []
    # AND the garbage leaves no parser state behind: the next good datagram decodes whole
    msgs, n_bad = decode_datagram(mav, _good_frame_bytes())
    assert n_bad == 0 and [m.get_type() for m in msgs] == ["ATTITUDE", "AOA_SSA", "VFR_HUD"]


def test_decoder_counts_corrupted_frame_and_recovers():
    plant = ScriptedPlant(9)   # only used to build bytes
    good = plant.frame_bytes(level_meas(1.0))
    mav = new_codec(1)
    bad = bytearray(good)
    bad[20] ^= 0xFF                          # CRC now wrong in the first frame
    msgs, n_bad = decode_datagram(mav, bytes(bad))
    assert n_bad >= 1
    msgs, n_bad = decode_datagram(mav, good[:-3])   # last frame (VFR_HUD) truncated
    assert n_bad == 1 and [m.get_type() for m in msgs] == ["ATTITUDE", "AOA_SSA"]
    msgs, n_bad = decode_datagram(mav, good)        # the parser state was reset
    assert n_bad == 0 and [m.get_type() for m in msgs] == ["ATTITUDE", "AOA_SSA", "VFR_HUD"]
    plant.close()


def _wait_readable(sock, timeout=2.0):
    r, _, _ = select.select([sock], [], [], timeout)
    return bool(r)


# fast_io: the compiled receive and answer (libc recvfrom/sendto, fc/frame_calls.py), else
# socket's calls; both must filter, count and answer alike
@pytest.mark.parametrize("fast_io", [True, False])
def test_plant_link_accepts_configured_sysid_then_only_that_address(fast_io):
    ep = UdpEndpoint("127.0.0.1", 0)
    link = PlantLink(ep, plant_sysid=2)
    assert link._fast_io                 # passed its start-up self-check
    link._fast_io = fast_io
    port = ep.address[1]
    meas = np.zeros(14)
    intruder_id = ScriptedPlant(port, sysid=7)
    intruder_id.send_frame(level_meas(0.5))
    assert _wait_readable(ep.sock)
    assert link.read_frame(meas) == -1 and link.counters.rejected_sysid == 1
    plant = ScriptedPlant(port, sysid=2)
    plant.send_frame(level_meas(1.0, alpha_deg=3.0))
    assert _wait_readable(ep.sock)
    assert link.read_frame(meas) == 1_000_000
    assert meas[7] == pytest.approx(math.radians(3.0), rel=1e-6)
    other = ScriptedPlant(port, sysid=2)            # right sysid, other address
    other.send_frame(level_meas(1.002))
    assert _wait_readable(ep.sock)
    assert link.read_frame(meas) == -1 and link.counters.rejected_addr == 1
    plant.send_raw(b"\xfd\x01\x02garbage")
    plant.send_raw(plant.mav.attitude_encode(1004, 0, 0, 0, 0, 0, 0).pack(plant.mav))  # incomplete
    plant.send_frame(level_meas(1.006))
    assert _wait_readable(ep.sock)
    got = -1
    for _ in range(50):
        got = link.read_frame(meas)
        if got >= 0:
            break
        _wait_readable(ep.sock, 0.1)
    assert got == 1_006_000
    assert link.counters.rejected_bad == 1 and link.counters.rejected_incomplete == 1
    assert link.send_servo(got, (1400, 1500, 1600))
    ans = plant.recv_servo(2.0)
    assert ans.time_usec == 1_006_000 and (ans.servo1_raw, ans.servo3_raw) == (1400, 1600)
    # after a data loss the fc allows a restarted plant (new port) to take over once
    link.relock_allowed = True
    other.send_frame(level_meas(0.002))
    assert _wait_readable(ep.sock)
    assert link.read_frame(meas) == 2000 and link.counters.relocks == 1
    assert link.peer == other.sock.getsockname() and not link.relock_allowed
    # AND every datagram, frame and answer was counted: 7 datagrams, 3 frames, 1 answer
    c = link.counters
    assert (c.datagrams, c.frames, c.outputs) == (7, 3, 1)
    assert link.send_servo(2000, (1500, 1500, 1500)) and other.recv_servo(2.0).time_usec == 2000
    assert c.outputs == 2
    for p in (intruder_id, plant, other):
        p.close()
    ep.close()


@pytest.mark.parametrize("fast_io", [True, False])
def test_servo_stamp_wraps_modulo_2_32(fast_io):
    ep = UdpEndpoint("127.0.0.1", 0)
    link = PlantLink(ep)
    link._fast_io = fast_io
    plant = ScriptedPlant(ep.address[1])
    plant.send_frame(level_meas(5000.0))           # 5e9 us > 2^32
    assert _wait_readable(ep.sock)
    stamp = link.read_frame(np.zeros(14))
    assert stamp == 5_000_000_000
    link.send_servo(stamp, (1500, 1500, 1500))
    assert plant.recv_servo(2.0).time_usec == stamp % (1 << 32)
    plant.close()
    ep.close()


def test_stamped_receive_into_the_buffer_gives_frame_and_kernel_stamp():
    # GIVEN a plant link whose endpoint asks the kernel for receive stamps (real time)
    import time
    ep = UdpEndpoint("127.0.0.1", 0)
    link = PlantLink(ep)
    assert ep.enable_rx_timestamps()
    plant = ScriptedPlant(ep.address[1])
    t0 = time.time_ns()
    plant.send_frame(level_meas(2.0, alpha_deg=4.0))
    assert _wait_readable(ep.sock)
    # WHEN the frame is read (recvmsg_into the link's buffer, decoded there)
    meas = np.zeros(14)
    # THEN it decodes, and its kernel stamp is the arrival time (wall clock ns)
    assert link.read_frame(meas) == 2_000_000
    assert meas[7] == pytest.approx(math.radians(4.0), rel=1e-6)
    assert t0 <= link.frame_rx_ns <= time.time_ns()
    plant.close()
    ep.close()


def test_signing_key_file_permissions(tmp_path):
    path = tmp_path / "key"
    path.write_text("s3cret\n")
    os.chmod(path, 0o644)
    with pytest.raises(PermissionError):
        load_signing_key(str(path))
    os.chmod(path, 0o600)
    import hashlib
    assert load_signing_key(str(path)) == hashlib.sha256(b"s3cret").digest()
