"""Tier 2 (HIL): the flight log a PX4/ArduPilot user reads (docs/fc.md "Flight log").

- a lockstep main-job run's ``fc.tlog`` read with pymavlink's own tools (``mavlogdump``,
  ``mavsummarize``, run as the user runs them): flight time = sim time, streams at their
  rates of sim time, one time base for every message (= the record stamps), sequence numbers
  without gaps, and a position that moves with the plant's truth;
- the fc against a stand-in plant: without GNSS it keeps flying, flags GPS unhealthy and
  sends no position; with GPS_INPUT in the frames it publishes the fix, GLOBAL_POSITION_INT
  and HOME_POSITION (on request too); live messages carry sim time in lockstep.
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from tests.fc_harness import FcProcess, ScriptedPlant, level_meas, mavlink
from tools.sitl.gcs import ScriptedGcs
from tools.sitl.procs import repo_env as _env

ROOT = Path(__file__).resolve().parents[2]
FLIGHT_S = 20.0
ATT_HZ = 10.0          # fc/gcs.py STREAM_DEFAULTS_S: ATTITUDE every 0.1 s
# messages with a time field and its scale to seconds
TIME_FIELDS = {"ATTITUDE": ("time_boot_ms", 1e-3), "AOA_SSA": ("time_usec", 1e-6),
               "DEBUG_VECT": ("time_usec", 1e-6), "NAMED_VALUE_FLOAT": ("time_boot_ms", 1e-3),
               "SYSTEM_TIME": ("time_boot_ms", 1e-3), "GPS_RAW_INT": ("time_usec", 1e-6),
               "GLOBAL_POSITION_INT": ("time_boot_ms", 1e-3),
               "LOCAL_POSITION_NED": ("time_boot_ms", 1e-3),
               "HOME_POSITION": ("time_usec", 1e-6), "SERVO_OUTPUT_RAW": ("time_usec", 1e-6)}


def _tool(name: str, *args: str) -> str:
    """Run ``python -m pymavlink.tools.NAME ARGS`` (as a user would) and return its stdout."""
    r = subprocess.run([sys.executable, "-m", f"pymavlink.tools.{name}", *args], cwd=ROOT,
                       env=_env(), capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, f"{name}: {r.stderr}"
    return r.stdout


@pytest.fixture(scope="module")
def lockstep_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("flightlog") / "run"
    r = subprocess.run([sys.executable, "-m", "tools.hil", "run", "--scenario", "paper",
                        "--variant", "coordinated", "--duration", str(FLIGHT_S), "--seed", "0",
                        "--out", str(out), "--no-plots", "--quiet"], cwd=ROOT, env=_env(),
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{r.stdout}\n{r.stderr}"
    return out / "coordinated"


def _dump(tlog: Path) -> list[dict]:
    """Every message of the .tlog as mavlogdump prints it (JSON lines)."""
    text = _tool("mavlogdump", "--format", "json", "--dialect", "ardupilotmega", str(tlog))
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


@pytest.mark.hil
def test_mavsummarize_reports_the_flight_time_and_a_position(lockstep_run):
    text = _tool("mavsummarize", str(lockstep_run / "fc.tlog"))
    m = re.search(r"Total time \(mm:ss\):\s+(\d+):(\d+)", text)
    assert m, text
    assert int(m.group(1)) * 60 + int(m.group(2)) == pytest.approx(FLIGHT_S, abs=1.0), text
    moved = re.search(r"Travelled from \(([-\d.]+), ([-\d.]+)\) to \(([-\d.]+), ([-\d.]+)\)", text)
    assert moved, f"no position in the log:\n{text}"
    dist = float(re.search(r"Total distance : ([\d.]+)m", text).group(1))
    truth = np.load(lockstep_run / "truth.npz")
    path_m = float(np.sum(np.hypot(np.diff(truth["pos_n_m"]), np.diff(truth["pos_e_m"]))))
    # the first fix is at t = 0 (fix_type 0 before it): the GNSS path covers the flight
    assert dist == pytest.approx(path_m, rel=0.02)


@pytest.mark.hil
def test_tlog_streams_time_base_and_sequence(lockstep_run):
    msgs = _dump(lockstep_run / "fc.tlog")
    fc_msgs = [m for m in msgs if m["meta"]["type"] in TIME_FIELDS]
    assert fc_msgs
    stamps = np.array([m["meta"]["timestamp"] for m in msgs])
    assert np.all(np.diff(stamps) >= 0.0), ".tlog record stamps must not go backwards"
    t0 = stamps[0]                        # epoch: the first record is at sim time 0
    # the record stamps span the flight (sim time), not the run's wall time
    assert stamps[-1] - t0 == pytest.approx(FLIGHT_S, rel=0.01)
    # streams at their rates of sim time
    n_att = sum(1 for m in msgs if m["meta"]["type"] == "ATTITUDE")
    assert n_att == pytest.approx(FLIGHT_S * ATT_HZ, abs=2)
    # ... written at the frame whose stamp makes them due (every 0.1 s of sim time exactly),
    # also when the fc read several plant frames at one wake-up
    att_ms = [m["data"]["time_boot_ms"] for m in msgs if m["meta"]["type"] == "ATTITUDE"]
    assert [t for t in att_ms if t % 100] == []
    n_gpi = sum(1 for m in msgs if m["meta"]["type"] == "GLOBAL_POSITION_INT")
    assert n_gpi == pytest.approx(FLIGHT_S * 10, abs=2)
    # one time base: every time field = record stamp - epoch, and monotone per message type
    last = defaultdict(float)
    for m in fc_msgs:
        typ = m["meta"]["type"]
        field, scale = TIME_FIELDS[typ]
        t = m["data"][field] * scale
        assert t == pytest.approx(m["meta"]["timestamp"] - t0, abs=2e-3), typ
        assert t >= last[typ], typ
        last[typ] = t
    # the controller's vectors are the newest tick's at each record, not a wall-clock cache
    est = [m["data"]["x"] for m in msgs
           if m["meta"]["type"] == "DEBUG_VECT" and m["data"]["name"] == "EST_DEG"]
    assert len(est) == pytest.approx(FLIGHT_S * 10, abs=2) and len(set(est)) > 0.9 * len(est)
    assert set(last) >= {"ATTITUDE", "AOA_SSA", "DEBUG_VECT", "NAMED_VALUE_FLOAT",
                         "SYSTEM_TIME", "GPS_RAW_INT", "GLOBAL_POSITION_INT", "HOME_POSITION"}
    # sequence numbers: per source, each message the next number (mod 256)
    text = _tool("mavlogdump", "--show-seq", "--show-source", "--dialect", "ardupilotmega",
                 str(lockstep_run / "fc.tlog"))
    seqs = defaultdict(list)
    for src, seq in re.findall(r"srcSystem=(\d+) srcComponent=\d+ seq=(\d+)", text):
        seqs[int(src)].append(int(seq))
    assert len(seqs[1]) == len(msgs) - sum(len(v) for k, v in seqs.items() if k != 1)
    for src, s in seqs.items():
        steps = {(b - a) % 256 for a, b in zip(s, s[1:])}
        assert steps <= {1}, f"sysid {src}: sequence steps {sorted(steps)}"
    assert 250 in seqs, "the scripted ground station's messages are logged"


@pytest.mark.hil
def test_position_follows_the_plant_truth(lockstep_run):
    from plant_sim.gnss import geodetic_to_ned
    from plant_sim.scenario import load
    g = load("paper").data["gnss"]
    origin = (g["origin_lat_deg"], g["origin_lon_deg"], g["origin_alt_m"])
    msgs = _dump(lockstep_run / "fc.tlog")
    pos = [(m["data"]["time_boot_ms"] * 1e-3, m["data"]["lat"] * 1e-7, m["data"]["lon"] * 1e-7,
            m["data"]["alt"] * 1e-3) for m in msgs if m["meta"]["type"] == "GLOBAL_POSITION_INT"]
    assert len(pos) > 100
    truth = np.load(lockstep_run / "truth.npz")
    t_true = truth["t_s"]
    ned = np.array([geodetic_to_ned(la, lo, al, *origin) for _, la, lo, al in pos])
    t = np.array([p[0] for p in pos])
    # every fix is the truth at its sample time: the frame it arrived with or up to one
    # receiver period (0.1 s) before the record (paper scenario: no GNSS latency)
    for k in range(len(t)):
        lo_n = np.interp(t[k] - 0.1 - 0.002, t_true, truth["pos_n_m"])
        hi_n = np.interp(t[k], t_true, truth["pos_n_m"])
        assert min(lo_n, hi_n) - 10.0 <= ned[k, 0] <= max(lo_n, hi_n) + 10.0
        e_true = np.interp(t[k], t_true, truth["pos_e_m"])
        assert abs(ned[k, 1] - e_true) < 0.1 * 60.0 + 10.0       # |v_east| < 60 m/s here
        assert -ned[k, 2] == pytest.approx(np.interp(t[k], t_true, truth["h_m"]), abs=25.0)
    # displacement over the flight = the truth's, to the noise and one receiver period
    d_gps = ned[-1, :2] - ned[0, :2]
    d_true = np.array([np.interp(t[-1], t_true, truth[c]) - np.interp(t[0], t_true, truth[c])
                       for c in ("pos_n_m", "pos_e_m")])
    assert np.linalg.norm(d_gps - d_true) < 0.01 * np.linalg.norm(d_true) + 20.0
    home = [m["data"] for m in msgs if m["meta"]["type"] == "HOME_POSITION"]
    assert home, "HOME_POSITION streamed after the first fix"
    h = geodetic_to_ned(home[0]["latitude"] * 1e-7, home[0]["longitude"] * 1e-7,
                        home[0]["altitude"] * 1e-3, *origin)
    assert math.hypot(h[0], h[1]) < 10.0            # the first fix: at the origin, t = 0
    # announced when set (the first fix arrives with the first frame), not 5 s later
    first_home = next(m for m in msgs if m["meta"]["type"] == "HOME_POSITION")
    assert first_home["data"]["time_usec"] < 0.1e6
    assert any("home set" in m["data"]["text"] for m in msgs if m["meta"]["type"] == "STATUSTEXT")
    status = [m["data"] for m in msgs if m["meta"]["type"] == "SYS_STATUS"]
    gps_bit = mavlink.MAV_SYS_STATUS_SENSOR_GPS
    assert all(s["onboard_control_sensors_present"] & gps_bit for s in status)
    assert status[-1]["onboard_control_sensors_health"] & gps_bit


def _gps_input(mav, stamp_us: int, lat_deg: float, lon_deg: float, alt_m: float) -> bytes:
    msg = mav.gps_input_encode(stamp_us, 0, 0, 0, 0, 3, int(round(lat_deg * 1e7)),
                               int(round(lon_deg * 1e7)), alt_m, 1.0, 1.0, 2200.0, 0.0, 0.0,
                               0.1, 1.5, 3.0, 12, 0)
    b = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return b


@pytest.mark.hil
def test_fc_without_gnss_keeps_flying_then_publishes_the_first_fix(tmp_path):
    with FcProcess(str(tmp_path)) as fc:
        gcs = ScriptedGcs(port=fc.gcs_ports[0])
        plant = ScriptedPlant(fc.plant_port)
        try:
            # GIVEN a plant without GNSS (an older plant): frames answered, no position
            k = 0
            for k in range(1, 201):
                plant.exchange(level_meas(0.002 * k))
            status = gcs.wait("SYS_STATUS", 5.0)
            gps_bit = mavlink.MAV_SYS_STATUS_SENSOR_GPS
            assert status.onboard_control_sensors_present & gps_bit
            assert not status.onboard_control_sensors_health & gps_bit
            raw = gcs.wait("GPS_RAW_INT", 5.0)
            assert raw is not None and raw.fix_type == 0
            ack = gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE,
                              mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            assert ack.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            # live messages carry sim time in lockstep: the newest frame's stamp (0.4 s)
            att = gcs.wait("ATTITUDE", 5.0)
            assert att.time_boot_ms == 400
            assert gcs.wait("GLOBAL_POSITION_INT", 1.5) is None
            # WHEN frames carry GPS_INPUT
            for j in range(1, 101):
                k += 1
                stamp = 2000 * k
                frame = plant.frame_bytes(level_meas(stamp * 1e-6))
                frame += _gps_input(plant.mav, stamp, 34.9 + 1e-5 * j, -117.9, 21000.0 + j)
                plant.send_raw(frame)
                reply = plant.recv_servo(5.0)
                assert reply is not None and reply.time_usec == stamp
            # THEN the fix, the position and home reach the ground station
            raw = gcs.wait("GPS_RAW_INT", 5.0, cond=lambda m: m.fix_type == 3)
            assert raw is not None and raw.satellites_visible == 12
            assert 349_000_100 <= raw.lat <= 349_010_000 and raw.lon == -1_179_000_000
            assert raw.vel == 65535                 # 2200 m/s does not fit u16 cm/s: unknown
            gpi = gcs.wait("GLOBAL_POSITION_INT", 5.0)
            assert gpi is not None and 400 < gpi.time_boot_ms <= 2 * k   # sim ms of a frame
            assert gpi.vx == 32767                  # saturated i16 cm/s
            # home is the first fix (alt 21001 m); relative_alt is above it (0 when this is the
            # first fix itself: the stream may publish before the second GPS_INPUT arrives)
            assert gpi.relative_alt == gpi.alt - 21_001_000 and gpi.alt >= 21_001_000
            ack = gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE,
                              mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            assert ack.result == mavlink.MAV_RESULT_ACCEPTED
            home = gcs.wait("HOME_POSITION", 5.0)
            assert home is not None and home.latitude == int(round((34.9 + 1e-5) * 1e7))
            status = gcs.wait("SYS_STATUS", 5.0,
                              cond=lambda m: m.onboard_control_sensors_health & gps_bit)
            assert status is not None
        finally:
            plant.close()
            gcs.close()
        assert fc.stop() == 0


def test_log_framer_gives_the_codecs_bytes():
    """The .tlog's lean framing (fc/link.py LeanFramer) is byte-identical to ``msg.pack``."""
    from fc.link import LeanFramer, new_codec
    framer = LeanFramer(1, 1)
    assert framer.ok
    c = new_codec(1, 1)
    rng = np.random.default_rng(3)
    for seq in range(300):
        x = rng.normal(size=6)
        msgs = (c.attitude_encode(seq * 100, *x),
                c.statustext_encode(4, b"chunk", seq % 7, seq % 3),      # a field named id
                c.global_position_int_encode(seq, 349054321, -1178839876, 21_000_000, -5,
                                             32767, -32767, 0, 35999),
                c.servo_output_raw_encode(seq, 0, 1500, 1000 + seq, 2000, 0, 0, 0, 0, 0))
        for m in msgs:
            c.seq = seq % 256
            assert framer.frame(m, seq % 256) == m.pack(c), m.get_type()
