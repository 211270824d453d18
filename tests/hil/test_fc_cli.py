"""The ``python -m fc`` command line: help, bad input, corrupt parameter file, outputs, signals."""
from __future__ import annotations

import glob
import os
import signal
import socket
import subprocess
import sys

import pytest

from tests.fc_harness import REPO, FcProcess, free_udp_port
from tools.sitl.gcs import ScriptedGcs

pytestmark = pytest.mark.hil


def _run(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "fc", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout)


def test_help_lists_the_contract_options():
    res = _run("--help")
    assert res.returncode == 0
    for opt in ("--mode", "--plant-bind", "--plant-sysid", "--gcs", "--gcs-bind", "--fast-hz",
                "--slow-hz", "--params", "--timeline", "--out", "--arm", "--flight-mode",
                "--sysid", "--signing-key-file"):
        assert opt in res.stdout, opt


@pytest.mark.parametrize("args,needle", [
    (("--fast-hz", "500", "--slow-hz", "300"), "integer multiple"),
    (("--gcs", "nohostport"), "HOST:PORT"),
    (("--timeline", "/nonexistent/timeline.toml"), "timeline.toml"),
])
def test_bad_input_gives_a_clear_error(tmp_path, args, needle):
    res = _run("--out", str(tmp_path), "--plant-bind", "127.0.0.1:0", "--gcs-bind",
               "127.0.0.1:0", *args)
    assert res.returncode != 0 and "READY" not in res.stdout
    assert needle in res.stderr


def test_port_in_use_is_reported(tmp_path):
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        res = _run("--out", str(tmp_path), "--plant-bind", f"127.0.0.1:{busy.getsockname()[1]}",
                   "--gcs-bind", "127.0.0.1:0")
    finally:
        busy.close()
    assert res.returncode == 2 and "cannot bind" in res.stderr


def test_corrupt_parameter_file_is_kept_aside_and_reported(tmp_path):
    params = tmp_path / "mine.parm"
    params.write_text("SLW_K1 2\nthis line is not a parameter\n")
    gcs_port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), "--params", str(params), gcs_ports=(gcs_port,)) as fc:
        gcs = ScriptedGcs(port=gcs_port)
        try:
            text = gcs.wait("STATUSTEXT", 10, cond=lambda m: "corrupt" in m.text)
            assert text is not None and text.severity == 2     # MAV_SEVERITY_CRITICAL
        finally:
            gcs.close()
        assert fc.stop() == 0
    aside = glob.glob(str(params) + ".corrupt-*")
    assert len(aside) == 1
    assert open(aside[0]).read() == "SLW_K1 2\nthis line is not a parameter\n"
    assert params.exists()          # a fresh file with the defaults, the bad one kept
    with open(os.path.join(fc.out, "fc.log")) as f:
        assert "ERROR parameter file unreadable" in f.read()


def test_several_gcs_outputs_and_sigterm(tmp_path):
    ports = (free_udp_port(), free_udp_port())
    with FcProcess(str(tmp_path), gcs_ports=ports) as fc:
        clients = [ScriptedGcs(port=p) for p in ports]
        try:
            for c in clients:
                assert c.wait("HEARTBEAT", 10) is not None
        finally:
            for c in clients:
                c.close()
        fc.proc.send_signal(signal.SIGTERM)
        assert fc.proc.wait(timeout=20) == 0
    assert os.path.exists(os.path.join(tmp_path, "fc_internals.npz"))
    assert os.path.getsize(os.path.join(tmp_path, "fc.tlog")) > 0
