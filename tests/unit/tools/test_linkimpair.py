"""tools/sitl/linkimpair.py: the seeded UDP impairment relay does what it is configured to do.

Loopback only, free ports, every wait bounded. The relay's own counters are checked against
what an echo server actually receives, and the rates against the configured probabilities
(binomial bounds, 5 sigma), for a fixed seed.
"""
from __future__ import annotations

import math
import select
import socket
import struct
import threading
import time

import pytest

from tools.sitl.linkimpair import Impairment, LinkImpair, RelayProcess

HDR = struct.Struct("<Id")   # sequence number, send time [s, monotonic]


class EchoServer:
    """Records (seq, receive time) of every datagram and echoes it back to its sender."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.address = self.sock.getsockname()
        self.seen: list[tuple[int, float]] = []
        self.peers: set = set()
        self._cv = threading.Condition()
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.sock], [], [], 0.05)
            if not r:
                continue
            data, addr = self.sock.recvfrom(2048)
            with self._cv:
                seq = HDR.unpack_from(data)[0] if len(data) >= HDR.size else -1
                self.seen.append((seq, time.monotonic()))
                self.peers.add(addr)
                self._cv.notify_all()
            self.sock.sendto(data, addr)

    def wait_count(self, n, timeout_s: float = 5.0) -> bool:
        """Wait (bounded) until ``n()`` (or n) datagrams have arrived."""
        want = n if callable(n) else (lambda: n)
        with self._cv:
            return self._cv.wait_for(lambda: len(self.seen) >= want(), timeout_s)

    def close(self) -> None:
        self._stop.set()
        self._t.join(2)
        self.sock.close()


def _client() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    s.bind(("127.0.0.1", 0))
    return s


def _drain(sock: socket.socket, out: list, until, timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not until() and time.monotonic() < deadline:
        r, _, _ = select.select([sock], [], [], 0.05)
        if r:
            data, _ = sock.recvfrom(2048)
            out.append((HDR.unpack_from(data)[0], time.monotonic()))


def _pump(relay_addr, server: EchoServer, n: int, spacing_s: float = 0.0,
          expect_server: int | None = None):
    """Send n numbered datagrams through the relay; returns what came back to the client."""
    c = _client()
    back: list = []
    for i in range(n):
        c.sendto(HDR.pack(i, time.monotonic()) + b"x" * 40, relay_addr)
        if spacing_s:
            t_next = time.monotonic() + spacing_s
            _drain(c, back, lambda: time.monotonic() >= t_next, spacing_s)
        elif i % 50 == 49:
            _drain(c, back, lambda: False, 0.002)
    return c, back


def _inversions(seqs: list[int]) -> int:
    """Datagrams that arrived after a higher-numbered one (duplicates are not inversions)."""
    top, n = -1, 0
    for s in seqs:
        if s < top:
            n += 1
        top = max(top, s)
    return n


def _within(count: int, n: int, p: float, sigmas: float = 5.0) -> bool:
    sd = math.sqrt(n * p * (1 - p))
    return abs(count - n * p) <= sigmas * sd + 1


def test_clean_relay_passes_everything_in_order_both_ways():
    srv = EchoServer()
    try:
        with LinkImpair(srv.address, seed=1) as relay:
            c, back = _pump(relay.listen_address, srv, 300)
            _drain(c, back, lambda: len(back) >= 300)
            c.close()
        k = relay.counters          # after stop: the relay thread has finished counting
        assert [s for s, _ in srv.seen] == list(range(300))
        assert [s for s, _ in back] == list(range(300))
        assert srv.peers == {relay.upstream_address}          # one stable address for the server
        assert k["up"]["received"] == k["up"]["delivered"] == 300
        assert k["down"]["delivered"] == 300 and k["up"]["dropped"] == 0
    finally:
        srv.close()


def test_loss_duplication_reordering_rates_match_the_seed():
    n = 3000
    up = Impairment(loss=0.10, dup=0.05, reorder=0.05)
    srv = EchoServer()
    try:
        with LinkImpair(srv.address, up=up, seed=42) as relay:
            c, back = _pump(relay.listen_address, srv, n)
            k = relay.counters["up"]
            expected = n - k["dropped"] + k["duplicated"]
            srv.wait_count(expected)
            c.close()
        k = relay.counters["up"]
        seqs = [s for s, _ in srv.seen]
        assert k["received"] == n
        assert len(seqs) == n - k["dropped"] + k["duplicated"] == k["delivered"]
        assert len(set(range(n)) - set(seqs)) == k["dropped"]            # each loss is a real gap
        assert len(seqs) - len(set(seqs)) == k["duplicated"]
        assert _inversions(seqs) == k["reordered"]
        assert _within(k["dropped"], n, 0.10)
        assert _within(k["duplicated"], n - k["dropped"], 0.05)
        # a held datagram is overtaken unless the hold timed out: almost every draw reorders
        assert _within(k["reordered"], n - k["dropped"], 0.05, sigmas=6.0)
        assert k["reordered"] > 0
    finally:
        srv.close()


def test_same_seed_same_losses_other_seed_other_losses():
    def lost(seed):
        srv = EchoServer()
        try:
            with LinkImpair(srv.address, up=Impairment(loss=0.2), seed=seed) as relay:
                c, _ = _pump(relay.listen_address, srv, 500)
                want = 500 - relay.counters["up"]["dropped"]
                srv.wait_count(want)
                c.close()
            return set(range(500)) - {s for s, _ in srv.seen}
        finally:
            srv.close()
    a, b, other = lost(7), lost(7), lost(8)
    assert a == b and a != other and 60 < len(a) < 140


def test_delay_and_jitter_bounds_and_order_kept():
    delay, jitter = 0.010, 0.005
    srv = EchoServer()
    try:
        with LinkImpair(srv.address, up=Impairment(delay_s=delay, jitter_s=jitter),
                        seed=3) as relay:
            c = _client()
            sent = {}
            for i in range(200):
                sent[i] = time.monotonic()
                c.sendto(HDR.pack(i, sent[i]), relay.listen_address)
                t_next = sent[i] + 0.002
                _drain(c, [], lambda: time.monotonic() >= t_next, 0.01)
            srv.wait_count(200)
            c.close()
        lat = [t - sent[s] for s, t in srv.seen]
        assert [s for s, _ in srv.seen] == list(range(200))       # jitter alone never reorders
        assert min(lat) >= delay - 1e-4                          # never early
        mean = sum(lat) / len(lat)
        # uniform jitter: mean delay + J/2; scheduling noise only adds, bounded generously
        assert delay + 0.3 * jitter < mean < delay + jitter + 0.010
    finally:
        srv.close()


def test_directions_are_independent():
    srv = EchoServer()
    try:
        with LinkImpair(srv.address, up=Impairment(), down=Impairment(loss=0.5), seed=5) as relay:
            c, back = _pump(relay.listen_address, srv, 400)
            _drain(c, back, lambda: len(back) >= 400 - relay.counters["down"]["dropped"])
            c.close()
        k = relay.counters
        assert k["up"]["dropped"] == 0 and len(srv.seen) == 400
        assert _within(k["down"]["dropped"], 400, 0.5)
        assert len(back) == 400 - k["down"]["dropped"]
    finally:
        srv.close()


def test_corruption_rate_and_every_corrupted_datagram_differs():
    n = 600
    srv = EchoServer()
    try:
        with LinkImpair(srv.address, up=Impairment(corrupt=0.2), seed=9) as relay:
            c = _client()
            payload = {}
            for i in range(n):
                payload[i] = HDR.pack(i, 0.0) + bytes(range(40))
                c.sendto(payload[i], relay.listen_address)
            srv.wait_count(n, 5.0)
            c.close()
        k = relay.counters["up"]
    finally:
        srv.close()
    assert k["received"] == n and k["delivered"] == n
    assert _within(k["corrupted"], n, 0.2)
    assert len(srv.seen) == n


def test_mutate_always_changes_the_datagram():
    import random
    from tools.sitl.linkimpair import mutate
    rng = random.Random(1)
    data = bytes(range(60))
    assert all(mutate(data, rng) != data for _ in range(2000))


@pytest.mark.parametrize("kw", [dict(loss=1.5), dict(dup=-0.1), dict(jitter_s=float("nan")),
                                dict(delay_s=-1.0), dict(reorder=float("inf"))])
def test_bad_configuration_is_refused(kw):
    with pytest.raises(ValueError):
        Impairment(**kw)


def test_command_line_relay_prints_listen_and_counters():
    srv = EchoServer()
    try:
        with RelayProcess(srv.address, up=Impairment(loss=0.25), seed=11) as relay:
            c, _ = _pump(relay.listen_address, srv, 400)
            c.close()
        k = relay.counters
        srv.wait_count(400 - k["up"]["dropped"], 3.0)
        assert k is not None and k["up"]["received"] == 400
        assert k["up"]["dropped"] == 400 - len(srv.seen)
        assert _within(k["up"]["dropped"], 400, 0.25)
        assert k["config"]["up"]["loss"] == 0.25 and k["config"]["seed"] == 11
    finally:
        srv.close()
