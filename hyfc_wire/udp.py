"""UDP on loopback: ``HOST:PORT`` parsing and the non-blocking endpoint both processes use."""
from __future__ import annotations

import socket
import struct

__all__ = ["parse_hostport", "UdpEndpoint", "MAX_DATAGRAM_B"]

#: the largest datagram read (a sensor frame is ~150 bytes, a MAVLink 2 frame at most 280)
MAX_DATAGRAM_B = 2048


def parse_hostport(text: str, what: str = "") -> tuple[str, int]:
    """``HOST:PORT`` -> ``(host, port)``; ValueError with a clear message otherwise.

    ``what`` (e.g. the option name ``--fc``) starts the message when given. The host is not
    resolved here; the port must be an integer in 0..65535 (0: ephemeral).
    """
    pre = f"{what}: " if what else ""
    host, sep, port = str(text).rpartition(":")
    if not sep or not host:
        raise ValueError(f"{pre}expected HOST:PORT, got {text!r}")
    try:
        port_n = int(port)
    except ValueError:
        raise ValueError(f"{pre}port must be an integer in {text!r}") from None
    if not 0 <= port_n <= 65535:
        raise ValueError(f"{pre}port {port_n} out of range 0..65535 in {text!r}")
    return host, port_n


_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)   # Linux value where Python lacks it
_TIMESPEC = struct.Struct("=qq")                          # struct timespec on 64-bit Linux
_ANC_B = socket.CMSG_SPACE(_TIMESPEC.size) if hasattr(socket, "CMSG_SPACE") else 64


def _rx_stamp_ns(anc) -> int:
    """The kernel receive stamp (CLOCK_REALTIME ns) in ``recvmsg``'s ancillary data, else 0."""
    for level, kind, cdata in anc:
        if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(cdata) >= 16:
            sec, nsec = _TIMESPEC.unpack_from(cdata)
            return sec * 1_000_000_000 + nsec
    return 0


class UdpEndpoint:
    """A bound, non-blocking UDP socket. ``recv`` returns None when nothing is waiting."""

    def __init__(self, host: str, port: int) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        except OSError:
            pass
        try:
            sock.bind((host, port))
        except OSError as exc:
            sock.close()
            raise OSError(f"cannot bind UDP {host}:{port}: {exc}") from exc
        self._adopt(sock)

    @classmethod
    def wrap(cls, sock: socket.socket) -> "UdpEndpoint":
        """An endpoint over an already bound socket (made non-blocking)."""
        ep = cls.__new__(cls)
        ep._adopt(sock)
        return ep

    def _adopt(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        self.sock = sock
        self.address = sock.getsockname()
        self.send_errors = 0
        #: kernel receive time of the last datagram ``recv`` returned (CLOCK_REALTIME, ns);
        #: 0 unless :meth:`enable_rx_timestamps` succeeded
        self.rx_ns = 0
        self._stamped = False

    @property
    def stamped(self) -> bool:
        """The kernel stamps each datagram's arrival (:meth:`enable_rx_timestamps`)."""
        return self._stamped

    def enable_rx_timestamps(self) -> bool:
        """Ask the kernel to stamp each datagram on arrival (``SO_TIMESTAMPNS``); ``recv``
        then stores the stamp in ``rx_ns``. Costs ~0.6 us per datagram (recvmsg instead of
        recvfrom). Returns False where the option is not available."""
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
        except (OSError, AttributeError):
            return False
        self._stamped = True
        return True

    def recv(self) -> tuple[bytes, tuple] | None:
        try:
            if self._stamped:
                data, anc, _flags, addr = self.sock.recvmsg(MAX_DATAGRAM_B, _ANC_B)
                self.rx_ns = _rx_stamp_ns(anc)
                return data, addr
            return self.sock.recvfrom(MAX_DATAGRAM_B)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            # e.g. ICMP port unreachable reported on a later recv (ECONNREFUSED)
            return None

    def recv_into(self, buf) -> tuple[int, tuple] | None:
        """Like :meth:`recv`, into the writable buffer ``buf`` (a datagram longer than it is
        cut, as ``recv`` cuts at MAX_DATAGRAM_B): ``(length, address)``, no allocation for the
        data."""
        try:
            if self._stamped:
                n, anc, _flags, addr = self.sock.recvmsg_into((buf,), _ANC_B)
                self.rx_ns = _rx_stamp_ns(anc)
                return n, addr
            return self.sock.recvfrom_into(buf)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            return None

    def send(self, data: bytes, addr: tuple) -> bool:
        try:
            self.sock.sendto(data, addr)
            return True
        except OSError:
            self.send_errors += 1
            return False

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        self.sock.close()
