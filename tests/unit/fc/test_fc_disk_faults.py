"""Unit tier: a full disk is seen and survived (issue 22, item 5; fc/storage.py).

Every write of the fc goes through ``fc.storage.write_all``; here a hook makes it raise ENOSPC
(the HIL test tests/hil/test_disk_full.py does it with a real tmpfs): the internals log drops
rows and resumes, its close leaves no partial file, the parameter file is kept and the fault
is reported, once per minute, and in SYS_STATUS's logging health bit.
"""
from __future__ import annotations

import errno
import logging
import os

import numpy as np
import pytest

from fc import storage
from fc.gcs import GcsLink
from fc.internals_log import InternalsLog, load
from fc.link import mavlink as ML, new_codec
from fc.param_service import ParamService
from fc.params import build_table
from fc.storage import DiskHealth, atomic_write
from tests.fc_harness import free_udp_port
from tests.unit.fc.test_gcs_links import _Vehicle


class _Disk:
    """The hook: ``full`` True makes every write raise ENOSPC."""

    def __init__(self, monkeypatch) -> None:
        self.full = False
        real = storage.write_all

        def write_all(fd, data):
            if self.full:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real(fd, data)
        monkeypatch.setattr(storage, "write_all", write_all)


@pytest.fixture()
def disk(monkeypatch):
    return _Disk(monkeypatch)


def _fill(log: InternalsLog, first: int, n: int) -> None:
    for i in range(first, first + n):
        row = log.row()
        while row is None:                # the writer is behind: wait for it (a test only)
            log.sync()
            row = log.row()
        row[:] = (i, 2.0 * i)


def test_internals_log_survives_enospc_and_resumes_when_space_returns(tmp_path, disk):
    health = DiskHealth()
    log = InternalsLog(str(tmp_path), ["i", "x"], chunk_rows=8, n_chunks=4, disk=health)
    _fill(log, 0, 16)
    log.sync()
    # GIVEN a disk that fills up: two chunks cannot be written
    disk.full = True
    _fill(log, 16, 16)
    log.sync()
    assert log.lost_rows == 16 and health.failing
    assert "internals log not written" in health.report(0.0)
    # WHEN space returns: the writer thread is alive and writes again
    disk.full = False
    _fill(log, 32, 16)
    log.sync()
    assert log._thread.is_alive() and not health.failing
    data = load(log.close())
    # THEN the file holds exactly the rows written, whole
    assert np.array_equal(data["i"], np.r_[0:16, 32:48].astype(float))
    assert np.array_equal(data["x"], 2.0 * data["i"])


def test_internals_log_close_on_a_full_disk_leaves_no_partial_file(tmp_path, disk):
    health = DiskHealth()
    log = InternalsLog(str(tmp_path), ["i", "x"], chunk_rows=8, n_chunks=4, disk=health)
    _fill(log, 0, 20)
    log.sync()
    disk.full = True
    path = log.close()                     # no exception
    # THEN no npz, partial or whole; the raw companion kept, with every row written
    assert sorted(os.listdir(tmp_path)) == ["fc_internals.cols.json", "fc_internals.raw"]
    assert np.array_equal(load(path)["i"], np.arange(20.0))
    assert health.failing


def test_atomic_write_on_a_full_disk_keeps_the_old_file_and_no_temp(tmp_path, disk):
    path = tmp_path / "params.parm"
    atomic_write(str(path), b"A 1\n")
    disk.full = True
    with pytest.raises(OSError):
        atomic_write(str(path), b"A 2\n")
    assert path.read_bytes() == b"A 1\n" and os.listdir(tmp_path) == ["params.parm"]


def _save_only_service(tmp_path) -> ParamService:
    """A ParamService for its save only (no law, no guidance): a fresh table, the file
    ``p.parm`` in ``tmp_path``, its own DiskHealth."""
    svc = ParamService.__new__(ParamService)
    svc.table, svc.path, svc.log, svc.disk, svc.dirty = (build_table(), str(tmp_path / "p.parm"),
                                                         logging.getLogger("test"), DiskHealth(),
                                                         False)
    return svc


def test_a_parameter_that_cannot_be_saved_is_reported_not_silently_accepted(tmp_path, disk):
    svc = _save_only_service(tmp_path)
    table, health = svc.table, svc.disk
    disk.full = True
    svc.save()
    # THEN the fault is known, said, and the next change is reported as not saved
    assert health.error_of("parameters") is not None and svc.dirty
    v = _Vehicle()
    link = GcsLink(v, ("127.0.0.1", free_udp_port()), [], disk=health)
    try:
        gcs = new_codec(255, 190)
        m = gcs.param_set_encode(1, 1, b"TRIM_RUD_DEG", 2.0, ML.MAV_PARAM_TYPE_REAL32)
        m.pack(gcs)
        link._param_set(m)
        texts = "".join(t[1].decode() for t in link.text_queue)
        assert "TRIM_RUD_DEG set, NOT saved" in texts
        assert link.text_queue[0][0] == ML.MAV_SEVERITY_ERROR
    finally:
        link.close()


def test_disk_faults_are_said_at_once_then_once_per_minute():
    health = DiskHealth(every_s=60.0)
    assert health.report(0.0) is None
    health.failed("tlog", OSError(errno.ENOSPC, "No space left on device"))
    said = [t for t in (health.report(k * 1.0) for k in range(0, 181)) if t is not None]
    assert said == ["DISK: tlog not written (No space left on device)"] * 4    # 0, 60, 120, 180 s
    health.ok("tlog")
    assert health.report(200.0) is None and not health.failing
    health.failed("parameters", OSError(errno.EIO, "Input/output error"))
    assert health.report(201.0) == "DISK: parameters not written (Input/output error)"
    # something new failing is said at once, within the minute
    health.failed("tlog", OSError(errno.ENOSPC, "No space left on device"))
    assert health.report(202.0) == ("DISK: parameters not written (Input/output error); "
                                    "tlog not written (No space left on device)")
    assert health.report(203.0) is None


class _SavingVehicle(_Vehicle):
    """The stub vehicle with a parameter file: ``save_params`` as the flight controller's
    (fc/app.py: ParamService.save on the I/O thread)."""

    def __init__(self, svc: ParamService, io) -> None:
        super().__init__()
        self.params = svc.table
        self.svc, self.io = svc, io

    def save_params(self, done):
        values = self.svc.snapshot(force=True)
        self.io.submit(lambda: done(self.svc.save(values)))
        return True


def _param_set(link: GcsLink, name: bytes, value: float) -> None:
    gcs = new_codec(255, 190)
    m = gcs.param_set_encode(1, 1, name, value, ML.MAV_PARAM_TYPE_REAL32)
    m.pack(gcs)
    link._param_set(m)


@pytest.mark.parametrize("full", [True, False])
def test_the_first_param_set_on_a_full_disk_is_not_echoed_as_simply_accepted(tmp_path, disk,
                                                                             full):
    """GIVEN a disk that is full but has not failed a write yet (the health knows nothing),
    WHEN a ground station sets a parameter, THEN its answer waits for the save: an ERROR
    STATUSTEXT `NOT saved` before the PARAM_VALUE; on a good disk the PARAM_VALUE alone, after
    the file holds the value. (Before: the echo at once, the failure only in fc.log.)"""
    from fc.iothread import IoThread
    svc = _save_only_service(tmp_path)
    table, health = svc.table, svc.disk
    io = IoThread()
    v = _SavingVehicle(svc, io)
    link = GcsLink(v, ("127.0.0.1", free_udp_port()), [], disk=health)
    sent, texts = [], []
    link.send = lambda msg, log=True: sent.append(("send", msg.get_type(), getattr(
        msg, "param_id", "")))
    link.statustext = lambda sev, text: (texts.append((sev, text)),
                                         sent.append(("text", "STATUSTEXT", text)))
    try:
        disk.full = full
        assert not health.failing
        _param_set(link, b"TRIM_RUD_DEG", 2.0)
        assert [s for s in sent if s[1] == "PARAM_VALUE"] == []    # not before the save
        io.close()                                                 # the save has run
        link.service(1e9)
        echoes = [s for s in sent if s[1] == "PARAM_VALUE"]
        assert len(echoes) == 1 and echoes[0][2] == "TRIM_RUD_DEG"
        assert table.get("TRIM_RUD_DEG") == 2.0                    # set in memory either way
        if full:
            assert (ML.MAV_SEVERITY_ERROR,
                    "TRIM_RUD_DEG set, NOT saved (disk: No space left on device)") in texts
            assert health.error_of("parameters") is not None
            kinds = [s[1] for s in sent if s[1] in ("STATUSTEXT", "PARAM_VALUE")]
            assert kinds == ["STATUSTEXT", "PARAM_VALUE"]                 # said first
        else:
            assert not any("NOT saved" in t for _, t in texts)
            assert "TRIM_RUD_DEG" in (tmp_path / "p.parm").read_text()
        # a command (not kept on file) is answered at once
        sent.clear()
        _param_set(link, b"CMD_MU_DEG", 1.0)
        assert [s[1] for s in sent] == ["PARAM_VALUE"]
    finally:
        link.close()


def test_the_disk_report_releases_its_lock_and_allocates_nothing_while_healthy():
    from tests.unit.fc.test_gcs_links import _blocks
    health = DiskHealth(every_s=60.0)
    # GIVEN a healthy disk: no text, the lock free after, and no Python block (``with`` on the
    # lock made two bound methods per call of the 1 Hz chore, issue 24)
    assert health.report(0.0) is None and not health._lock.locked()
    assert _blocks(lambda: health.report(1.0)) == 0
    # WHEN a write fails: said, and the lock free after saying it and after holding it back
    health.failed("tlog", OSError(errno.ENOSPC, "No space left on device"))
    assert health.report(2.0) is not None and not health._lock.locked()
    assert health.report(3.0) is None and not health._lock.locked()
    # AND a report that raises inside (an unsortable fault table) leaves the lock free
    health._failing[None] = "x"
    with pytest.raises(TypeError):
        health.report(100.0)
    assert not health._lock.locked()
