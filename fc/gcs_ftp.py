"""fc/gcs_ftp.py - read-only MAVLink FTP (FILE_TRANSFER_PROTOCOL, id 110).

mavlink.io "File Transfer Protocol (FTP)". The payload (251 bytes) is a header ``<HBBBBBBI``:
seq, session, opcode, size, req_opcode, burst_complete, padding, offset; then up to 239 data
bytes. Every request addressed to us gets an answer at once (ACK 128 or NAK 129 with the error
code in data[0]): seq = the request's + 1, the request's session, req_opcode = its opcode,
target = the requester. Served read-only:

- ListDirectory (3): the run directory (``--out``: fc.log, fc.tlog, params.parm, ...) as "/",
  regular files as ``F<name>\\t<size>``, plus the virtual directory ``D@PARAM``; ``offset`` =
  the first entry; past the last: NAK EndOfFile.
- OpenFileRO (4): a file of the run directory, or ``@PARAM/param.pck`` (the parameters,
  fc/gcs_ftp_param.py; ``?withdefaults=1`` adds the defaults), snapshotted at open: ACK with
  the length (uint32) in data. The session is the requester's number (MAVProxy runs several);
  at most MAX_SESSIONS at once (NAK NoSessionsAvailable); opening a session that is open
  replaces it. A path outside the run directory or missing: NAK FileNotFound.
- ReadFile (5): up to ``size`` (<= 239) bytes at ``offset``; at or past the end: NAK EndOfFile.
- BurstReadFile (15): ACKs of up to ``size`` bytes each from ``offset``, streamed (``take``: at
  most the pacer's share per call, fc/gcs_logs.py ``Pacer``), BURST_PACKETS per request, the
  last with burst_complete = 1 (a short last packet = the end); a request at the end: NAK
  EndOfFile. The client asks for the next burst.
- TerminateSession (1), ResetSessions (2): close one / all sessions; ACK.
- CreateFile, WriteFile, RemoveFile, CreateDirectory, RemoveDirectory, OpenFileWO,
  TruncateFile, Rename (6-13): NAK FileProtected (read-only). Anything else (CalcFileCRC32
  included): NAK UnknownCommand, so a client never waits for a time-out.

Files are read with ``os.pread`` (at most 239 bytes per message) from the GCS link's service
(the housekeeping side), never from the frame path. Calls return ``(peer, message)`` outputs.
"""
from __future__ import annotations

import os
import struct

from fc.gcs_ftp_param import pack_params
from fc.gcs_logs import Pacer
from fc.link import mavlink as ML

__all__ = ["FtpService", "HDR", "MAX_DATA", "MAX_SESSIONS", "BURST_PACKETS", "OP", "ERR",
           "PARAM_FILE", "encode_op", "decode_op"]

HDR = struct.Struct("<HBBBBBBI")
MAX_DATA = 239
PAYLOAD = 251
MAX_SESSIONS = 4
BURST_PACKETS = 16
PARAM_DIR = "@PARAM"
PARAM_FILE = "@PARAM/param.pck"


class OP:
    NONE, TERMINATE, RESET, LIST, OPEN_RO, READ = 0, 1, 2, 3, 4, 5
    CREATE, WRITE, REMOVE, MKDIR, RMDIR, OPEN_WO, TRUNCATE, RENAME = 6, 7, 8, 9, 10, 11, 12, 13
    CRC32, BURST_READ = 14, 15
    ACK, NAK = 128, 129


class ERR:
    NONE, FAIL, FAIL_ERRNO, INVALID_SIZE, INVALID_SESSION, NO_SESSIONS = 0, 1, 2, 3, 4, 5
    EOF, UNKNOWN_COMMAND, FILE_EXISTS, FILE_PROTECTED, FILE_NOT_FOUND = 6, 7, 8, 9, 10


_WRITE_OPS = frozenset(range(OP.CREATE, OP.RENAME + 1))


def decode_op(payload) -> tuple[int, int, int, int, int, int, int, bytes]:
    """(seq, session, opcode, size, req_opcode, burst_complete, offset, data[:size])."""
    raw = bytes(bytearray(payload[:PAYLOAD]))
    raw = raw + bytes(max(0, HDR.size - len(raw)))
    seq, session, opcode, size, req_op, burst, _pad, offset = HDR.unpack_from(raw)
    return seq, session, opcode, size, req_op, burst, offset, raw[HDR.size:HDR.size + size]


def encode_op(seq: int, session: int, opcode: int, req_opcode: int, offset: int,
              data: bytes = b"", burst_complete: int = 0) -> list[int]:
    """An FTP payload as FILE_TRANSFER_PROTOCOL's uint8_t[251]."""
    raw = HDR.pack(seq & 0xFFFF, session, opcode, len(data), req_opcode, burst_complete, 0,
                   offset & 0xFFFFFFFF) + data
    return list(raw) + [0] * (PAYLOAD - len(raw))


class _Session:
    __slots__ = ("data", "fd", "size")

    def __init__(self, data: bytes | None, fd: int | None, size: int) -> None:
        self.data = data          # in-memory file (@PARAM/param.pck) or None
        self.fd = fd              # read-only descriptor of a run-directory file or None
        self.size = size          # length at open (bytes)

    def read(self, offset: int, n: int) -> bytes:
        n = max(0, min(n, self.size - offset))
        if n == 0:
            return b""
        if self.data is not None:
            return self.data[offset:offset + n]
        try:
            return os.pread(self.fd, n, offset)
        except OSError:
            return b""

    def close(self) -> None:
        if self.fd is not None:
            try:
                os.close(self.fd)
            except OSError:
                pass
            self.fd = None


class _Burst:
    __slots__ = ("peer", "ids", "seq", "session", "offset", "size", "left")

    def __init__(self, peer, ids, seq, session, offset, size) -> None:
        self.peer, self.ids, self.seq, self.session = peer, ids, seq, session
        self.offset, self.size, self.left = offset, size, BURST_PACKETS


class FtpService:
    """The FTP server's state: open sessions and the running burst."""

    def __init__(self, root: str | None, params=None, pacer: Pacer | None = None) -> None:
        self.root = os.path.realpath(root) if root else None
        self.params = params                 # the ParamTable behind @PARAM/param.pck
        self.sessions: dict[int, _Session] = {}
        self.burst: _Burst | None = None
        self.pacer = pacer or Pacer()
        self.naks = 0                        # counters
        self.acks = 0

    @property
    def busy(self) -> bool:
        return self.burst is not None

    # ------------------------------------------------------------------ requests
    def handle(self, m, peer, now_s: float) -> list:
        """One FILE_TRANSFER_PROTOCOL request from ``peer``: its immediate answer."""
        seq, session, op, size, _req, _bc, offset, data = decode_op(m.payload)
        ids = (m.get_srcSystem(), m.get_srcComponent())

        def ack(payload: bytes = b"", off: int = offset) -> list:
            self.acks += 1
            return [(peer, self._msg(ids, seq + 1, session, OP.ACK, op, off, payload))]

        def nak(code: int) -> list:
            self.naks += 1
            return [(peer, self._msg(ids, seq + 1, session, OP.NAK, op, offset, bytes((code,))))]

        if op == OP.TERMINATE:
            s = self.sessions.pop(session, None)
            if s is not None:
                s.close()
            if self.burst is not None and self.burst.session == session:
                self.burst = None
            return ack()
        if op == OP.RESET:
            self.reset()
            return ack()
        if op == OP.LIST:
            return self._list(_path(data), offset, ack, nak)
        if op == OP.OPEN_RO:
            return self._open(session, _path(data), ack, nak)
        if op in (OP.READ, OP.BURST_READ):
            s = self.sessions.get(session)
            if s is None:
                return nak(ERR.INVALID_SESSION)
            if offset >= s.size:
                return nak(ERR.EOF)
            want = size if 0 < size <= MAX_DATA else MAX_DATA
            if op == OP.READ:
                return ack(s.read(offset, want))
            self.burst = _Burst(peer, ids, seq, session, offset, want)
            return []
        if op in _WRITE_OPS:
            return nak(ERR.FILE_PROTECTED)
        return nak(ERR.UNKNOWN_COMMAND)

    def _msg(self, ids, seq, session, opcode, req_op, offset, data, burst_complete=0):
        return ML.MAVLink_file_transfer_protocol_message(
            0, ids[0], ids[1], encode_op(seq, session, opcode, req_op, offset, data,
                                         burst_complete))

    def _entries(self, path: str) -> list[bytes] | None:
        """The directory's entries (ListDirectory format), or None if it is not one."""
        if path == PARAM_DIR:
            size = len(pack_params(self.params)) if self.params is not None else 0
            return [b"Fparam.pck\t%d" % size]
        full = self._resolve(path)
        if full is None or not os.path.isdir(full):
            return None
        out = [b"D" + PARAM_DIR.encode()] if full == self.root and self.params is not None else []
        try:
            names = sorted(os.listdir(full))
        except OSError:
            return None
        for name in names:
            p = os.path.join(full, name)
            try:
                enc = name.encode("ascii")
            except UnicodeEncodeError:
                continue
            if os.path.isfile(p):
                out.append(b"F%s\t%d" % (enc, os.path.getsize(p)))
            elif os.path.isdir(p):
                out.append(b"D" + enc)
        return out

    def _list(self, path: str, first: int, ack, nak) -> list:
        entries = self._entries(path)
        if entries is None:
            return nak(ERR.FILE_NOT_FOUND)
        if first >= len(entries):
            return nak(ERR.EOF)
        data = b""
        for e in entries[first:]:
            if len(data) + len(e) + 1 > MAX_DATA:
                break
            data += e + b"\0"
        return ack(data)

    def _open(self, session: int, path: str, ack, nak) -> list:
        old = self.sessions.pop(session, None)
        if old is not None:
            old.close()
        if len(self.sessions) >= MAX_SESSIONS:
            return nak(ERR.NO_SESSIONS)
        name, _, query = path.partition("?")
        if name == PARAM_FILE and self.params is not None:
            blob = pack_params(self.params, with_defaults="withdefaults=1" in query)
            s = _Session(blob, None, len(blob))
        else:
            full = self._resolve(name)
            if full is None or not os.path.isfile(full):
                return nak(ERR.FILE_NOT_FOUND)
            try:
                fd = os.open(full, os.O_RDONLY)
            except OSError:
                return nak(ERR.FILE_NOT_FOUND)
            s = _Session(None, fd, os.fstat(fd).st_size)
        self.sessions[session] = s
        return ack(struct.pack("<I", s.size & 0xFFFFFFFF), 0)

    def _resolve(self, path: str) -> str | None:
        """The real path of ``path`` inside the run directory, or None (outside, no root)."""
        if self.root is None:
            return None
        full = os.path.realpath(os.path.join(self.root, path))
        if full != self.root and not full.startswith(self.root + os.sep):
            return None
        return full

    # ------------------------------------------------------------------ streaming
    def take(self, now_s: float, budget: int) -> list:
        """The next packets of the running burst (``(peer, message)``), paced."""
        b = self.burst
        if b is None:
            return []
        n = self.pacer.allowance(now_s, budget)
        out = []
        s = self.sessions.get(b.session)
        while len(out) < n and b is not None:
            if s is None:
                self.burst = b = None
                break
            data = s.read(b.offset, b.size)
            b.left -= 1
            b.seq += 1
            end = b.offset + len(data) >= s.size or not data
            done = end or b.left <= 0
            if not data:
                out.append((b.peer, self._msg(b.ids, b.seq, b.session, OP.NAK, OP.BURST_READ,
                                              b.offset, bytes((ERR.EOF,)), 1)))
            else:
                out.append((b.peer, self._msg(b.ids, b.seq, b.session, OP.ACK, OP.BURST_READ,
                                              b.offset, data, 1 if done else 0)))
            b.offset += len(data)
            if done:
                self.burst = b = None
        self.pacer.spend(len(out))
        return out

    def reset(self) -> None:
        """Close every session (ResetSessions; the fc's exit)."""
        for s in self.sessions.values():
            s.close()
        self.sessions.clear()
        self.burst = None

    close = reset


def _path(data: bytes) -> str:
    """A request's path: ASCII up to the first NUL, without leading "/" or "./"."""
    name = data.split(b"\0", 1)[0].decode("ascii", "replace").strip()
    while name.startswith("/") or name.startswith("./"):
        name = name[1:] if name.startswith("/") else name[2:]
    return "" if name in (".", "") else name.rstrip("/")
