"""fc/ratelimit.py - de-duplicating rate limiter for STATUSTEXT and fc.log lines.

A ground station can make the fc say something on every message it sends (a refused
parameter, a refused command), so what the fc says is bounded here, the way ArduPilot's
GCS_MAVLINK text queue and PX4's mavlink_log rate limits do:

- **per text**: a text repeated within ``quiet_s`` of its previous occurrence is not repeated,
  only counted; once it has been quiet for ``quiet_s`` a summary ``"<text> (N suppressed)"``
  is due (:meth:`RateLimiter.summaries`), and every ``hold_s`` while the repeats go on, so a
  condition that persists is not silenced for good;
- **overall**: a token bucket (``rate_hz`` sustained, ``burst`` at once) bounds distinct
  texts; texts over it are counted and summarised as ``"N messages suppressed"`` once the flood
  has been quiet for ``quiet_s``. Texts at ``bypass_severity`` or more severe (lower number:
  failsafe, law fault) are never held back by the bucket, only de-duplicated, so a flood cannot
  hide a failsafe.

Memory is bounded: only texts that were let through are remembered (at most ``max_keys``).
No clock is read here: the caller passes ``now_s`` (monotonic seconds).
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["RateLimiter"]


@dataclass(slots=True)
class _Seen:
    severity: int
    last_s: float                  # last occurrence
    sent_s: float                  # last time it (or its summary) went out
    suppressed: int = 0


@dataclass(slots=True)
class RateLimiter:
    """Decides which texts go out. ``allow`` per text; ``summaries`` from the periodic service."""

    rate_hz: float = 2.0           # sustained distinct texts per second
    burst: float = 10.0            # distinct texts at once
    quiet_s: float = 2.0           # a repeat this soon after the last one is suppressed
    hold_s: float = 30.0           # repeats going on this long: an interim summary
    bypass_severity: int = 3       # MAV_SEVERITY_ERROR and more severe skip the bucket
    max_keys: int = 64
    tokens: float = -1.0           # < 0: full bucket on first use
    last_refill_s: float = 0.0
    dropped: int = 0               # distinct texts over the bucket since the last summary
    dropped_severity: int = 7
    last_drop_s: float = 0.0
    total_suppressed: int = 0      # all texts held back, ever (telemetry, tests)
    seen: dict = field(default_factory=dict)

    def _refill(self, now_s: float) -> None:
        if self.tokens < 0:
            self.tokens = self.burst
        else:
            self.tokens = min(self.burst, self.tokens + (now_s - self.last_refill_s) * self.rate_hz)
        self.last_refill_s = now_s

    def allow(self, now_s: float, severity: int, text: str) -> bool:
        """True if ``text`` should go out now; False if it is held back (and counted)."""
        s = self.seen.get(text)
        if s is not None and now_s - s.last_s < self.quiet_s:
            s.last_s = now_s
            s.suppressed += 1
            self.total_suppressed += 1
            return False
        self._refill(now_s)
        if severity > self.bypass_severity:
            if self.tokens < 1.0:
                self.dropped += 1
                self.dropped_severity = min(self.dropped_severity, severity)
                self.last_drop_s = now_s
                self.total_suppressed += 1
                return False
            self.tokens -= 1.0
        if s is None and len(self.seen) >= self.max_keys:
            oldest = min(self.seen, key=lambda k: self.seen[k].last_s)
            del self.seen[oldest]      # its repeats (if any) are counted in no summary
        self.seen[text] = _Seen(severity, now_s, now_s)
        return True

    @property
    def idle(self) -> bool:
        """Nothing held back or remembered: :meth:`summaries` would say nothing."""
        return not self.seen and not self.dropped

    def summaries(self, now_s: float) -> list[tuple[int, str]]:
        """Summaries of bursts that have ended: ``[(severity, text), ...]``; forgets quiet texts."""
        out: list[tuple[int, str]] = []
        for text, s in list(self.seen.items()):
            quiet = now_s - s.last_s >= self.quiet_s
            if s.suppressed and (quiet or now_s - s.sent_s >= self.hold_s):
                out.append((s.severity, f"{text} ({s.suppressed} suppressed)"))
                s.suppressed = 0
                s.sent_s = now_s
            if quiet:
                del self.seen[text]
        if self.dropped and now_s - self.last_drop_s >= self.quiet_s:
            out.append((self.dropped_severity, f"{self.dropped} messages suppressed"))
            self.dropped = 0
            self.dropped_severity = 7
        return out
