"""HIL tier: stock MAVProxy, headless, against the fc (shared docs mavlink.md section 5).

MAVProxy finds the vehicle, downloads every parameter, sets one, sends the documented
attitude COMMAND_LONG (``long USER_1 ...``), saves the parameters to a file and loads a file.
Its exit code is always 1, so the output is checked instead.
"""
from __future__ import annotations

import importlib.util
import os
import queue
import signal
import subprocess
import sys
import threading
import time

import pytest

from fc.params import ParamTable, build_table
from tests.fc_harness import REPO, FcProcess, free_udp_port

pytestmark = pytest.mark.hil


def _mavproxy() -> list[str]:
    """MAVProxy of this interpreter (``python -m MAVProxy.mavproxy``: works in a venv whose
    bin/ is not on PATH, as in .ci/run)."""
    if importlib.util.find_spec("MAVProxy") is None:
        pytest.skip("MAVProxy is not installed (pip install -e .[test])")
    return [sys.executable, "-m", "MAVProxy.mavproxy"]


class _Console:
    """MAVProxy driven through its console (stdin), each command sent when the previous one
    has shown its effect in the output (no fixed delays)."""

    def __init__(self, argv: list[str], cwd: str) -> None:
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, cwd=cwd,
                                     env=dict(os.environ, PYTHONPATH=REPO))
        self.lines: queue.Queue = queue.Queue()
        self.out: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def send(self, command: str) -> None:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def expect(self, text: str, timeout_s: float = 15.0) -> str:
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"MAVProxy never printed {text!r}:\n" + "\n".join(self.out))
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                continue
            self.out.append(line)
            if text in line:
                return line

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)


def test_mavproxy_shows_and_sets_every_mode_by_name_with_the_hyfc_module(tmp_path):
    """tools/mavproxy_hyfc.py loaded: ``mode`` lists our names, each is set by name and shown
    (the "Mode X" announcement comes from the HEARTBEAT); integer parameters show and set as
    whole numbers."""
    exe = _mavproxy()
    gcs_port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), gcs_ports=(gcs_port,)) as fc:
        # loaded as the README says: before the default modules see the first HEARTBEAT
        con = _Console(exe + [f"--master=udpin:127.0.0.1:{gcs_port}", "--no-state",
                              "--default-modules=link,param,misc,mode",
                              "--load-module", "tools.mavproxy_hyfc", "--cmd=set param_ftp 0"],
                       str(tmp_path))
        try:
            con.expect("Loaded module tools.mavproxy_hyfc")
            con.expect("Mode MANUAL")
            con.expect(f"Received {len(build_table())} parameters")
            con.send("param show CO_FAC_EQ")                # INT32 from the download, bytewise
            con.expect("CO_FAC_EQ        19")
            con.send("mode")
            con.expect("Available modes:")
            for name in ("COORDINATED", "UNCOORDINATED", "FAILSAFE", "CRUISE", "GUIDED", "MANUAL"):
                con.send(f"mode {name}")
                con.expect(f"AP: mode {name}")            # the fc's STATUSTEXT: it was set
                con.expect(f"Mode {name}")                # MAVProxy names the HEARTBEAT's mode
            con.send("mode MISSION")                      # sent as the number 6: refused, why
            con.expect("AP: MISSION refused: no mission stored")
            con.send("param set CO_FAC_EQ 19")
            for _ in range(10):                           # the set is queued in MAVProxy
                con.send("param fetch CO_FAC_EQ")
                if con.expect("CO_FAC_EQ = ").endswith("= 19"):
                    break
            else:
                raise AssertionError("CO_FAC_EQ never read back as 19")
            con.send("param show FS_RECOVER")
            con.expect("FS_RECOVER")
        finally:
            con.close()
        assert fc.stop() == 0
    out = "\n".join(con.out)
    print(out)
    assert ("Available modes:  MANUAL, COORDINATED, UNCOORDINATED, FAILSAFE, CRUISE, GUIDED, "
            "MISSION, RTL") in out
    assert "Unknown mode" not in out and "CIRCLE" not in out and "STABILIZE" not in out
    assert "FS_RECOVER       1" in out
    with open(os.path.join(fc.out, "fc.log")) as f:
        assert "param CO_FAC_EQ = 19" in f.read()


def test_mavproxy_headless_finds_vehicle_downloads_and_sets(tmp_path):
    exe = _mavproxy()
    n_params = len(build_table())
    saved = tmp_path / "saved.parm"
    to_load = tmp_path / "load.parm"
    to_load.write_text("TRIM_RUD_DEG 1.5\n")
    gcs_port = free_udp_port()
    steps = "; ".join([
        "set param_ftp 0", "set requireexit 1", "module load tools.mavproxy_hyfc",
        "repeat add 2 param set FS_TIMEOUT_S 2.5",
        "repeat add 3 param fetch FS_TIMEOUT_S",
        "repeat add 3 long USER_1 5 0 4",
        f"repeat add 3 param save {saved}",
        f"repeat add 3 param load {to_load}",
        "repeat add 5 exit",
    ])
    with FcProcess(str(tmp_path / "run"), gcs_ports=(gcs_port,)) as fc:
        res = subprocess.run(
            exe + [f"--master=udpin:127.0.0.1:{gcs_port}", "--non-interactive", "--no-state",
                   "--default-modules=link,param,misc,cmdlong", f"--cmd={steps}"],
            stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
            cwd=str(tmp_path), env=dict(os.environ, PYTHONPATH=REPO))
        out = res.stdout
        # MAVProxy ran its last step 2 s before exiting: everything reached the fc by now
        assert fc.stop() == 0
    log_path = os.path.join(fc.out, "fc.log")
    assert "Detected vehicle 1:1" in out, out
    assert f"Received {n_params} parameters" in out, out
    assert "FS_TIMEOUT_S = 2.5" in out, out
    assert "USER_1: ACCEPTED" in out, out
    with open(log_path) as f:
        log = f.read()
    assert "param TRIM_RUD_DEG = 1.5" in log, "MAVProxy param load did not reach the fc"
    assert "param CMD_ALPHA_DEG = 5" in log and "param CMD_MU_DEG = 4" in log
    # MAVProxy's saved file is a complete parameter file our table reads back
    values = ParamTable.read_file(str(saved))
    assert set(values) == set(build_table().names)
    assert values["FS_TIMEOUT_S"] == pytest.approx(2.5)
    assert values["FS_RECOVER"] == 1.0 and values["CO_FAC_EQ"] == 19.0   # INT32, whole numbers
    # and the fc persisted the set it received
    persisted = ParamTable.read_file(os.path.join(fc.out, "params.parm"))
    assert persisted["FS_TIMEOUT_S"] == pytest.approx(2.5)
    assert persisted["TRIM_RUD_DEG"] == pytest.approx(1.5)


def test_mavproxy_with_the_signing_key_can_set_without_it_cannot(tmp_path):
    exe = _mavproxy()
    key_file = tmp_path / "gcs.key"
    key_file.write_text("s3cret-passphrase\n")
    os.chmod(key_file, 0o600)

    def mavproxy(port: int, key: str | None, value: float) -> str:
        steps = ["set param_ftp 0", "set requireexit 1"]
        if key is not None:
            steps += ["module load signing", f"signing key {key}"]
        steps += [f"repeat add 2 param set TRIM_RUD_DEG {value}", "repeat add 4 exit"]
        res = subprocess.run(
            exe + [f"--master=udpin:127.0.0.1:{port}", "--non-interactive", "--no-state",
                   "--default-modules=link,param,misc", f"--cmd={'; '.join(steps)}"],
            stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60,
            cwd=str(tmp_path))
        return res.stdout

    gcs_port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), "--signing-key-file", str(key_file),
                   gcs_ports=(gcs_port,)) as fc:
        unsigned_out = mavproxy(gcs_port, None, 1.25)
        signed_out = mavproxy(gcs_port, "s3cret-passphrase", 2.5)
        assert fc.stop() == 0
    assert "Detected vehicle 1:1" in unsigned_out and "Detected vehicle 1:1" in signed_out
    with open(os.path.join(fc.out, "fc.log")) as f:
        log = f.read()
    assert "param TRIM_RUD_DEG = 1.25" not in log, "an unsigned set must be rejected"
    assert "param TRIM_RUD_DEG = 2.5" in log, signed_out
    assert "s3cret-passphrase" not in log
