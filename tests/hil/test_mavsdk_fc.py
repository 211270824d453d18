"""HIL tier: MAVSDK (the native ``mavsdk`` >= 4 binding, no mavsdk_server) against the fc.

MAVSDK decodes a non-ArduPilot HEARTBEAT's custom_mode as PX4's main/sub mode and a
non-ArduPilot vehicle's integer parameters bytewise: the fc's conventions (docs/fc.md 5, 8).
"""
from __future__ import annotations

import importlib.util
import time

import pytest

from tests.fc_harness import FcProcess, free_udp_port, mavlink as ML
from tools.sitl.gcs import ScriptedGcs

pytestmark = pytest.mark.hil


@pytest.fixture()
def mavsdk_fc(tmp_path):
    if importlib.util.find_spec("mavsdk") is None:
        pytest.skip("mavsdk is not installed (pip install -e .[test])")
    import mavsdk
    if int(mavsdk.__version__.split(".")[0]) < 4:
        pytest.skip(f"mavsdk {mavsdk.__version__}: the test drives the native binding (>= 4)")
    from mavsdk import ComponentType, Configuration, Mavsdk
    port = free_udp_port()
    with FcProcess(str(tmp_path / "run"), gcs_ports=(port,)) as fc:
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            assert sdk.add_any_connection(f"udpin://127.0.0.1:{port}").name == "SUCCESS"
            system = sdk.first_autopilot(10.0)
            assert system is not None, "MAVSDK found no autopilot"
            yield fc, system
        finally:
            sdk.destroy()


def _wait_mode(telemetry, want, timeout_s: float = 5.0):
    deadline = time.monotonic() + timeout_s
    mode = telemetry.flight_mode()
    while mode != want and time.monotonic() < deadline:
        time.sleep(0.05)
        mode = telemetry.flight_mode()
    return mode


def test_mavsdk_reads_the_flight_mode(mavsdk_fc):
    from mavsdk.plugins.telemetry import FlightMode, Telemetry
    fc, system = mavsdk_fc
    telemetry = Telemetry(system)
    assert _wait_mode(telemetry, FlightMode.MANUAL) == FlightMode.MANUAL
    # change the mode from a second ground station (the scripted one, a peer of the fc's bind
    # port) and watch MAVSDK follow
    peer = ScriptedGcs(vehicle=("127.0.0.1", fc.gcs_bind_port))
    try:
        for number, want in ((1, FlightMode.STABILIZED), (2, FlightMode.STABILIZED),
                             (3, FlightMode.MANUAL)):
            ack = peer.command(ML.MAV_CMD_DO_SET_MODE, 1, number)
            assert ack is not None and ack.result == ML.MAV_RESULT_ACCEPTED
            assert _wait_mode(telemetry, want) == want, number
    finally:
        peer.close()


def test_mavsdk_gets_and_sets_integer_parameters_and_out_of_range_fails_fast(mavsdk_fc):
    from mavsdk.plugins.param import Param, ParamError, ParamResult
    _, system = mavsdk_fc
    param = Param(system)
    assert param.get_param_int("CO_FAC_EQ") == 19
    assert param.get_param_int("FS_RECOVER") == 1
    param.set_param_int("CO_FAC_EQ", 14)
    assert param.get_param_int("CO_FAC_EQ") == 14
    assert param.get_param_float("FS_TIMEOUT_S") == pytest.approx(0.5)
    t0 = time.monotonic()
    with pytest.raises(ParamError) as err:
        param.set_param_int("CO_FAC_EQ", 99)                        # outside [14, 19]
    dt = time.monotonic() - t0
    print(f"out-of-range set_param_int answered in {dt:.2f} s: {err.value}")
    assert err.value.result == ParamResult.VALUE_OUT_OF_RANGE and dt < 2.0
    assert param.get_param_int("CO_FAC_EQ") == 14
    with pytest.raises(ParamError) as err:
        param.set_param_float("FS_TIMEOUT_S", 1000.0)
    assert err.value.result == ParamResult.VALUE_OUT_OF_RANGE
