"""Helpers for the fc HIL tests: the fc as a real process, a scripted plant, a closed loop.

The ground station is the harness's one scripted ground station, ``tools.sitl.gcs.ScriptedGcs``.

Everything on 127.0.0.1 with free ports; every wait is bounded; processes are stopped by the
fixtures that start them (``FcProcess`` is a context manager).
"""
from __future__ import annotations

import contextlib
import math
import os
import select
import signal
import socket
import subprocess
import sys
import time

import numpy as np

from fc.params import wire_number
from hyfc_wire.pwm import throttle_from_pwm
from tools.sitl.procs import Child, free_udp_port  # noqa: F401  (tests import it from here)

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# measurement layout (docs/architecture.md section 4), kept literal here on purpose: the
# test checks the fc against the contract, not against the fc's own constants.
M_T_S, M_ROLL, M_PITCH, M_YAW, M_P, M_Q, M_R, M_AOA, M_SSA = range(9)
M_AIRSPEED, M_ALT, M_CLIMB, M_GROUNDSPEED, M_HEADING = range(9, 14)


#: the failsafe time-out of the ``flying`` fixture (tests/conftest.py), s
FLYING_FS_TIMEOUT_S = 0.3


def param_number(m) -> float:
    """The number a PARAM_VALUE carries: INT32 values travel bytewise in the float field
    (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE), REAL32 as the float itself."""
    return wire_number(m.param_value, m.param_type)


def level_meas(t_s: float, alpha_deg: float = 1.0, beta_deg: float = 0.0, roll_deg: float = 0.0,
               V: float = 2200.0, h: float = 21000.0) -> np.ndarray:
    """A plausible measurement vector: wings-level-ish flight at pitch = alpha (gamma = 0)."""
    m = np.zeros(14)
    m[M_T_S] = t_s
    m[M_ROLL] = math.radians(roll_deg)
    m[M_PITCH] = math.radians(alpha_deg)
    m[M_AOA] = math.radians(alpha_deg)
    m[M_SSA] = math.radians(beta_deg)
    m[M_AIRSPEED] = V
    m[M_ALT] = h
    m[M_GROUNDSPEED] = V
    return m


class _Null:
    def write(self, _b):
        return None


class ScriptedPlant:
    """A plant stand-in: sends one-datagram sensor frames (docs/wire.md 2), reads the answers."""

    def __init__(self, fc_port: int, sysid: int = 2) -> None:
        self.fc_addr = ("127.0.0.1", fc_port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.mav = mavlink.MAVLink(_Null(), srcSystem=sysid, srcComponent=1)
        self.rx = mavlink.MAVLink(_Null())
        self.rx.robust_parsing = True

    def frame_bytes(self, m: np.ndarray) -> bytes:
        stamp_us = int(round(m[M_T_S] * 1e6))
        out = b""
        for msg in (
            self.mav.attitude_encode(int(stamp_us // 1000) & 0xFFFFFFFF, m[M_ROLL], m[M_PITCH],
                                     m[M_YAW], m[M_P], m[M_Q], m[M_R]),
            self.mav.aoa_ssa_encode(stamp_us, math.degrees(m[M_AOA]), math.degrees(m[M_SSA])),
            self.mav.vfr_hud_encode(m[M_AIRSPEED], m[M_GROUNDSPEED],
                                    int(round(math.degrees(m[M_HEADING]))) % 360, 0, m[M_ALT],
                                    m[M_CLIMB]),
        ):
            out += msg.pack(self.mav)
            self.mav.seq = (self.mav.seq + 1) % 256
        return out

    def send_raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.fc_addr)

    def send_frame(self, m: np.ndarray) -> None:
        self.send_raw(self.frame_bytes(m))

    def recv_servo(self, timeout_s: float):
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            r, _, _ = select.select([self.sock], [], [], left)
            if not r:
                return None
            data, _ = self.sock.recvfrom(4096)
            msgs = self.rx.parse_buffer(data) or []
            for msg in msgs:
                if msg.get_type() == "SERVO_OUTPUT_RAW":
                    return msg

    def exchange(self, m: np.ndarray, timeout_s: float = 5.0):
        """Send a frame and return the SERVO_OUTPUT_RAW echoing its stamp (lockstep)."""
        stamp = int(round(m[M_T_S] * 1e6)) & 0xFFFFFFFF
        self.send_frame(m)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            msg = self.recv_servo(deadline - time.monotonic())
            if msg is None:
                break
            if msg.time_usec == stamp:
                return msg
        raise TimeoutError(f"no SERVO_OUTPUT_RAW for stamp {stamp} within {timeout_s} s")

    def close(self) -> None:
        self.sock.close()


class FcProcess:
    """``python -m fc`` with free ports (a ``tools.sitl.procs.Child``); waits for READY; SIGINT
    on exit (kill if stuck)."""

    def __init__(self, out_dir: str, *extra: str, gcs_ports: tuple[int, ...] = (),
                 ready_timeout_s: float = 90.0) -> None:
        self.out = out_dir
        self.plant_port = free_udp_port()
        self.gcs_bind_port = free_udp_port()
        self.gcs_ports = gcs_ports or (free_udp_port(),)
        args = [sys.executable, "-m", "fc", "--out", out_dir,
                "--plant-bind", f"127.0.0.1:{self.plant_port}",
                "--gcs-bind", f"127.0.0.1:{self.gcs_bind_port}"]
        for p in self.gcs_ports:
            args += ["--gcs", f"127.0.0.1:{p}"]
        args += list(extra)
        self.args = args
        self.ready_timeout_s = ready_timeout_s
        self.proc: subprocess.Popen | None = None
        self.returncode: int | None = None

    def __enter__(self) -> "FcProcess":
        self.child = Child("fc", self.args, None, cwd=REPO)
        self.proc = self.child.proc
        if self.child.wait_line(lambda s: s.strip() == "READY", self.ready_timeout_s) is None:
            err = self._kill()
            raise RuntimeError(f"fc did not become READY: rc={self.proc.returncode} {err}")
        return self

    @property
    def stdout_lines(self) -> list[str]:
        return self.child.history

    def _kill(self) -> str:
        self.child.stop(int_wait_s=0.0, term_wait_s=None, first_signal=signal.SIGKILL)
        return "\n".join(self.child.stderr_tail)

    def stop(self, timeout_s: float = 20.0) -> int:
        """SIGINT, wait up to ``timeout_s``, then SIGKILL; the exit code (also ``returncode``,
        the last stderr lines in ``stderr``)."""
        if self.proc is None or self.returncode is not None:
            return self.returncode
        self.returncode = self.child.stop(int_wait_s=timeout_s, term_wait_s=None)
        self.stderr = "\n".join(self.child.stderr_tail)
        return self.returncode

    def __exit__(self, *exc) -> None:
        self.stop()


@contextlib.contextmanager
def fc_with_gcs(out_dir: str, *extra: str, **gcs_kw):
    """``python -m fc`` (``FcProcess``, ``extra`` its arguments) and a ``ScriptedGcs`` on its
    ground-station port that has heard the fc's HEARTBEAT; yields (fc, gcs), closes both."""
    from tools.sitl.gcs import ScriptedGcs
    port = free_udp_port()
    with FcProcess(out_dir, *extra, gcs_ports=(port,)) as fc:
        gcs = ScriptedGcs(port=port, **gcs_kw)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None, "no HEARTBEAT from the fc"
            yield fc, gcs
        finally:
            gcs.close()


def pwm_to_rad(us: int) -> float:
    """docs/wire.md section 3, plant side (defaults MIN 1000, TRIM 1500, MAX 2000, 20 deg)."""
    us = min(max(us, 1000), 2000)
    return math.radians(20.0) * (us - 1500) / 500.0


class ClosedLoop:
    """The in-process PlantSim flown by the fc over real UDP, lockstep, driven by the test.

    Each ``run`` frame: measure -> sensor frame to the fc -> wait for the SERVO_OUTPUT_RAW
    echoing the stamp -> apply it -> advance. ``on_frame`` (optional) is called after every
    frame, so a test can look at the ground-station link meanwhile.
    """

    def __init__(self, plant_port: int, scenario: str = "paper", seed: int = 1) -> None:
        from plant_sim.scenario import load
        from plant_sim.sim import TRUTH_N, TRUTH_NAMES, PlantSim
        self.sim = PlantSim(load(scenario), seed=seed)
        # load the plant's kernels now, on a spare instance, so the first exchanges are not
        # delayed by JIT/cache loading (the fc's wall-clock failsafe would see a data gap)
        spare = PlantSim(load(scenario), seed=seed)
        spare.measure(np.zeros(14))
        spare.command(np.zeros(3))
        spare.truth_row(np.zeros(TRUTH_N))
        spare.advance()
        self.col = {n: i for i, n in enumerate(TRUTH_NAMES)}
        self.row = np.zeros(TRUTH_N)
        self.meas = np.zeros(14)
        self.cmd = np.zeros(3)
        self.plant = ScriptedPlant(plant_port)
        self.outputs: list[tuple[int, int, int]] = []
        self.servo4 = 0

    def truth(self, name: str) -> float:
        return float(self.row[self.col[name]])

    def run(self, n_frames: int, on_frame=None) -> None:
        for _ in range(n_frames):
            self.sim.measure(self.meas)
            ans = self.plant.exchange(self.meas)
            pwm = (ans.servo1_raw, ans.servo2_raw, ans.servo3_raw)
            self.outputs.append(pwm)
            for i in range(3):
                self.cmd[i] = pwm_to_rad(pwm[i])
            self.sim.command(self.cmd)
            self.servo4 = ans.servo4_raw
            if ans.servo4_raw:          # the throttle channel (0: none, the plant keeps its own)
                self.sim.throttle(throttle_from_pwm(ans.servo4_raw))
            self.sim.truth_row(self.row)
            self.sim.advance()
            if on_frame is not None and on_frame():
                return

    def close(self) -> None:
        self.plant.close()


def received(msg, sysid: int = 255, compid: int = 190):
    """``msg`` packed by a ground station (``sysid``/``compid``) and decoded by the fc's codec,
    as the fc receives it (header, source ids, payload bytes): the input of the GCS link's
    protocol services in their unit tests."""
    from fc.link import decode_datagram, new_codec
    tx = mavlink.MAVLink(_Null(), srcSystem=sysid, srcComponent=compid)
    msgs, bad = decode_datagram(new_codec(1, 1), msg.pack(tx))
    assert bad == 0 and len(msgs) == 1
    return msgs[0]
