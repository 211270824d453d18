"""Unit tier: the GCS link's per-peer stream schedules and the STATUSTEXT/log rate limiter.

``GcsLink`` runs in-process against a stand-in vehicle; time is passed in (``now_s``), so the
peer time-out is checked without waiting for it.
"""
from __future__ import annotations

import os
import socket

from types import SimpleNamespace

import numpy as np

os.environ["MAVLINK20"] = "1"
from fc.gcs import PEER_TIMEOUT_S, STREAM_DEFAULTS_S, GcsLink  # noqa: E402
from fc.link import G_N, LinkCounters  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from fc.mission import Mission  # noqa: E402
from fc.modes import ModeManager  # noqa: E402
from fc.params import build_table  # noqa: E402
from fc.ratelimit import RateLimiter  # noqa: E402
from fc.vehicle_view import VehicleView  # noqa: E402
from tests.fc_harness import free_udp_port  # noqa: E402


class _Vehicle:
    """What GcsLink reads of the vehicle (fc/vehicle_view.py ``VehicleView``), at rest."""

    sysid, compid = 1, 1

    def __init__(self) -> None:
        self.params = build_table()
        self.modes = ModeManager()
        self.meas = np.zeros(14)
        self.meas_stamp_us = 0
        self.pwm_us = [1500, 1500, 1500, 0]
        self.plant = SimpleNamespace(gps_samples=0, gps=np.zeros(G_N), counters=LinkCounters())
        self.mission = Mission()

    def set_param(self, name, value):
        return self.params.set(name, value)

    def save_params(self, done):
        return False                       # no parameter file: answered at once

    def request_mode(self, mode):
        return self.modes.request_mode(mode)

    def arm(self, armed, forced=False):
        return self.modes.set_armed(armed, data_ok=True)

    def set_attitude_command(self, alpha_deg, beta_deg, mu_deg):
        return "no attitude commands at rest"

    def set_guidance_targets(self, h_m=None, chi_rad=None, V_m_s=None):
        return "no guidance at rest"

    def change_speed(self, v_m_s):
        return "no guidance at rest"

    def go_to(self, lat_deg, lon_deg, h_m, v_m_s):
        return "no guidance at rest"

    def orbit(self, lat_deg, lon_deg, radius_m, h_m):
        return "no guidance at rest"

    def debug_vectors(self):
        return [(b"CMD_DEG", (0.0, 0.0, 0.0))] * 3

    def named_values(self):
        return [(b"GAMMA_DEG", 0.0)]

    def health_failed_bits(self):
        return 0

    def error_counts(self):
        return (0, 0, 0, 0, 0)

    def load_permille(self):
        return 0

    def throttle_percent(self):
        return 0

    def nav_controller_output(self):
        return None


def test_the_stub_vehicle_is_a_vehicle_view():
    assert isinstance(_Vehicle(), VehicleView)
    # a vehicle missing a member GcsLink reads is not one
    v = _Vehicle()
    del v.mission
    assert not isinstance(v, VehicleView)


class _Null:
    def write(self, _b):
        return None


def test_a_peer_rate_request_is_its_own_and_is_forgotten_with_the_peer():
    out_port = free_udp_port()
    link = GcsLink(_Vehicle(), ("127.0.0.1", free_udp_port()), [("127.0.0.1", out_port)])
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    try:
        tx = ML.MAVLink(_Null(), srcSystem=255, srcComponent=190)
        att = ML.MAVLINK_MSG_ID_ATTITUDE
        peer.sendto(tx.command_long_encode(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0, att, -1,
                                           0, 0, 0, 0, 0).pack(tx), link.endpoint.address)
        for _ in range(100):                       # the datagram is on loopback: read it
            if link.poll(100.0):
                break
        addr = ("127.0.0.1", peer.getsockname()[1])
        assert addr in link.peers and addr in link.links
        assert link.links[addr].intervals[att] == -1.0
        assert link.intervals[att] == STREAM_DEFAULTS_S[att]      # the outputs' schedule
        link.service(100.0 + PEER_TIMEOUT_S / 2)                  # still heard recently
        assert addr in link.links
        link.service(100.0 + PEER_TIMEOUT_S + 1.0)                # silent too long
        assert addr not in link.peers and addr not in link.links
    finally:
        peer.close()
        link.close()


def test_limiter_lets_a_text_once_per_burst_and_summarises_the_repeats():
    lim = RateLimiter(rate_hz=2.0, burst=10.0, quiet_s=2.0)
    sent = [t for t in range(100) if lim.allow(t * 0.01, 4, "refused: X")]
    assert sent == [0]
    assert lim.summaries(0.99 + 1.0) == []                        # burst not over yet
    assert lim.summaries(0.99 + 2.0) == [(4, "refused: X (99 suppressed)")]
    assert lim.allow(10.0, 4, "refused: X")                       # a new burst
    assert lim.summaries(20.0) == []                              # nothing held back


def test_limiter_bounds_distinct_texts_and_never_holds_back_a_failsafe():
    lim = RateLimiter(rate_hz=2.0, burst=10.0, quiet_s=2.0)
    n = sum(lim.allow(i * 0.001, 4, f"refused: X={i}") for i in range(1000))   # 1 s of flood
    assert n == 11                                                # burst + 1 s of refill
    assert lim.allow(1.0, 2, "FAILSAFE: plant data lost")         # CRITICAL: not bucketed
    assert not lim.allow(1.1, 2, "FAILSAFE: plant data lost")     # but de-duplicated
    out = dict((text, sev) for sev, text in lim.summaries(10.0))
    assert out["989 messages suppressed"] == 4
    assert out["FAILSAFE: plant data lost (1 suppressed)"] == 2
    assert lim.total_suppressed == 990


def test_limiter_reports_a_repeat_that_goes_on_every_hold_s():
    lim = RateLimiter(rate_hz=2.0, burst=10.0, quiet_s=2.0, hold_s=30.0)
    assert lim.allow(0.0, 4, "refused: Y")
    out = []
    for k in range(1, 61):                          # once a second for a minute
        assert not lim.allow(float(k), 4, "refused: Y")
        out += lim.summaries(float(k) + 0.5)
    assert out == [(4, "refused: Y (30 suppressed)"), (4, "refused: Y (30 suppressed)")]


def _settle(link: GcsLink, now_s: float) -> float:
    """Call ``service`` until everything due at start is sent (``max_tx`` per call); returns
    the time of the last call."""
    for _ in range(50):
        if link.service(now_s) == 0:
            return now_s
        now_s += 1e-4
    raise AssertionError("the start-up streams never drained")


def test_service_walks_the_schedules_only_when_something_is_due():
    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    out.bind(("127.0.0.1", 0))
    link = GcsLink(_Vehicle(), ("127.0.0.1", free_udp_port()), [out.getsockname()])
    walks = []
    walk = link._streams
    link._streams = lambda sched, now_s, sent: (walks.append(now_s), walk(sched, now_s, sent))[1]
    try:
        now = _settle(link, 100.0)
        due = link.wall_due
        assert now < due <= now + min(STREAM_DEFAULTS_S.values())
        n_walks = len(walks)
        # GIVEN nothing due and nothing queued: no walk, nothing sent
        assert link.service(due - 1e-6) == 0 and len(walks) == n_walks
        # WHEN the earliest stream falls due: walked and sent
        assert link.service(due) >= 1 and len(walks) == n_walks + 1
    finally:
        out.close()
        link.close()


def test_a_peer_rate_request_is_served_at_once_not_at_the_next_due_time():
    out_port = free_udp_port()
    link = GcsLink(_Vehicle(), ("127.0.0.1", free_udp_port()), [("127.0.0.1", out_port)])
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    peer.settimeout(2.0)
    try:
        now = _settle(link, 100.0)
        assert link.wall_due > now + 1e-3
        # GIVEN a peer asking for ATTITUDE at 50 Hz (its own schedule, due now; no reply queued)
        tx = ML.MAVLink(_Null(), srcSystem=255, srcComponent=190)
        peer.sendto(tx.request_data_stream_encode(1, 1, ML.MAV_DATA_STREAM_EXTRA1, 50, 1)
                    .pack(tx), link.endpoint.address)
        t = now + 1e-5
        for _ in range(100):                   # the datagram is on loopback: read it
            if link.poll(t):
                break
        # WHEN serviced before the old schedules' next due time: the peer's streams go out
        assert link.service(t + 1e-5) >= 1
        rx = ML.MAVLink(_Null())
        msgs = rx.parse_buffer(peer.recv(2048)) or []
        assert msgs and msgs[0].get_srcSystem() == 1
    finally:
        peer.close()
        link.close()


def _blocks(f, calls: int = 5) -> int:
    """Python object-allocator blocks ``calls`` calls of ``f`` take (tools.bench's counter),
    less the counter's own (a window with no call)."""
    from tools.bench.allocs import PyAllocCounter
    f()                                    # (first-call paths, free lists filled)
    counts = []
    for n in (0, calls):
        counter = PyAllocCounter()
        with counter:
            k = 0
            while k < n:
                f()
                k += 1
        counts.append(int(counter.counts[0]) + int(counter.counts[1]))
    return counts[1] - counts[0]


def test_a_full_peer_table_forgets_its_oldest_peer_for_a_newcomer():
    from fc.gcs import MAX_PEERS
    link = GcsLink(_Vehicle(), ("127.0.0.1", free_udp_port()), [])
    try:
        # GIVEN a full table of unsigned peers heard at 100 s, 101 s, ... (the first the oldest)
        addrs = [("127.0.0.1", 40000 + i) for i in range(MAX_PEERS)]
        for i, a in enumerate(addrs):
            link._heard(a, 100.0 + i, False)
        assert len(link.peers) == MAX_PEERS
        # WHEN a newcomer is heard
        link._heard(("127.0.0.1", 50000), 100.0 + MAX_PEERS, False)
        # THEN the oldest peer made room for it, the others are kept
        assert addrs[0] not in link.peers and ("127.0.0.1", 50000) in link.peers
        assert all(a in link.peers for a in addrs[1:]) and len(link.peers) == MAX_PEERS
        # AND a later expiry forgets the ones silent for PEER_TIMEOUT_S (the newcomer stays)
        link._expire_peers(100.0 + MAX_PEERS - 1 + PEER_TIMEOUT_S + 0.5)
        assert list(link.peers) == [("127.0.0.1", 50000)]
    finally:
        link.close()


def test_the_heartbeat_seconds_peer_expiry_allocates_nothing_without_peers():
    # GIVEN a link no ground station has talked to (the outputs only)
    link = GcsLink(_Vehicle(), ("127.0.0.1", free_udp_port()), [])
    try:
        # THEN the heartbeat second's expiry and summaries take no Python block (the expiry's
        # comprehension made a cell object per call while it was in the same function, issue 24)
        assert _blocks(lambda: link._expire_peers(100.0)) == 0
        assert _blocks(link._summaries) == 0
    finally:
        link.close()


def _drain_ids(sock, ids: list) -> None:
    rx = ML.MAVLink(_Null())
    while True:
        try:
            data = sock.recv(4096)
        except BlockingIOError:
            return
        ids.extend(m.get_msgId() for m in rx.parse_buffer(data) or [])


def test_home_position_goes_out_and_into_the_tlog_only_once_home_is_set(tmp_path):
    from pymavlink import mavutil
    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    out.bind(("127.0.0.1", 0))
    out.setblocking(False)
    v = _Vehicle()
    tlog = str(tmp_path / "fc.tlog")
    link = GcsLink(v, ("127.0.0.1", free_udp_port()), [out.getsockname()], tlog_path=tlog,
                   sim_time=True)
    home_id = ML.MAVLINK_MSG_ID_HOME_POSITION
    before, after = [], []
    try:
        # GIVEN 11 s of streams without a GNSS fix (HOME_POSITION's period is 5 s), 100 calls/s
        for k in range(1100):
            v.meas_stamp_us = k * 10_000
            link.service(100.0 + k * 0.01)
            _drain_ids(out, before)
        # WHEN home is set, and 11 s more
        link.home = (34.9054246, -117.8839078, 27998.8)
        for k in range(1100, 2200):
            v.meas_stamp_us = k * 10_000
            link.service(100.0 + k * 0.01)
            _drain_ids(out, after)
    finally:
        link.close()
        out.close()
    # THEN no HOME_POSITION before home, and one every 5 s after, to the outputs and the .tlog
    assert home_id not in before and ML.MAVLINK_MSG_ID_ATTITUDE in before
    assert 2 <= after.count(home_id) <= 3
    logged = []
    mlog = mavutil.mavlink_connection(tlog)
    while True:
        m = mlog.recv_match(type="HOME_POSITION")
        if m is None:
            break
        logged.append(m.time_usec)
    assert logged and min(logged) >= 11_000_000, logged
    assert 2 <= len(logged) <= 3 and logged[0].__class__ is int
