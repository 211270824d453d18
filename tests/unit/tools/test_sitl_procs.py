"""tools.sitl.procs: the one child-process helper of the harness (python -c children only)."""
from __future__ import annotations

import signal
import socket
import sys

from tools.sitl.procs import Child, free_udp_port

#: the child takes SIGINT as KeyboardInterrupt even when it inherited SIGINT ignored (a test run
#: started as a background job of a non-interactive shell, ``cmd &``: CPython then leaves it
#: ignored; the fc and the plant install their own handlers)
PRINT_THEN_WAIT = ("import signal, sys, time\n"
                   "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                   "print('hello', flush=True)\n"
                   "print('oops', file=sys.stderr, flush=True)\n"
                   "print('READY', flush=True)\n"
                   "time.sleep(60)\n")
IGNORE_SIGINT = ("import signal, time\n"
                 "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
                 "print('READY', flush=True)\n"
                 "time.sleep(60)\n")


def test_lines_are_queued_and_kept_and_stderr_is_separate(tmp_path):
    # GIVEN a child printing two stdout lines and one stderr line, then waiting
    c = Child("demo", [sys.executable, "-c", PRINT_THEN_WAIT], tmp_path / "demo.log")
    try:
        # WHEN we wait for READY both ways
        assert c.wait_for_line("READY", 30.0) == "READY"          # consumes the queue
        assert c.wait_line(lambda s: s == "hello", 1.0) == "hello"  # history keeps every line
        assert c.wait_line(lambda s: s == "never", 0.2) is None
    finally:
        rc = c.stop(int_wait_s=10.0)
    # THEN SIGINT ended it, stderr went to the tail and the console log has both streams
    assert rc == -signal.SIGINT or rc == 1          # KeyboardInterrupt traceback exits 1
    assert c.stderr_tail[0] == "oops" and "oops" not in c.history
    log = (tmp_path / "demo.log").read_text()
    assert "hello" in log and "[stderr] oops" in log and "# exit code" in log


def test_merged_stderr_and_escalation_to_sigkill():
    # GIVEN a child that ignores SIGINT, its stderr merged into stdout, no console file
    c = Child("stubborn", [sys.executable, "-c", IGNORE_SIGINT], None, merge_stderr=True)
    assert c.wait_line(lambda s: s == "READY", 30.0) == "READY"
    # WHEN it is stopped with a short SIGINT wait and no SIGTERM stage
    rc = c.stop(int_wait_s=0.5, term_wait_s=None)
    # THEN SIGKILL ended it
    assert rc == -signal.SIGKILL and c.wait_exit(0.0) == -signal.SIGKILL


def test_free_udp_port_can_be_bound():
    port = free_udp_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", port))
        assert s.getsockname()[1] == port
