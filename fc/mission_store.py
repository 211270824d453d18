"""fc/mission_store.py - the mission and home kept across an fc restart (issue 22, item 7).

A restarted fc must fly on: the stored mission (its items, the current item) and home (the
first GNSS fix, fc/gcs.py) are written beside the parameters (``mission.json``) with the same
atomic write (fc/storage.py), from the I/O thread when they change (fc/loops.py
``Housekeeping`` savers, at most once a second) and at exit, and restored at start.
"""
from __future__ import annotations

import json
import logging
import math
import os
from typing import Callable

from fc.mission import Mission
from fc.storage import DiskHealth, atomic_write

__all__ = ["MissionStore", "FILE_NAME"]

FILE_NAME = "mission.json"


class MissionStore:
    """Saves and restores ``mission`` and home (``home_of()``: (lat deg, lon deg, alt m) or
    None) at ``path``."""

    def __init__(self, mission: Mission, path: str,
                 home_of: Callable[[], tuple[float, float, float] | None],
                 log: logging.Logger | None = None, disk: DiskHealth | None = None) -> None:
        self.mission = mission
        self.disk = disk
        self.path = path
        self.home_of = home_of
        self.log = log or logging.getLogger("fc")
        self._saved_key = None

    def _key(self) -> tuple:
        m = self.mission
        return (m.version, m.count, m.current, m.finished, self.home_of())

    def snapshot(self) -> bytes | None:
        """The file's bytes when the mission, its current item or home changed since the
        last call, else None."""
        key = self._key()
        if key == self._saved_key:
            return None
        self._saved_key = key
        return self._document()

    def _document(self) -> bytes:
        """The file's bytes now. Apart from :meth:`snapshot`: its comprehension's closure over
        the mission made a cell object on every call, also when nothing changed (issue 24)."""
        m = self.mission
        doc = {"items": [m.item(i) for i in range(m.count)], "current": m.current,
               "finished": m.finished, "home": self.home_of()}
        return json.dumps(doc, allow_nan=True).encode("ascii")

    def save(self, data: bytes) -> None:
        """Write a snapshot (I/O thread); a failure goes to the disk health and the next
        ``snapshot`` tries again."""
        try:
            atomic_write(self.path, data)
        except OSError as exc:
            self._saved_key = None           # tried again at the next snapshot
            if self.disk is None or self.disk.failed("mission", exc):
                self.log.error("cannot save the mission to %s: %s", self.path, exc)
            return
        if self.disk is not None:
            self.disk.ok("mission")

    def load(self) -> tuple[float, float, float] | None:
        """Restore the mission from the file (none: nothing to do); returns home or None.
        A file that cannot be read or holds an invalid item is logged and set aside."""
        try:
            with open(self.path, encoding="utf-8") as f:
                doc = json.load(f)
            items, current = list(doc["items"]), int(doc["current"])
            home = doc.get("home")
            if home is not None:
                home = tuple(float(v) for v in home)
                if len(home) != 3 or not all(math.isfinite(v) for v in home):
                    raise ValueError(f"home {home}")
            reason = self.mission.restore(items, current, bool(doc.get("finished", False)))
            if reason is not None:
                raise ValueError(reason)
        except FileNotFoundError:
            self._saved_key = self._key()    # nothing to save until something changes
            return None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            self.log.error("mission file %s not restored (%s); kept aside", self.path, exc)
            try:
                os.replace(self.path, self.path + ".bad")
            except OSError:
                pass
            return None
        self._saved_key = self._key()[:4] + (home,)
        return home
