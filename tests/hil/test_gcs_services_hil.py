"""HIL tier: issue 21's protocol services with the real clients against the fc process.

- MAVProxy (headless, its default ``param_ftp`` on, the ``ftp`` and ``log`` modules and the
  project's tools.mavproxy_hyfc loaded): the parameters arrive by FTP (``@PARAM/param.pck``)
  without an FTP time-out and can be set, ``log list`` shows the run's .tlog and ``log
  download`` returns it byte for byte.
- MAVSDK: ``telemetry.in_air()`` is True at Mach 7 (EXTENDED_SYS_STATE), the velocity of
  ``position_velocity_ned`` is the true 2200 m/s (LOCAL_POSITION_NED), and a parameter read of
  an unknown name fails at once (PARAM_ERROR) instead of after MAVSDK's time-out.

The plant is scripted (tests/fc_harness.py ``ScriptedPlant``) with a GPS_INPUT in each frame.
"""
from __future__ import annotations

import importlib.util
import math
import os
import threading
import time

import pytest

from fc.params import build_table
from tests.fc_harness import FcProcess, ScriptedPlant, free_udp_port, level_meas
from tests.hil.test_mavproxy_fc import _Console, _mavproxy

pytestmark = pytest.mark.hil

V_NORTH_M_S = 2200.0     # Mach ~7 at 21 km


class _FlyingPlant:
    """A scripted plant sending a level Mach 7 frame with a GNSS sample every 20 ms of wall
    time (sim time advancing with it) from a thread, until ``close``."""

    def __init__(self, fc_port: int) -> None:
        self.plant = ScriptedPlant(fc_port)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _frame(self, t_s: float) -> bytes:
        m = level_meas(t_s, V=V_NORTH_M_S)
        mav = self.plant.mav
        lat = 34.9 + V_NORTH_M_S * t_s / 6_371_000.0 * 180.0 / math.pi
        gps = mav.gps_input_encode(int(t_s * 1e6), 0, 0, 0, 0, 3, int(round(lat * 1e7)),
                                   int(round(-117.9 * 1e7)), 21000.0, 1.0, 1.0,
                                   V_NORTH_M_S, 0.0, 0.0, 0.1, 1.5, 3.0, 12, 0)
        buf = self.plant.frame_bytes(m) + gps.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return buf

    def _run(self) -> None:
        t = 0.0
        while not self.stop.wait(0.02):
            t += 0.02
            self.plant.send_raw(self._frame(t))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.plant.close()


def test_mavproxy_gets_parameters_by_ftp_at_once_and_lists_and_downloads_the_log(tmp_path):
    exe = _mavproxy()
    port = free_udp_port()
    n_params = len(build_table())
    with FcProcess(str(tmp_path / "run"), gcs_ports=(port,)) as fc:
        plant = _FlyingPlant(fc.plant_port)        # a flight: the .tlog grows while served
        con = None
        try:
            t0 = time.monotonic()
            con = _Console(exe + [f"--master=udpin:127.0.0.1:{port}", "--no-state",
                                  "--default-modules=link,param,misc,ftp,log",
                                  "--load-module", "tools.mavproxy_hyfc"], str(tmp_path))
            con.expect("Detected vehicle 1:1", 30)
            t_detect = time.monotonic()
            line = con.expect(f"Received {n_params} parameters", 30)
            t_params = time.monotonic()
            print(f"MAVProxy: '{line.strip()}' {t_params - t_detect:.2f} s after 'Detected "
                  f"vehicle' ({t_params - t0:.2f} s after start)")
            assert "(ftp)" in line
            # an FTP time-out would cost seconds; the answer is at once
            assert t_params - t_detect < 5.0
            # the packed file's integers are whole numbers, and a set after it is verified
            con.send("param show CO_FAC_EQ")
            con.expect("CO_FAC_EQ        19")
            con.send("param set CO_FAC_EQ 14")
            for _ in range(10):                           # the set is queued in MAVProxy
                con.send("param fetch CO_FAC_EQ")
                if con.expect("CO_FAC_EQ = ").endswith("= 14"):
                    break
            else:
                raise AssertionError("CO_FAC_EQ never read back as 14")
            con.send("log list")
            entry = con.expect("Log 1  numLogs 1 lastLog 1 size", 15)
            size = int(entry.split("size")[1].split()[0])
            assert size > 0
            dl = tmp_path / "log1.tlog"
            con.send(f"log download 1 {dl}")
            done = con.expect("Finished downloading", 60)
            print("MAVProxy:", entry.strip(), "|", done.strip())
            con.send("ftp list /")
            con.expect("fc.tlog", 15)
        finally:
            if con is not None:
                con.close()
            plant.close()
        assert fc.stop() == 0
    with open(os.path.join(fc.out, "fc.tlog"), "rb") as f:
        whole = f.read()
    got = dl.read_bytes()
    assert len(got) == size and got == whole[:size]


@pytest.fixture()
def mavsdk_flying(tmp_path):
    if importlib.util.find_spec("mavsdk") is None:
        pytest.skip("mavsdk is not installed (pip install -e .[test])")
    import mavsdk
    if int(mavsdk.__version__.split(".")[0]) < 4:
        pytest.skip(f"mavsdk {mavsdk.__version__}: the test drives the native binding (>= 4)")
    from mavsdk import ComponentType, Configuration, Mavsdk
    port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), gcs_ports=(port,)) as fc:
        plant = _FlyingPlant(fc.plant_port)
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            assert sdk.add_any_connection(f"udpin://127.0.0.1:{port}").name == "SUCCESS"
            system = sdk.first_autopilot(10.0)
            assert system is not None, "MAVSDK found no autopilot"
            yield fc, system
        finally:
            sdk.destroy()
            plant.close()


def _wait(get, ok, timeout_s: float = 10.0):
    """Poll ``get()`` until ``ok(value)`` or the time-out; returns the last value."""
    deadline = time.monotonic() + timeout_s
    value = get()
    while not ok(value) and time.monotonic() < deadline:
        time.sleep(0.1)
        value = get()
    return value


def test_mavsdk_in_air_true_velocity_and_unknown_parameter_at_once(mavsdk_flying):
    from mavsdk.plugins.param import Param, ParamError, ParamResult
    from mavsdk.plugins.telemetry import Telemetry
    _, system = mavsdk_flying
    telemetry = Telemetry(system)
    assert _wait(telemetry.in_air, bool) is True
    pvn = _wait(telemetry.position_velocity_ned,
                lambda p: p is not None and p.velocity.north_m_s > 1000.0)
    print(f"MAVSDK in_air True; position_velocity_ned north {pvn.velocity.north_m_s:.1f} m/s")
    assert pvn.velocity.north_m_s == pytest.approx(V_NORTH_M_S)
    param = Param(system)
    t0 = time.monotonic()
    with pytest.raises(ParamError) as err:
        param.get_param_float("NO_SUCH_PARAM")
    dt = time.monotonic() - t0
    print(f"MAVSDK get_param_float(NO_SUCH_PARAM): {err.value.result} after {dt:.2f} s")
    assert err.value.result == ParamResult.DOES_NOT_EXIST and dt < 1.0


def test_mavsdk_downloads_an_msl_mission_with_mission_raw(mavsdk_flying):
    """MAVSDK's Mission plugin takes on download only NAV_WAYPOINT in frame 6
    (GLOBAL_RELATIVE_ALT_INT) and DO_CHANGE_SPEED with param1 = 1 (MAVSDK 4.1
    mission_impl.cpp ``convert_to_result_and_mission_items``), so the shipped MSL mission is
    UNSUPPORTED there; the fc returns items as stored, and MissionRaw downloads them all."""
    from mavsdk.plugins.mission import Mission, MissionError
    from mavsdk.plugins.mission_raw import MissionRaw
    from tests.fc_harness import REPO
    from tools.sitl.gcs import ScriptedGcs, read_wpl
    fc, system = mavsdk_flying
    items = read_wpl(os.path.join(REPO, "plant_sim", "scenarios", "mission_short.waypoints"))
    peer = ScriptedGcs(vehicle=("127.0.0.1", fc.gcs_bind_port))
    try:
        peer.upload_mission(items)
    finally:
        peer.close()
    got = MissionRaw(system).download_mission()
    assert [(g.seq, g.frame, g.command, g.x, g.y, g.z) for g in got] == [
        (k, it["frame"], it["command"], it["x"], it["y"], it["z"]) for k, it in enumerate(items)]
    with pytest.raises(MissionError) as err:
        Mission(system).download_mission()
    print(f"MAVSDK Mission.download_mission of the MSL mission: {err.value.result}; "
          f"MissionRaw: {len(got)} items")
