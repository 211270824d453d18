"""Unit tier: read-only MAVLink FTP (fc/gcs_ftp.py, fc/gcs_ftp_param.py): requests in, ACK/NAK
out, files from a temporary run directory; time is passed in."""
from __future__ import annotations

import os
import struct

import pytest

os.environ["MAVLINK20"] = "1"
from fc.gcs_ftp import (BURST_PACKETS, ERR, MAX_DATA, MAX_SESSIONS, OP, FtpService,  # noqa: E402
                        decode_op, encode_op)
from fc.gcs_ftp_param import pack_params  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from fc.params import build_table  # noqa: E402
from tests.fc_harness import received  # noqa: E402

PEER = ("127.0.0.1", 14550)


class _Client:
    """A ground station's FTP requests (seq counting as a client does)."""

    def __init__(self, svc: FtpService, session: int = 0) -> None:
        self.svc, self.session, self.seq = svc, session, 0

    def ask(self, op: int, data: bytes = b"", offset: int = 0, size: int | None = None):
        """Send one request; returns the decoded replies (op tuples) and checks their address."""
        payload = encode_op(self.seq, self.session, op, 0, offset, data)
        if size is not None:                      # a read's size field is the count wanted
            payload[4] = size
        self.seq += 1
        out = self.svc.handle(received(ML.MAVLink_file_transfer_protocol_message(0, 1, 1, payload)),
                              PEER, 0.0)
        return [self._check(o) for o in out]

    def _check(self, out):
        peer, m = out
        assert peer == PEER and (m.target_system, m.target_component) == (255, 190)
        return decode_op(m.payload)

    def burst(self, offset: int, size: int = MAX_DATA) -> list:
        assert self.ask(OP.BURST_READ, offset=offset, size=size) == []
        got, t = [], 0.0
        for _ in range(10_000):
            if not self.svc.busy:
                break
            t += 0.01
            got += [self._check(o) for o in self.svc.take(t, 6)]
        return got


@pytest.fixture()
def run_dir(tmp_path):
    (tmp_path / "fc.tlog").write_bytes(bytes(i % 256 for i in range(5000)))
    (tmp_path / "fc.log").write_text("hello\n")
    (tmp_path.parent / "secret.txt").write_text("outside")
    return tmp_path


def test_list_open_read_and_terminate(run_dir):
    c = _Client(FtpService(str(run_dir), build_table()))
    (seq, _s, op, size, req, _b, _o, data), = c.ask(OP.LIST, b"/")
    assert (seq, op, req) == (1, OP.ACK, OP.LIST)
    entries = data.split(b"\0")
    assert b"D@PARAM" in entries and b"Ffc.tlog\t5000" in entries and b"Ffc.log\t6" in entries
    (_, _, op, _, _, _, _, data), = c.ask(OP.LIST, b"/", offset=len(entries) - 1)
    assert op == OP.NAK and data == bytes((ERR.EOF,))
    (_, _, op, size, _, _, _, data), = c.ask(OP.OPEN_RO, b"/fc.tlog")
    assert op == OP.ACK and struct.unpack("<I", data)[0] == 5000
    (_, _, op, size, _, _, off, data), = c.ask(OP.READ, offset=4900, size=200)
    assert op == OP.ACK and off == 4900 and data == bytes(i % 256 for i in range(4900, 5000))
    (_, _, op, _, _, _, _, data), = c.ask(OP.READ, offset=5000, size=200)
    assert op == OP.NAK and data == bytes((ERR.EOF,))
    (_, _, op, *_), = c.ask(OP.TERMINATE)
    assert op == OP.ACK
    (_, _, op, _, _, _, _, data), = c.ask(OP.READ, offset=0, size=10)
    assert op == OP.NAK and data == bytes((ERR.INVALID_SESSION,))


def test_burst_read_returns_the_whole_file_in_bursts(run_dir):
    c = _Client(FtpService(str(run_dir), build_table()))
    c.ask(OP.OPEN_RO, b"fc.tlog")
    got, offset = b"", 0
    for _ in range(10):
        replies = c.burst(offset)
        assert len(replies) <= BURST_PACKETS and replies[-1][5] == 1    # burst_complete last
        if replies[-1][2] == OP.NAK:
            assert replies[-1][7] == bytes((ERR.EOF,))
            break
        for (_seq, _s, op, size, req, _b, off, data) in replies:
            assert op == OP.ACK and req == OP.BURST_READ and off == len(got)
            got += data
        offset = len(got)
        if len(replies[-1][7]) < MAX_DATA:       # a short last packet: the end
            break
    assert got == (run_dir / "fc.tlog").read_bytes()


def test_writes_paths_outside_and_unknown_opcodes_are_refused_at_once(run_dir):
    c = _Client(FtpService(str(run_dir), build_table()))
    for op, data, err in ((OP.CREATE, b"x", ERR.FILE_PROTECTED),
                          (OP.REMOVE, b"fc.log", ERR.FILE_PROTECTED),
                          (OP.OPEN_WO, b"fc.log", ERR.FILE_PROTECTED),
                          (OP.OPEN_RO, b"../secret.txt", ERR.FILE_NOT_FOUND),
                          (OP.OPEN_RO, b"/nope", ERR.FILE_NOT_FOUND),
                          (OP.LIST, b"/nope", ERR.FILE_NOT_FOUND),
                          (OP.CRC32, b"fc.log", ERR.UNKNOWN_COMMAND),
                          (77, b"", ERR.UNKNOWN_COMMAND)):
        (_, _, rop, _, req, _, _, rdata), = c.ask(op, data)
        assert (rop, req, rdata) == (OP.NAK, op, bytes((err,))), op
    assert (run_dir / "fc.log").read_text() == "hello\n"


def test_sessions_are_bounded_and_reset(run_dir):
    svc = FtpService(str(run_dir), build_table())
    clients = [_Client(svc, session=k) for k in range(MAX_SESSIONS + 1)]
    for c in clients[:-1]:
        assert c.ask(OP.OPEN_RO, b"fc.log")[0][2] == OP.ACK
    (_, _, op, _, _, _, _, data), = clients[-1].ask(OP.OPEN_RO, b"fc.log")
    assert op == OP.NAK and data == bytes((ERR.NO_SESSIONS,))
    assert clients[0].ask(OP.RESET)[0][2] == OP.ACK and svc.sessions == {}
    assert clients[-1].ask(OP.OPEN_RO, b"fc.log")[0][2] == OP.ACK


def test_param_pck_decodes_with_mavproxy_to_every_parameter_and_value(run_dir):
    param_ftp = pytest.importorskip("MAVProxy.modules.lib.param_ftp")
    table = build_table()
    table.values[table.index["FS_TIMEOUT_S"]] = 2.5
    c = _Client(FtpService(str(run_dir), table))
    (_, _, op, _, _, _, _, data), = c.ask(OP.OPEN_RO, b"@PARAM/param.pck?withdefaults=1")
    assert op == OP.ACK
    size = struct.unpack("<I", data)[0]
    blob = b""
    while len(blob) < size:
        (_, _, op, _, _, _, _, data), = c.ask(OP.READ, offset=len(blob), size=MAX_DATA)
        blob += data
    assert blob == pack_params(table, with_defaults=True)
    pdata = param_ftp.ftp_param_decode(blob)
    got = {n.decode(): v for n, v, _t in pdata.params}
    assert list(got) == table.names                          # every one, in index order
    for name in table.names:
        assert got[name] == pytest.approx(table.get(name), rel=1e-6), name
    defaults = {n.decode(): v for n, v, _t in pdata.defaults}
    assert defaults["FS_TIMEOUT_S"] == pytest.approx(table.defn("FS_TIMEOUT_S").default)
    ints = {n.decode() for n, _v, t in pdata.params if t == 3}
    assert ints == {d.name for d in table.defs if d.integer}
