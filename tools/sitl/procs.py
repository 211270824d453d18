"""Child processes of the SITL harness: start in their own process group, read their output,
wait on it with bounded waits, stop them cleanly (SIGINT, then SIGTERM, then SIGKILL, each with
a bounded wait). Used by the main job (tools.hil), the reliability rig (tools.sitl.rig), the
benchmarks (tools.bench), the link-impairment relay and the tests' fc process.

No orphans: every child is started with ``start_new_session=True`` (its own process group),
so signals go to the whole group (the child and anything it starts), and the terminal's
Ctrl-C reaches only the parent, which forwards the stop.
"""
from __future__ import annotations

import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

#: the repository root (children run our packages from here)
ROOT = Path(__file__).resolve().parents[2]
#: waits (s) after SIGINT and after SIGTERM before escalating
STOP_INT_WAIT_S = 15.0
STOP_TERM_WAIT_S = 5.0


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port that is free on ``host`` right now (bind port 0, read it, release it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def repo_env(**extra: str) -> dict:
    """The environment for a child running our packages: ours, with the repository root first
    on PYTHONPATH (so a child imports this tree, not an installed copy), plus ``extra``."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.update(extra)
    return env


class Child:
    """One child process with its output copied to a console log and each stdout line
    delivered twice: through a queue (``lines``, consumed by a reader such as tools.hil) and
    kept in ``history`` (guarded by ``cv``, for waits on any line seen so far).

    Parameters
    ----------
    name : short name used in messages ("plant", "fc").
    argv : the command line.
    console_path : file receiving everything the child prints (stdout and stderr); None: none.
    env : environment (default: inherited).
    cwd : working directory (default: inherited).
    merge_stderr : stderr joins stdout (one stream, in ``lines``/``history``); else stderr
        lines go to the console with a ``[stderr]`` prefix and the last 20 to ``stderr_tail``.
    console_mode : "w" (truncate) or "a" (append to an existing console log).
    """

    def __init__(self, name: str, argv: list[str], console_path: Path | None,
                 env: dict | None = None, cwd: str | None = None, merge_stderr: bool = False,
                 console_mode: str = "w"):
        self.name = name
        self.argv = argv
        self.console_path = None if console_path is None else Path(console_path)
        self.lines: queue.Queue[str] = queue.Queue()
        self.history: list[str] = []
        self.cv = threading.Condition()
        self.stderr_tail: list[str] = []
        self._console = (open(os.devnull, "w") if console_path is None
                         else open(self.console_path, console_mode, buffering=1))
        self._console.write("$ " + " ".join(argv) + "\n")
        self._lock = threading.Lock()
        self.proc = subprocess.Popen(
            argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT if merge_stderr else subprocess.PIPE,
            text=True, bufsize=1, start_new_session=True, env=env, cwd=cwd)
        self.pgid = self.proc.pid  # new session: pgid == pid
        self._threads = [threading.Thread(target=self._pump, args=(self.proc.stdout, True),
                                          daemon=True)]
        if not merge_stderr:
            self._threads.append(threading.Thread(target=self._pump,
                                                  args=(self.proc.stderr, False), daemon=True))
        for t in self._threads:
            t.start()

    def _pump(self, stream, is_stdout: bool) -> None:
        for line in stream:
            with self._lock:
                self._console.write(line if is_stdout else "[stderr] " + line)
                if not is_stdout:
                    self.stderr_tail.append(line.rstrip("\n"))
                    del self.stderr_tail[:-20]
            if is_stdout:
                self.lines.put(line.rstrip("\n"))
                with self.cv:
                    self.history.append(line.rstrip("\n"))
                    self.cv.notify_all()
        stream.close()
        with self.cv:
            self.cv.notify_all()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def poll(self) -> int | None:
        return self.proc.poll()

    def wait_for_line(self, prefix: str, timeout_s: float, on_other=None,
                      stop: threading.Event | None = None) -> str:
        """Wait until the child prints a stdout line starting with ``prefix``.

        Raises RuntimeError if the child exits first or the timeout passes, InterruptedError
        when ``stop`` is set (Ctrl-C) meanwhile.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            if stop is not None and stop.is_set():
                raise InterruptedError(f"interrupted while waiting for {self.name}")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise RuntimeError(f"{self.name} did not print {prefix!r} within {timeout_s:.0f} s "
                                   f"(see {self.console_path})")
            try:
                line = self.lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                if self.poll() is not None:
                    # drain what is left before giving up
                    try:
                        line = self.lines.get(timeout=0.5)
                    except queue.Empty:
                        raise RuntimeError(self.death_message()) from None
                else:
                    continue
            if line.startswith(prefix):
                return line
            if on_other is not None:
                on_other(line)

    def wait_line(self, pred, timeout_s: float) -> str | None:
        """First stdout line satisfying ``pred`` (already seen or new); None when the timeout
        passes or the child has exited with nothing matching."""
        deadline = time.monotonic() + timeout_s
        i = 0
        with self.cv:
            while True:
                while i < len(self.history):
                    if pred(self.history[i]):
                        return self.history[i]
                    i += 1
                left = deadline - time.monotonic()
                if left <= 0 or (self.proc.poll() is not None and not self._threads[0].is_alive()):
                    return None
                self.cv.wait(min(left, 0.2))

    def wait_exit(self, timeout_s: float) -> int | None:
        """The exit code once the child has exited, None if it still runs after ``timeout_s``."""
        try:
            return self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def kill9(self) -> int:
        """SIGKILL the process itself (not its group: a crash), wait for it; its exit code."""
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=10)
        return self.proc.returncode

    def death_message(self) -> str:
        rc = self.poll()
        how = (f"was killed by signal {-rc}" if rc is not None and rc < 0
               else f"exited with code {rc}")
        with self._lock:
            tail = next((ln for ln in reversed(self.stderr_tail) if ln.strip()), "")
        reason = f": {tail}" if tail else ""
        return f"{self.name} (pid {self.pid}) {how}{reason} (full output: {self.console_path})"

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.pgid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def _group_alive(self) -> bool:
        try:
            os.killpg(self.pgid, 0)
            return True
        except (ProcessLookupError, PermissionError):
            return False

    def stop(self, int_wait_s: float = STOP_INT_WAIT_S,
             term_wait_s: float | None = STOP_TERM_WAIT_S,
             first_signal: int = signal.SIGINT) -> int | None:
        """Stop the child's process group: ``first_signal`` (SIGINT), then SIGTERM (left out
        when ``term_wait_s`` is None), then SIGKILL. Returns the child's exit code (negative:
        killed by that signal)."""
        steps = [(first_signal, int_wait_s)]
        if term_wait_s is not None:
            steps.append((signal.SIGTERM, term_wait_s))
        for sig, wait_s in (*steps, (signal.SIGKILL, 5.0)):
            if self.poll() is None:
                self._signal_group(sig)
                try:
                    self.proc.wait(timeout=wait_s)
                except subprocess.TimeoutExpired:
                    print(f"tools.hil: {self.name} did not stop within {wait_s:.0f} s after "
                          f"{signal.Signals(sig).name}", file=sys.stderr)
                    continue
            # the child is gone; make sure nothing it started is left in its group
            if self._group_alive():
                self._signal_group(signal.SIGKILL)
            break
        self.close()
        return self.poll()

    def close(self) -> None:
        for t in self._threads:
            t.join(timeout=2.0)
        with self._lock:
            if not self._console.closed:
                rc = self.poll()
                self._console.write(f"# exit code {rc}\n")
                self._console.close()


def run_serving(name: str, argv: list[str], serve, timeout_s: float,
                cwd: str | None = None) -> Child:
    """Run a child to its end while calling ``serve()`` (one bounded step of the peer it talks
    to, e.g. ``ServoResponder.serve_one``) in a loop; SIGKILL it if it is still running after
    ``timeout_s``. Returns the stopped ``Child`` (exit code ``poll()``, ``history``,
    ``stderr_tail``)."""
    child = Child(name, argv, None, cwd=cwd)
    try:
        deadline = time.monotonic() + timeout_s
        while child.poll() is None and time.monotonic() < deadline:
            serve()
        child.wait_exit(30.0)
    finally:
        child.stop(int_wait_s=0.0, term_wait_s=None, first_signal=signal.SIGKILL)
    return child
