"""The plant's lockstep frame in one compiled call (plant_sim/frame_path.py, issue 24) against
the Python path it replaces: the same datagrams sent, the same truth log, the same counters,
with GNSS frames, throttle commands, channels left at 0, stale answers, datagrams only the
codec's general parser takes (one of them the answer), garbage, a foreign system id and a
foreign source address.

Both runs are ``plant_sim.process.run`` in this process (the main thread: it installs signal
handlers) against a scripted fc stand-in on a thread.
"""
import json
import logging
import math
import socket
import threading

import numpy as np
import pytest

from hyfc_wire.codec import mavlink, new_codec
from hyfc_wire.pwm import DEFAULT_PWM, throttle_to_pwm
from plant_sim import frame_path as fpm
from plant_sim import truthlog
from plant_sim import process
from plant_sim.process import RunConfig, run
from plant_sim.scenario import load

DEG = math.pi / 180.0
FRAMES = 300            # 0.6 s at 500 Hz: GNSS samples at 10 Hz, a truth block flushed


class _Fc:
    """Answers each sensor datagram with SERVO_OUTPUT_RAW echoing its stamp (a damper on the
    measured rates), and now and then something harder; keeps every datagram received."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.addr = self.sock.getsockname()
        self.foreign = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.foreign.bind(("127.0.0.1", 0))
        self.mav = new_codec(1)
        self.other = new_codec(77)
        self.rx = []
        self.done = False
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _servo(self, mav, stamp, pwm):
        m = mav.servo_output_raw_encode(stamp % (1 << 32), 0, *pwm, 0, 0, 0, 0)
        b = m.pack(mav)
        mav.seq = (mav.seq + 1) & 0xFF
        return b

    def _serve(self):
        n = 0
        while not self.done:
            try:
                data, peer = self.sock.recvfrom(2048)
            except (socket.timeout, OSError):
                continue
            msgs = self.mav.parse_buffer(data) or []
            att = next((m for m in msgs if m.get_type() == "ATTITUDE"), None)
            aoa = next((m for m in msgs if m.get_type() == "AOA_SSA"), None)
            if att is None or aoa is None:          # the goodbye HEARTBEAT
                continue
            self.rx.append(bytes(data))
            pitch = 2.0 * DEG - 0.5 * att.pitchspeed
            roll = -0.3 * att.rollspeed
            pwm = [DEFAULT_PWM.to_pwm(pitch - roll), DEFAULT_PWM.to_pwm(pitch + roll),
                   DEFAULT_PWM.to_pwm(0.4 * att.yawspeed),
                   throttle_to_pwm(0.5 + 0.001 * (n % 50)) if n % 7 == 0 else 0]
            if n % 11 == 3:
                pwm[1] = 0                          # a channel 0 keeps its command
            stamp = aoa.time_usec
            if n % 13 == 5:                         # a stale answer first
                self.sock.sendto(self._servo(self.mav, stamp - 2000, (1000, 2000, 1500, 0)), peer)
            if n % 17 == 6:                         # garbage, another sysid, another source
                self.sock.sendto(b"\xfd\x09garbage-not-mavlink", peer)
                self.sock.sendto(self._servo(self.other, stamp, (1000, 1000, 1000, 0)), peer)
                self.foreign.sendto(self._servo(self.mav, stamp, (2000, 2000, 2000, 0)), peer)
            answer = self._servo(self.mav, stamp, pwm)
            if n % 19 == 9:                         # the answer behind a HEARTBEAT: general parser
                hb = self.mav.heartbeat_encode(mavlink.MAV_TYPE_GENERIC,
                                               mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                answer = hb.pack(self.mav) + answer
                self.mav.seq = (self.mav.seq + 1) & 0xFF
            self.sock.sendto(answer, peer)
            n += 1

    def close(self):
        self.done = True
        self.thread.join(2.0)
        self.sock.close()
        self.foreign.close()


def _run(tmp_path, name, compiled, scenario="paper", truth_full_rate_s=60.0):
    fc = _Fc()
    out = tmp_path / name
    out.mkdir()
    cfg = RunConfig(mode="lockstep", fc_addr=("127.0.0.1", fc.addr[1]),
                    bind_addr=("127.0.0.1", 0), out_dir=out, duration_s=FRAMES * 0.002, seed=3,
                    progress_every_s=0.0, quiet=True, compiled_frame=compiled,
                    truth_full_rate_s=truth_full_rate_s, truth_tail_hz=50.0)
    log = logging.getLogger(f"test_plant_frame_path.{name}")
    log.addHandler(logging.NullHandler())
    log.propagate = False
    try:
        stats = run(load(scenario), cfg, log)
    finally:
        fc.close()
    summary = json.loads((out / "plant_summary.json").read_text())
    return stats, summary, fc.rx, out


@pytest.mark.skipif(not fpm.FAST_IO, reason="NUMBA_DISABLE_JIT: no compiled frame path")
@pytest.mark.parametrize("scenario,full_s", [("paper", 60.0), ("cruise", 0.1)])
def test_compiled_frame_matches_python_path(tmp_path, monkeypatch, scenario, full_s):
    s_py, sum_py, rx_py, out_py = _run(tmp_path, "py", False, scenario, full_s)

    def no_python_path(*args):
        raise AssertionError("the compiled run took the Python path")
    monkeypatch.setattr(process, "_lockstep_python", no_python_path)
    s_c, sum_c, rx_c, out_c = _run(tmp_path, "c", True, scenario, full_s)
    assert s_c.exit_reason == s_py.exit_reason == "completed"
    assert len(rx_c) == len(rx_py) == FRAMES
    for k, (a, b) in enumerate(zip(rx_py, rx_c)):
        assert a == b, f"sensor datagram {k} differs"
    assert sum(1 for d in rx_c if len(d) > 150) >= 2          # GNSS frames among them
    for key in ("frames", "rerequests", "stale_commands", "aero_clip_frames", "truth_rows",
                "truth_rows_decimated", "gnss_samples", "frames_sent", "rx_datagrams",
                "servo_frames_accepted", "servo_frames_applied", "rejected_malformed",
                "rejected_source", "rejected_sysid", "ignored_messages", "send_errors",
                "sim_time_s"):
        assert sum_c[key] == sum_py[key], key
    assert sum_c["stale_commands"] > 0 and sum_c["rejected_source"] > 0
    assert sum_c["rejected_sysid"] > 0 and sum_c["ignored_messages"] > 0
    assert sum_c["rejected_malformed"] > 0
    assert (out_c / "truth.npz").read_bytes() == (out_py / "truth.npz").read_bytes()
    t = truthlog.load(out_c)
    assert np.ptp(t["delta_cmd_right_rad"]) > 0.0


@pytest.mark.skipif(not fpm.FAST_IO, reason="NUMBA_DISABLE_JIT: no compiled frame path")
def test_kernel_codes_leave_the_state_alone(tmp_path):
    """A datagram the compiled decoder rejects, another system id or a stale stamp: a code
    (< 0), nothing stepped, the counts kept; a match steps once."""
    from hyfc_wire.pwm import PwmMap
    from plant_sim import dynamics as dy
    from plant_sim.link import PlantLink, ServoResponder
    from plant_sim.sim import PlantSim
    from plant_sim.truthlog import TruthWriter
    sim = PlantSim(load("paper"))
    resp = ServoResponder()
    link = PlantLink(("127.0.0.1", resp.addr[1]), ("127.0.0.1", 0),
                     PwmMap(1000, 1500, 2000, sim.p[dy.P_ACT_LIMIT]))
    writer = TruthWriter(tmp_path, sim.TRUTH_NAMES, block_rows=4)
    try:
        fp = fpm.FramePath(sim, link, writer, 1e-4)
        sim.measure(sim.last_meas)
        fp.enter()
        x0 = sim.x.copy()
        mode = fpm.MODE_DECODE | fpm.MODE_ENCODE
        for data, code in ((b"\xfd\x09garbage-not-mavlink", fpm.R_FALLBACK),
                           (resp.servo_frame(0, (1600, 1400, 1500), sysid=9), fpm.R_SYSID),
                           (resp.servo_frame(2000, (1600, 1400, 1500)), fpm.R_STALE)):
            fp.set_rx_len(link.put_rx(data))
            assert fpm.lockstep_frame_p(fp.addr, 0, mode, 0) == code
            assert np.array_equal(sim.x, x0, equal_nan=True)
        fp.set_rx_len(link.put_rx(resp.servo_frame(0, (1600, 1400, 1500))))
        assert fpm.lockstep_frame_p(fp.addr, 0, mode, 0) >= 0
        fp.leave()
        assert sim.frames == 1 and writer.rows == 1 and link.cmd_count == 2
        assert link.rejected_sysid == 1 and link.applied_count == 1
        assert link.cmd_rad == [link.pwm.to_rad(1600), link.pwm.to_rad(1400), 0.0]
        assert sim.x[dy.X_STEP] == x0[dy.X_STEP] + sim.n_sub
    finally:
        writer.close()
        link.close()
        resp.close()


@pytest.mark.parametrize("every", [1, 3, 50])
@pytest.mark.parametrize("delay", [0, 1, 7, 50, 120])
def test_gnss_next_event_is_the_first_frame_update_acts_on(every, delay):
    """The compiled loop frames in Python only from ``GnssSensor.next_event``: before it,
    ``update`` must return None and change nothing (no capture, no sample)."""
    from plant_sim.sim import PlantSim
    sim = PlantSim(load("paper"))
    g = sim.gnss
    g.every, g.delay = every, delay
    g.reset()
    nxt = g.next_event(0)
    acted = 0
    for k in range(400):
        before = (len(g._pending), g.samples)
        out = g.update(k, sim.x)
        changed = out is not None or (len(g._pending), g.samples) != before
        assert k >= nxt or not changed, k
        if k >= nxt:
            acted += changed
            nxt = g.next_event(k + 1)
    assert acted >= 400 // every - 1
