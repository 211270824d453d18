"""tools/sitl/linkimpair.py - a seeded UDP impairment relay (loss, delay, jitter, duplicates, reordering).

The relay sits between a *client* that sends first (the plant, a ground station) and a
*server* that binds and answers whoever writes to it (the fc):

    client --up--> [listen socket]  relay  [upstream socket] --up--> server (target)
    client <-down- [listen socket]  relay  [upstream socket] <-down- server

The client is pointed at the relay's listen port instead of the server; the server sees the
relay's upstream socket as its peer (one stable address, so address pinning on the server side
keeps working). Replies go back to the address the client last wrote from.

Each direction (``up``: client -> server, ``down``: server -> client) has its own
:class:`Impairment` and its own random stream derived from one seed, so the same seed and the
same traffic give the same decisions. Per datagram, in this order:

- **loss** ``loss``: dropped with this probability;
- **duplicate** ``dup``: delivered twice (the copy right after the original);
- **delay** ``delay_s`` plus **jitter** ``jitter_s`` (uniform in [0, jitter_s]); delivery keeps
  the arrival order (a later datagram is never released before an earlier one of the same
  direction), so jitter alone never reorders;
- **corrupt** ``corrupt``: the datagram is mutated (bit flips, truncation, garbage; fuzzing);
- **blackout** (``set_blackout``, tests only): the link is cut, every datagram dropped;
- **reorder** ``reorder``: the datagram is held back and released right after the *next*
  datagram of the same direction (the two swap), or after ``reorder_hold_s`` if no other comes.
- **frame delay** ``delay_frames`` (lockstep, fc -> plant): a wall-clock delay only slows a
  lockstep run (the plant waits for the answer to each frame), so this delays in *frames*:
  each SERVO_OUTPUT_RAW is held and its channels are sent N answers later, re-stamped with the
  frame being answered (``time_usec``), so the plant applies at frame k the fc's answer to
  frame k - N (the first N frames get the first answer). Applied before the other impairments;
  a datagram that is not exactly one SERVO_OUTPUT_RAW passes unchanged. Counted as
  ``frame_delayed``. Used by ``tools.evidence.margins wire`` (time-delay margin over the wire).

Counters per direction (``received, dropped, duplicated, reordered, delivered, send_errors``)
are exact counts of what the relay did (``reordered`` = held datagrams actually overtaken), so
tests can check rates against the seed.

Command line (runs until SIGINT/SIGTERM, prints ``LISTEN HOST:PORT`` once bound and one JSON
line of counters at exit)::

    python -m tools.relay --listen 127.0.0.1:14570 --target 127.0.0.1:14560 \\
        --loss 0.05 --jitter-ms 5 --dup 0.01 --reorder 0.01 [--down-loss ...] --seed 1
    python -m tools.relay --listen ... --target ... --down-delay-frames 20   # lockstep

``--loss/--delay-ms/--jitter-ms/--dup/--reorder`` set both directions; ``--up-*`` and
``--down-*`` override one direction. From Python::

    with LinkImpair(("127.0.0.1", fc_port), up=Impairment(loss=0.05), seed=1) as relay:
        plant_target = relay.listen_address          # point the client here
        ...
        relay.counters["up"]["dropped"]
"""
from __future__ import annotations

import argparse
import heapq
import json
import math
import os
import random
import select
import signal
import socket
import sys
import threading
import time
from dataclasses import asdict, dataclass

from hyfc_wire.udp import parse_hostport
from tools.sitl.procs import ROOT, Child, repo_env

__all__ = ["Impairment", "LinkImpair", "RelayProcess", "parse_hostport", "mutate",
           "COUNTER_NAMES"]

MAX_DATAGRAM_B = 65535
COUNTER_NAMES = ("received", "dropped", "duplicated", "reordered", "delivered", "send_errors",
                 "blackout", "corrupted", "frame_delayed")


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One random mutation of a datagram: bit flips, truncation, garbage inserted or appended,
    a byte run overwritten, or two datagram halves swapped. Never returns the input unchanged
    unless it is empty."""
    b = bytearray(data)
    kind = rng.randrange(6)
    if not b:
        return bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 64)))
    if kind == 0:
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
    elif kind == 1:
        b = b[:rng.randrange(len(b))]
    elif kind == 2:
        i = rng.randrange(len(b) + 1)
        b[i:i] = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 16)))
    elif kind == 3:
        b += bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 64)))
    elif kind == 4:
        i = rng.randrange(len(b))
        n = rng.randint(1, 8)
        b[i:i + n] = bytes([rng.choice((0x00, 0xFF, 0x7F, 0x80, 0xFD, 0xFE))] * n)
    else:
        i = rng.randrange(len(b))
        b = b[i:] + b[:i]
    if bytes(b) == data:
        b.append(rng.getrandbits(8))
    return bytes(b)


@dataclass(frozen=True)
class Impairment:
    """What happens to the datagrams of one direction. Probabilities in [0, 1], times in s."""

    loss: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    dup: float = 0.0
    reorder: float = 0.0
    reorder_hold_s: float = 0.02
    corrupt: float = 0.0      # probability a datagram is mutated (fuzzing: tools/fuzz.py)
    delay_frames: int = 0     # SERVO_OUTPUT_RAW answers held this many frames (lockstep)

    def __post_init__(self) -> None:
        for name in ("loss", "dup", "reorder", "corrupt"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 <= v <= 1.0):
                raise ValueError(f"{name} must be a probability in [0, 1], got {v!r}")
        for name in ("delay_s", "jitter_s", "reorder_hold_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 <= v <= 10.0):
                raise ValueError(f"{name} must be a time in [0, 10] s, got {v!r}")
        if not (isinstance(self.delay_frames, int) and 0 <= self.delay_frames <= 100000):
            raise ValueError(f"delay_frames must be an integer in [0, 100000], got "
                             f"{self.delay_frames!r}")

    @property
    def is_clean(self) -> bool:
        return not (self.loss or self.delay_s or self.jitter_s or self.dup or self.reorder
                    or self.corrupt or self.delay_frames)


class _Direction:
    """Decisions and bookkeeping of one direction (single-threaded: the relay thread)."""

    def __init__(self, imp: Impairment, rng: random.Random) -> None:
        self.imp = imp
        self.rng = rng
        self.last_due = 0.0          # FIFO: no datagram leaves before the previous one
        self.held: tuple | None = None   # (data, release_deadline) waiting to be overtaken
        self.counters = {n: 0 for n in COUNTER_NAMES}
        self.blackout = False        # link cut: every datagram is dropped (counted apart)
        self.corrupt_now = False
        self.frames = FrameDelay(imp.delay_frames) if imp.delay_frames else None

    def decide(self, now: float) -> tuple[list[float] | None, bool]:
        """(due times of the copies of one datagram or None when dropped, hold-for-reorder).

        Always draws the same number of random numbers per datagram, so the decisions for
        datagram k depend only on the seed and k.
        """
        imp = self.imp
        r_loss, r_dup, r_jit, r_reo, r_cor = (self.rng.random(), self.rng.random(),
                                               self.rng.random(), self.rng.random(),
                                               self.rng.random())
        self.corrupt_now = r_cor < imp.corrupt
        self.counters["received"] += 1
        if self.blackout:
            self.counters["blackout"] += 1
            return None, False
        reorder = r_reo < imp.reorder
        if r_loss < imp.loss:
            self.counters["dropped"] += 1
            return None, False
        due = max(now + imp.delay_s + r_jit * imp.jitter_s, self.last_due)
        self.last_due = due
        if r_dup < imp.dup:
            self.counters["duplicated"] += 1
            return [due, due], reorder
        return [due], reorder


class FrameDelay:
    """Delay SERVO_OUTPUT_RAW answers by ``n`` frames, re-stamped (see the module docstring).

    ``process(datagram) -> (datagram out, delayed?)``. The output keeps the sender's system
    and component ids, sequence number and MAVLink version; only the channels change.
    """

    def __init__(self, n: int) -> None:
        from collections import deque
        os.environ.setdefault("MAVLINK20", "1")
        from pymavlink.dialects.v20 import ardupilotmega as mavlink
        self.n = int(n)
        self._mavlink = mavlink
        self._parser = mavlink.MAVLink(None)
        self._parser.robust_parsing = True
        self._held: deque = deque()
        self._first: tuple | None = None

    def process(self, data: bytes) -> tuple[bytes, bool]:
        try:
            msgs = self._parser.parse_buffer(bytes(data)) or []
        except Exception:  # noqa: BLE001 - not ours to judge: pass it on unchanged
            return data, False
        if len(msgs) != 1 or msgs[0].get_type() != "SERVO_OUTPUT_RAW":
            return data, False
        m = msgs[0]
        chans = tuple(int(getattr(m, f"servo{i}_raw", 0)) for i in range(1, 17))
        self._held.append(chans)
        if self._first is None:
            self._first = chans
        out = self._held.popleft() if len(self._held) > self.n else self._first
        enc = self._mavlink.MAVLink(None, srcSystem=m.get_srcSystem(),
                                    srcComponent=m.get_srcComponent())
        enc.seq = m.get_seq()
        msg = enc.servo_output_raw_encode(m.time_usec, m.port, *out)
        return bytes(msg.pack(enc, force_mavlink1=data[:1] == b"\xfe")), True


class LinkImpair:
    """The relay, in a background thread of this process (context manager).

    Parameters
    ----------
    target : the server's address (e.g. the fc's ``--plant-bind``).
    up, down : impairments client->server and server->client (default: none).
    listen : local address the client sends to (default 127.0.0.1 and a free port).
    seed : one seed for both directions (each gets its own stream).
    """

    def __init__(self, target: tuple[str, int], up: Impairment | None = None,
                 down: Impairment | None = None, listen: tuple[str, int] = ("127.0.0.1", 0),
                 seed: int = 0) -> None:
        self.target = (target[0], int(target[1]))
        self.up_imp = up or Impairment()
        self.down_imp = down or Impairment()
        self.seed = int(seed)
        self._listen_req = listen
        self.client_addr: tuple | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self.listen_sock: socket.socket | None = None
        self.up_sock: socket.socket | None = None
        self.error: BaseException | None = None
        self._dirs = {
            "up": _Direction(self.up_imp, random.Random(f"{self.seed}:up")),
            "down": _Direction(self.down_imp, random.Random(f"{self.seed}:down")),
        }
        self._heap: list = []
        self._seq = 0

    # ------------------------------------------------------------------ public
    @property
    def listen_address(self) -> tuple[str, int]:
        return self._listen_addr

    @property
    def listen_port(self) -> int:
        return self.listen_address[1]

    @property
    def upstream_address(self) -> tuple[str, int]:
        """The address the server sees datagrams coming from."""
        return self._up_addr

    @property
    def counters(self) -> dict[str, dict[str, int]]:
        with self._lock:
            return {k: dict(d.counters) for k, d in self._dirs.items()}

    def set_blackout(self, on: bool, direction: str = "both") -> None:
        """Cut (``on``) or restore one direction (``up``/``down``) or ``both``: a lost link."""
        with self._lock:
            for name in (("up", "down") if direction == "both" else (direction,)):
                self._dirs[name].blackout = bool(on)

    def start(self) -> "LinkImpair":
        self._bind()
        self._thread = threading.Thread(target=self._run_guarded, name="linkimpair",
                                        daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0) -> dict[str, dict[str, int]]:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        for s in (self.listen_sock, self.up_sock):
            if s is not None:
                s.close()
        return self.counters

    def __enter__(self) -> "LinkImpair":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def run_forever(self, stop: threading.Event | None = None) -> None:
        """Run the relay loop in the calling thread (the command line)."""
        if stop is not None:
            self._stop = stop
        if self.listen_sock is None:
            self._bind()
        self._run()

    # ------------------------------------------------------------------ internals
    def _bind(self) -> None:
        self.listen_sock = self._socket(self._listen_req)
        try:
            self.up_sock = self._socket((self._listen_req[0], 0))
        except OSError:
            self.listen_sock.close()
            raise
        self._listen_addr = self.listen_sock.getsockname()
        self._up_addr = self.up_sock.getsockname()

    @staticmethod
    def _socket(addr: tuple[str, int]) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setblocking(False)
        for opt in (socket.SO_RCVBUF, socket.SO_SNDBUF):
            try:
                s.setsockopt(socket.SOL_SOCKET, opt, 1 << 20)
            except OSError:
                pass
        try:
            s.bind((addr[0], int(addr[1])))
        except OSError as exc:
            s.close()
            raise OSError(f"linkimpair: cannot bind UDP {addr[0]}:{addr[1]}: {exc}") from exc
        return s

    def _run_guarded(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # noqa: BLE001 - reported through .error
            self.error = exc

    def _push(self, due: float, direction: str, data: bytes) -> None:
        self._seq += 1
        heapq.heappush(self._heap, (due, self._seq, direction, data))

    def _accept(self, direction: str, data: bytes, now: float) -> None:
        d = self._dirs[direction]
        if d.frames is not None:
            data, delayed = d.frames.process(data)
            if delayed:
                with self._lock:
                    d.counters["frame_delayed"] += 1
        with self._lock:
            dues, reorder = d.decide(now)
        if dues is None:
            return
        if d.corrupt_now:
            with self._lock:
                d.counters["corrupted"] += 1
            data = mutate(data, d.rng)
        held = d.held
        if held is not None:
            # the held datagram is overtaken by this one: release it right after
            d.held = None
            with self._lock:
                d.counters["reordered"] += 1
            for t in dues:
                self._push(t, direction, data)
            self._push(dues[-1], direction, held[0])
            return
        if reorder:
            # held until the next datagram of this direction (or the hold time)
            d.held = (data, dues[0] + d.imp.reorder_hold_s)
            for t in dues[1:]:                  # a duplicate copy still goes in order
                self._push(t, direction, data)
            return
        for t in dues:
            self._push(t, direction, data)

    def _deliver(self, direction: str, data: bytes) -> None:
        d = self._dirs[direction]
        if direction == "up":
            sock, addr = self.up_sock, self.target
        else:
            sock, addr = self.listen_sock, self.client_addr
            if addr is None:
                return
        try:
            sock.sendto(data, addr)
            ok = True
        except OSError:
            ok = False
        with self._lock:
            d.counters["delivered" if ok else "send_errors"] += 1

    def _run(self) -> None:
        socks = [self.listen_sock, self.up_sock]
        clock = time.monotonic
        while not self._stop.is_set():
            now = clock()
            # release held datagrams nobody overtook
            for name, d in self._dirs.items():
                if d.held is not None and now >= d.held[1]:
                    data, _ = d.held
                    d.held = None
                    self._push(now, name, data)
            while self._heap and self._heap[0][0] <= now:
                _, _, direction, data = heapq.heappop(self._heap)
                self._deliver(direction, data)
            wait = 0.05
            if self._heap:
                wait = min(wait, max(0.0, self._heap[0][0] - now))
            for d in self._dirs.values():
                if d.held is not None:
                    wait = min(wait, max(0.0, d.held[1] - now))
            try:
                readable, _, _ = select.select(socks, [], [], wait)
            except InterruptedError:
                continue
            except (OSError, ValueError):
                if self._stop.is_set():
                    return
                raise
            now = clock()
            for s in readable:
                for _ in range(256):   # drain, bounded
                    try:
                        data, addr = s.recvfrom(MAX_DATAGRAM_B)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        break   # e.g. ICMP port unreachable from an earlier send
                    if s is self.listen_sock:
                        self.client_addr = addr
                        self._accept("up", data, now)
                    elif addr == self.target:
                        self._accept("down", data, now)


class RelayProcess:
    """The relay as a separate process (``python -m tools.relay``), context manager.

    Keeps the relay's work off the caller's interpreter (GIL) in timing-sensitive tests.
    ``listen_address`` is known after start; ``counters`` after stop (the JSON line).
    """

    def __init__(self, target: tuple[str, int], up: Impairment | None = None,
                 down: Impairment | None = None, seed: int = 0,
                 listen: tuple[str, int] = ("127.0.0.1", 0), start_timeout_s: float = 20.0):
        self.argv = [sys.executable, "-m", "tools.relay",
                     "--listen", f"{listen[0]}:{listen[1]}",
                     "--target", f"{target[0]}:{target[1]}", "--seed", str(seed)]
        for prefix, imp in (("up", up or Impairment()), ("down", down or Impairment())):
            self.argv += [f"--{prefix}-loss", repr(imp.loss),
                          f"--{prefix}-delay-ms", repr(imp.delay_s * 1e3),
                          f"--{prefix}-jitter-ms", repr(imp.jitter_s * 1e3),
                          f"--{prefix}-dup", repr(imp.dup),
                          f"--{prefix}-reorder", repr(imp.reorder),
                          f"--{prefix}-corrupt", repr(imp.corrupt)]
            if imp.delay_frames:
                self.argv += [f"--{prefix}-delay-frames", str(imp.delay_frames)]
        self.start_timeout_s = start_timeout_s
        self.child: Child | None = None
        self.listen_address: tuple[str, int] | None = None
        self.counters: dict | None = None

    @property
    def listen_port(self) -> int:
        return self.listen_address[1]

    def __enter__(self) -> "RelayProcess":
        self.child = Child("linkimpair", self.argv, None, env=repo_env(), cwd=str(ROOT))
        try:
            line = self.child.wait_for_line("LISTEN ", self.start_timeout_s)
        except RuntimeError as exc:
            self.child.stop(int_wait_s=0.0, term_wait_s=None, first_signal=signal.SIGKILL)
            raise RuntimeError(f"linkimpair did not start: {exc}") from None
        self.listen_address = parse_hostport(line.split()[1])
        return self

    def stop(self, timeout_s: float = 10.0) -> dict | None:
        """SIGINT (the relay prints its counters as one JSON line and exits), then SIGKILL."""
        if self.child is None or self.child.poll() is not None and self.counters is not None:
            return self.counters
        self.child.stop(int_wait_s=timeout_s, term_wait_s=None)
        for line in self.child.history:
            if line.startswith("{"):
                self.counters = json.loads(line)
        return self.counters

    def __exit__(self, *exc) -> None:
        self.stop()


# ---------------------------------------------------------------------- command line
def _impairment(args, prefix: str) -> Impairment:
    def pick(name):
        v = getattr(args, f"{prefix}_{name}")
        return getattr(args, name) if v is None else v
    return Impairment(loss=pick("loss"), delay_s=pick("delay_ms") * 1e-3,
                      jitter_s=pick("jitter_ms") * 1e-3, dup=pick("dup"),
                      reorder=pick("reorder"), corrupt=pick("corrupt"),
                      reorder_hold_s=args.reorder_hold_ms * 1e-3,
                      delay_frames=getattr(args, f"{prefix}_delay_frames"))


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m tools.relay",
        description="Seeded UDP impairment relay: the client sends to --listen, the relay "
                    "forwards to --target and relays the replies back. Prints LISTEN HOST:PORT "
                    "when bound; SIGINT/SIGTERM print the counters as one JSON line and exit 0.")
    ap.add_argument("--listen", type=parse_hostport, default=("127.0.0.1", 0), metavar="HOST:PORT",
                    help="address the client sends to (default 127.0.0.1:0 = a free port)")
    ap.add_argument("--target", type=parse_hostport, required=True, metavar="HOST:PORT",
                    help="the server (e.g. the fc's --plant-bind)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--duration", type=float, default=0.0,
                    help="stop after this many seconds (default 0 = until SIGINT)")
    ap.add_argument("--reorder-hold-ms", type=float, default=20.0,
                    help="longest hold of a reordered datagram waiting to be overtaken (20)")
    for name, kind, hlp in (("loss", float, "drop probability"),
                            ("delay-ms", float, "fixed delay [ms]"),
                            ("jitter-ms", float, "extra delay uniform in [0, J] ms (order kept)"),
                            ("dup", float, "duplicate probability"),
                            ("reorder", float, "probability a datagram swaps with the next"),
                            ("corrupt", float, "probability a datagram is mutated (fuzzing)")):
        ap.add_argument(f"--{name}", type=kind, default=0.0, help=f"{hlp}, both directions (0)")
        for prefix in ("up", "down"):
            ap.add_argument(f"--{prefix}-{name}", type=kind, default=None,
                            help=argparse.SUPPRESS)
    ap.add_argument("--down-delay-frames", type=int, default=0, metavar="N",
                    help="lockstep: hold the server's SERVO_OUTPUT_RAW answers N frames, "
                         "re-stamped (a delay in sim time; 0)")
    ap.add_argument("--up-delay-frames", type=int, default=0, help=argparse.SUPPRESS)
    ap.epilog = ("--up-X / --down-X (X = loss, delay-ms, jitter-ms, dup, reorder) override one "
                 "direction: up = client->target, down = target->client.")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        up, down = _impairment(args, "up"), _impairment(args, "down")
    except ValueError as exc:
        ap.error(str(exc))
    relay = LinkImpair(args.target, up=up, down=down, listen=args.listen, seed=args.seed)
    stop = threading.Event()

    def _sig(_s, _f):
        stop.set()

    signal.signal(signal.SIGINT, _sig)
    signal.signal(signal.SIGTERM, _sig)
    try:
        relay._bind()
    except OSError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    host, port = relay.listen_address
    print(f"LISTEN {host}:{port}", flush=True)
    if args.duration > 0:
        threading.Timer(args.duration, stop.set).start()
    relay.run_forever(stop)
    print(json.dumps({"up": relay._dirs["up"].counters, "down": relay._dirs["down"].counters,
                      "config": {"up": asdict(up), "down": asdict(down), "seed": args.seed}}),
          flush=True)
    relay.listen_sock.close()
    relay.up_sock.close()
    return 0

