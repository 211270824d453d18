"""A text progress bar for campaigns: cases done, failures so far, rate, time left.

On a terminal it redraws one line (at most ``hz`` times a second); otherwise (a log file,
CI) it prints a plain line every ``every_s`` wall seconds and at the end.
"""
from __future__ import annotations

import sys
import time


def _hms(s: float) -> str:
    if s != s or s == float("inf"):
        return "--:--"
    s = int(round(s))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m:02d}:{sec:02d}"


class Progress:
    """Progress of ``total`` cases, of which ``already`` were finished before this run."""

    def __init__(self, total: int, already: int = 0, stream=None, hz: float = 4.0,
                 every_s: float = 10.0, width: int = 28):
        self.total = total
        self.already = already
        self.done = 0            # cases finished in this run
        self.failures = 0        # rows diverged or errored, this run
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.min_dt = 1.0 / hz if self.tty else every_s
        self.width = width
        self.t0 = time.monotonic()
        self._last = -1e9

    def update(self, cases: int = 1, failures: int = 0, force: bool = False) -> None:
        self.done += cases
        self.failures += failures
        now = time.monotonic()
        if force or now - self._last >= self.min_dt:
            self._last = now
            self._draw(now)

    def line(self, now: float | None = None) -> str:
        now = time.monotonic() if now is None else now
        el = now - self.t0
        n = self.already + self.done
        frac = n / self.total if self.total else 1.0
        rate = self.done / el if el > 0 else 0.0
        left = (self.total - n) / rate if rate > 0 else float("inf")
        fill = int(round(frac * self.width))
        bar = "#" * fill + "." * (self.width - fill)
        return (f"[{bar}] {n}/{self.total} cases ({100 * frac:5.1f} %)  failures {self.failures}"
                f"  {rate:6.1f} cases/s  elapsed {_hms(el)}  ETA {_hms(left)}")

    def _draw(self, now: float) -> None:
        if self.tty:
            self.stream.write("\r" + self.line(now))
        else:
            self.stream.write(self.line(now) + "\n")
        self.stream.flush()

    def close(self) -> None:
        self._draw(time.monotonic())
        if self.tty:
            self.stream.write("\n")
        self.stream.flush()
