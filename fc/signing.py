"""fc/signing.py - MAVLink 2 signing of the ground-station link that holds (docs/fc.md, Signing).

The MAVLink spec (mavlink.io "Message Signing"): the signature is the first 48 bits of
SHA-256(secret key + header + payload + CRC + link id + timestamp); the timestamp (10 us
units since 2015-01-01) of each stream (link id, system, component) must grow; the timestamp
is stored persistently (at least once a minute) and at start it is the larger of the stored
one and the system clock.

pymavlink 2.4.50's ``MAVLink.check_signature`` stores the stream's timestamp *before* it
checks the signature, so one forged frame (the GCS's link id, system and component are sent
in the clear, a timestamp near 2^48, any signature) locks that stream out until a restart, and
256 datagrams lock out every link id. :class:`SigningGuard` replaces that method on our codec
(``install``): the signature is verified first, in constant time, and only a frame that
carries a valid one touches any state. The stream timestamps persist beside the parameters
(``signing.json``, fc/storage.py ``atomic_write``): a signed message captured before a restart
is stale after it. A stream the fc has not heard is accepted only with a timestamp newer
than every timestamp the fc had accepted when it last saved (``floor``), and, as the spec
and pymavlink have it, at most a minute behind the fc's own timestamp.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import logging
import os
import struct
import time

from fc.storage import atomic_write

__all__ = ["SigningGuard", "SIGNING_EPOCH_S", "clock_timestamp", "signature_ok", "FILE_NAME"]

SIGNING_EPOCH_S = 1420070400          # 2015-01-01T00:00:00Z
#: a new stream may be this far behind the fc's own timestamp (10 us units: 60 s, the spec's)
NEW_STREAM_BEHIND = 6000 * 1000
FILE_NAME = "signing.json"
_SIG_BLOCK = 13                       # link id (1), timestamp (6), signature (6)


def clock_timestamp(now_s: float | None = None) -> int:
    """The system clock as a signing timestamp (10 us units since 2015-01-01)."""
    return int(((time.time() if now_s is None else now_s) - SIGNING_EPOCH_S) * 1e5)


def signature_ok(key: bytes, msgbuf) -> bool:
    """True when the signed frame ``msgbuf`` (its whole bytes, signature block included)
    carries the signature of ``key``: sha256(key + frame up to the timestamp)[:6]."""
    if len(msgbuf) < _SIG_BLOCK + 12:
        return False
    h = hashlib.sha256(key)
    h.update(bytes(msgbuf[:-6]))
    return hmac.compare_digest(h.digest()[:6], bytes(msgbuf[-6:]))


class SigningGuard:
    """The receive side of signing: verify, then the stream timestamps; saved and restored.

    ``streams``: (link id, system, component) -> the newest accepted timestamp.
    ``floor``: a stream not in ``streams`` must be newer than this (the newest timestamp the
    fc knew when the file was last saved; 0 without a file).
    """

    def __init__(self, key: bytes, path: str | None = None,
                 log: logging.Logger | None = None) -> None:
        self.key = key
        self.path = path
        self.log = log or logging.getLogger("fc")
        self.streams: dict[tuple[int, int, int], int] = {}
        self.floor = 0
        self.stored_timestamp = 0         # the fc's own timestamp in the file
        self.dirty = False
        self.bad_signatures = 0           # frames with the signed flag and a wrong signature
        self.stale = 0                    # good signature, timestamp not newer (replays)
        if path is not None:
            self.load()

    # ------------------------------------------------------------------ receive
    def install(self, mav) -> None:
        """Make ``mav`` (a pymavlink codec with ``signing.secret_key`` set) check incoming
        signatures here instead of in pymavlink's ``check_signature``."""
        signing = mav.signing

        def check_signature(msgbuf, src_system: int, src_component: int) -> bool:
            return self.check(signing, msgbuf, src_system, src_component)

        mav.check_signature = check_signature

    def check(self, signing, msgbuf, src_system: int, src_component: int) -> bool:
        """Accept a signed frame: signature first (nothing changes when it is wrong), then
        the stream's timestamp must grow; ``signing.timestamp`` (what the fc signs with next)
        follows the newest accepted timestamp, as the spec has it."""
        if not signature_ok(self.key, msgbuf):
            self.bad_signatures += 1
            return False
        link_id = msgbuf[-_SIG_BLOCK]
        lo, hi = struct.unpack("<IH", bytes(msgbuf[-12:-6]))
        ts = lo | (hi << 32)
        key = (int(link_id), int(src_system), int(src_component))
        last = self.streams.get(key)
        if last is not None:
            if ts <= last:
                self.stale += 1
                return False
        elif ts <= self.floor or ts + NEW_STREAM_BEHIND < signing.timestamp:
            self.stale += 1
            return False
        self.streams[key] = ts
        self.dirty = True
        if ts > signing.timestamp:
            signing.timestamp = ts
        return True

    # ------------------------------------------------------------------ persistence
    def start_timestamp(self) -> int:
        """The timestamp to sign with at start: the larger of the stored one and the clock."""
        return max(self.stored_timestamp + 1, clock_timestamp())

    def load(self) -> None:
        """Read the saved state (a missing file: a first start; an unreadable one is logged
        and set aside: the floor is then the clock less a minute, as for a new stream)."""
        try:
            with open(self.path, encoding="utf-8") as f:
                doc = json.load(f)
            streams = {(int(a), int(b), int(c)): int(t) for a, b, c, t in doc["streams"]}
            own = int(doc["timestamp"])
        except FileNotFoundError:
            return
        except (OSError, ValueError, KeyError, TypeError) as exc:
            self.log.error("signing state %s unreadable (%s): every stream starts new",
                           self.path, exc)
            try:
                os.replace(self.path, self.path + ".bad")
            except OSError:
                pass
            return
        self.streams = streams
        self.stored_timestamp = own
        self.floor = max([own, *streams.values()])

    def snapshot(self, own_timestamp: int) -> bytes | None:
        """The file's bytes when a stream changed since the last call, else None.
        ``own_timestamp``: the fc's current signing timestamp (the largest of its links)."""
        if not self.dirty:
            return None
        self.dirty = False
        doc = {"timestamp": int(own_timestamp),
               "streams": [[*k, t] for k, t in sorted(self.streams.items())]}
        return json.dumps(doc).encode("ascii")

    def save(self, data: bytes) -> None:
        """Write a snapshot (on the I/O thread); OSError as raised (the caller reports it)."""
        atomic_write(self.path, data)
