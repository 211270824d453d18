"""fc/storage.py - the fc's writes to disk: one write call, atomic files, disk health.

Every byte the fc puts on disk (parameters, signing timestamps, the mission and home, the
.tlog, the internals log) goes through :func:`write_all`, so a full or failing disk is met at
one place (and a test can make that place raise ENOSPC: ``monkeypatch.setattr(storage,
"write_all", ...)``). Small state files (parameters, signing timestamps, mission) are written
with :func:`atomic_write`: temp file in the same directory, fsync, rename, so a reader sees
the old file or the new one, never a part (as PX4's ``mavlink_signing_storage`` and
parameter files).

:class:`DiskHealth` records what could not be written. The fc says it once per minute as a
STATUSTEXT (severity ERROR) and clears SYS_STATUS's MAV_SYS_STATUS_LOGGING health bit while
it lasts (fc/loops.py ``Housekeeping``, fc/app.py ``health_failed_bits``); the flight goes on.
"""
from __future__ import annotations

import io
import os
import tempfile
import threading

__all__ = ["write_all", "atomic_write", "open_for_write", "AppendFile", "DiskHealth",
           "REPORT_EVERY_S"]

#: a disk fault that lasts is said again this often (s)
REPORT_EVERY_S = 60.0


def write_all(fd: int, data) -> None:
    """Write all of ``data`` (bytes-like) to the file descriptor ``fd``; OSError (ENOSPC,
    EIO, ...) as the system raises it. The one write call of the fc."""
    view = memoryview(data).cast("B")
    while view:
        n = os.write(fd, view)
        view = view[n:]


def atomic_write(path: str, data: bytes) -> None:
    """Replace ``path`` by ``data`` atomically: a temp file in the same directory, written,
    fsync'ed, renamed over ``path``. On any failure the temp file is removed and ``path`` is
    left as it was; the error is raised."""
    directory = os.path.dirname(os.path.abspath(path)) or "."
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=directory)
    try:
        try:
            write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


class DiskHealth:
    """What could not be written, by whom (``what``: "parameters", "internals log", ...).

    ``failed``/``ok`` may be called from any thread (the I/O thread, the internals-log
    writer); ``report`` from the loop: the text to say, at most once per ``every_s``.
    """

    def __init__(self, every_s: float = REPORT_EVERY_S) -> None:
        self.every_s = every_s
        self._lock = threading.Lock()
        self._failing: dict[str, str] = {}     # what -> the last error
        self.failures = 0                      # writes that failed, ever
        self._next_report_s = 0.0
        self._said: set[str] = set()           # what the last report named

    @property
    def failing(self) -> bool:
        return bool(self._failing)

    def failed(self, what: str, exc: BaseException) -> bool:
        """A write of ``what`` failed with ``exc``. True when ``what`` was not failing before
        (the caller logs the first failure only; the repeats are in the reports)."""
        text = exc.strerror if isinstance(exc, OSError) and exc.strerror else repr(exc)
        with self._lock:
            self.failures += 1
            new = what not in self._failing
            self._failing[what] = text
        return new

    def ok(self, what: str) -> None:
        """A write of ``what`` succeeded (its fault, if any, is over)."""
        if what in self._failing:
            with self._lock:
                self._failing.pop(what, None)

    def error_of(self, what: str) -> str | None:
        """The last error of ``what`` while it is failing, else None."""
        return self._failing.get(what)

    def report(self, now_s: float) -> str | None:
        """The text to say now (a fault of something new at once, a lasting one every
        ``every_s``), or None. ``now_s``: monotonic seconds."""
        # the lock taken by its methods, not by ``with``: ``with`` looked up ``__enter__`` and
        # ``__exit__`` as bound method objects, two blocks per call of the 1 Hz chore (issue 24)
        lock = self._lock
        lock.acquire()
        try:
            if not self._failing:               # (no set made: the 1 Hz chore, issue 24)
                self._said.clear()              # what recovered is new again next time
                return None
            return self._report_failing(now_s)
        finally:
            lock.release()

    def _report_failing(self, now_s: float) -> str | None:
        """:meth:`report` while something is failing (the lock held)."""
        self._said &= set(self._failing)
        if now_s < self._next_report_s and set(self._failing) <= self._said:
            return None
        self._next_report_s = now_s + self.every_s
        self._said = set(self._failing)
        parts = "; ".join(f"{w} not written ({e})" for w, e in sorted(self._failing.items()))
        return f"DISK: {parts}"


class AppendFile:
    """A log file written by appending whole records (.tlog chunks, internals-log rows).

    A write that fails (ENOSPC, EIO) is dropped whole: the file is cut back to its last good
    size, so it never holds a partial record, and the failure goes to ``disk`` (what =
    ``what``); the next append tries again, so the log resumes when space returns.
    """

    def __init__(self, path: str, what: str, disk: DiskHealth | None = None) -> None:
        self.path = path
        self.what = what
        self.disk = disk
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self.size = 0                 # bytes on file, all whole records
        self.dropped_b = 0            # bytes of records that could not be written

    def append(self, data) -> bool:
        """Append ``data``; False (counted, reported) when it could not be written."""
        n = memoryview(data).nbytes
        try:
            write_all(self.fd, data)
        except OSError as exc:
            self.dropped_b += n
            if self.disk is not None:
                self.disk.failed(self.what, exc)
            try:
                os.ftruncate(self.fd, self.size)
                os.lseek(self.fd, self.size, os.SEEK_SET)
            except OSError:
                pass
            return False
        self.size += n
        if self.disk is not None:
            self.disk.ok(self.what)
        return True

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


class _FdRaw(io.RawIOBase):
    """A raw binary file over a descriptor whose writes go through :func:`write_all`."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self.fd = fd

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def write(self, b) -> int:
        write_all(self.fd, b)
        return memoryview(b).nbytes

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return os.lseek(self.fd, offset, whence)

    def tell(self) -> int:
        return os.lseek(self.fd, 0, os.SEEK_CUR)

    def close(self) -> None:
        if not self.closed:
            try:
                os.close(self.fd)
            finally:
                super().close()


def open_for_write(path: str) -> io.BufferedWriter:
    """``path`` opened for writing (created, truncated) as a buffered binary file whose
    writes go through :func:`write_all` (for writers that want a file object: np.savez)."""
    return io.BufferedWriter(_FdRaw(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)))
