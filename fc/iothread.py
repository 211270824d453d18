"""fc/iothread.py - one background thread for the fc's slow I/O (files), off the control loop.

The loop hands over finished work (``submit(fn, *args)``): tlog chunks, parameter-file
saves. A write that blocks on a busy disk (page-cache throttling, fsync) then delays this
thread, never a control tick. ``close()`` runs what is queued and joins.
"""
from __future__ import annotations

import logging
import queue
import threading

__all__ = ["IoThread"]


class IoThread:
    def __init__(self, log: logging.Logger | None = None) -> None:
        self.log = log or logging.getLogger("fc")
        self._q: queue.SimpleQueue = queue.SimpleQueue()
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name="fc-io", daemon=True)
        self._thread.start()

    def submit(self, fn, *args) -> None:
        self._q.put((fn, args))

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            fn, args = item
            try:
                fn(*args)
            except Exception as exc:  # noqa: BLE001 - report and keep serving
                self.errors += 1
                self.log.error("background I/O failed: %r", exc)

    def close(self, timeout_s: float = 10.0) -> None:
        self._q.put(None)
        self._thread.join(timeout_s)
