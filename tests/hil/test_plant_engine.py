"""The plant's engine speed model (docs/plant.md s. 6): throttle limits, lag, rate limit,
thrust law and cap, trimmed start; and the [[target]] timelines of guided scenarios."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_sim import dynamics as dy
from plant_sim.scenario import ScenarioError, load, parse
from plant_sim.sim import TRUTH_NAMES, PlantSim
from plant_sim.vehicle import S_REF_M2


def _sim(**speed):
    sc = load("cruise")
    sc.data["speed"].update(speed)
    sc.data["sensors"]["enabled"] = False
    return PlantSim(sc)


def _speed(x):
    return math.sqrt(x[dy.X_U] ** 2 + x[dy.X_V] ** 2 + x[dy.X_W] ** 2)


def test_trimmed_start_holds_speed_and_balances_drag():
    sim = _sim()
    thr0 = sim.x[dy.X_THR]
    assert 0.3 < thr0 < 0.6 and sim.x[dy.X_CMD_THR] == thr0
    for _ in range(500):                                   # 1 s with trim surfaces
        sim.step_frame(sim.trim_rad)
    assert abs(_speed(sim.x) - 2250.0) < 0.01
    assert abs(-sim.x[dy.X_PD] - 28000.0) < 0.1


def test_throttle_lag_is_first_order_with_its_time_constant():
    sim = _sim(throttle_tau_s=0.5, throttle_initial=0.4)
    assert sim.x[dy.X_THR] == pytest.approx(0.4)
    sim.throttle(0.8)
    for _ in range(250):                                   # 0.5 s = one time constant
        sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THR] == pytest.approx(0.4 + 0.4 * (1.0 - math.exp(-1.0)), abs=1e-9)


def test_throttle_command_limits_and_rate_limit():
    sim = _sim(throttle_tau_s=0.0, throttle_initial=0.5)
    sim.throttle(3.0)                                      # beyond full: clipped to 1
    sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THR] == 1.0
    sim.throttle(-2.0)                                     # below idle: clipped to 0
    sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THR] == 0.0
    sim = _sim(throttle_tau_s=0.0, throttle_rate_1_s=0.5, throttle_initial=0.2)
    sim.throttle(1.0)
    for _ in range(100):                                   # 0.2 s at 0.5 /s
        sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THR] == pytest.approx(0.3, abs=1e-9)
    sim.throttle(math.nan)                                 # a NaN command holds the position
    sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THR] == pytest.approx(0.3, abs=1e-9)


def test_thrust_law_and_cap():
    sim = _sim(throttle_tau_s=0.0, throttle_initial=0.5)
    row = np.zeros(len(TRUTH_NAMES))
    sim.truth_row(row)
    qbar = row[TRUTH_NAMES.index("qbar_pa")]
    t = row[TRUTH_NAMES.index("thrust_N")]
    assert t == pytest.approx(0.5 * 0.02576 * qbar * S_REF_M2, rel=1e-12)
    sim = _sim(throttle_tau_s=0.0, throttle_initial=1.0, thrust_max_N=3.0e5)
    sim.truth_row(row)
    assert row[TRUTH_NAMES.index("thrust_N")] == 3.0e5    # capped at thrust_max_N
    sim.step_frame(sim.trim_rad)
    assert sim.x[dy.X_THRUST] == 3.0e5                     # the dynamics use the same thrust


def test_more_throttle_accelerates_less_decelerates():
    # the trim throttle is the trimmed start's own (it depends on the scenario's earth model:
    # the round Earth's centrifugal relief lowers the lift, hence the drag, needed)
    thr_trim = float(_sim(throttle_tau_s=0.0).x[dy.X_THR])
    v = {}
    for thr in (0.2, thr_trim, 0.8):
        sim = _sim(throttle_tau_s=0.0)
        sim.throttle(thr)
        for _ in range(500):
            sim.step_frame(sim.trim_rad)
        v[thr] = _speed(sim.x) - 2250.0
    assert 0.2 < thr_trim < 0.8
    assert v[0.2] < -0.5 and abs(v[thr_trim]) < 0.05 and v[0.8] > 0.5


def test_hold_model_ignores_the_throttle_command():
    sc = load("paper")
    a, b = PlantSim(sc), PlantSim(sc)
    b.throttle(1.0)
    for _ in range(100):
        a.step_frame(np.zeros(3))
        b.step_frame(np.zeros(3))
    assert np.array_equal(a.x[:dy.X_CMD_THR], b.x[:dy.X_CMD_THR]) and b.x[dy.X_THR] == 0.0


def test_target_timeline_parses_round_trips_and_rejects_bad_rows():
    sc = load("mission")
    assert sc.targets[0] == (0.0, 28000.0, 0.0, 2250.0) and len(sc.targets) == 5
    again = parse(sc.to_toml(), src="<round trip>")
    assert again.targets == sc.targets and again.data == sc.data
    base = load("paper").to_toml()
    with pytest.raises(ScenarioError, match=r"target\[0\].speed_m_s"):
        parse(base + "\n[[target]]\nt_s = 0.0\nalt_m = 1000.0\ncourse_deg = 0.0\n", src="x")
    with pytest.raises(ScenarioError, match=r"unknown key 'target\[0\].heading"):
        parse(base + "\n[[target]]\nt_s = 0.0\nalt_m = 1.0\ncourse_deg = 0.0\nspeed_m_s = 2000.0"
              "\nheading = 3\n", src="x")
    # out of file order: sorted by t_s (hyfc_wire.timeline, the one meaning of every reader)
    tg = parse(base + "".join(f"\n[[target]]\nt_s = {t}\nalt_m = {h}\ncourse_deg = 0.0\n"
                              f"speed_m_s = 2000.0\n" for t, h in ((5.0, 1.0), (1.0, 2.0))),
               src="x").targets
    assert tg == [(1.0, 2.0, 0.0, 2000.0), (5.0, 1.0, 0.0, 2000.0)]
    with pytest.raises(ScenarioError, match="speed.model"):
        parse(base.replace('model = "hold"', 'model = "rocket"'), src="x")
    with pytest.raises(ScenarioError, match="throttle_initial"):
        parse(base.replace("throttle_initial = -1.0", "throttle_initial = 1.5"), src="x")


@pytest.mark.hil
def test_plant_process_flies_the_throttle_from_servo4(tmp_path):
    """The plant process (lockstep, cruise scenario) applies servo4 as the engine throttle."""
    import json
    import sys

    from plant_sim import truthlog
    from plant_sim.link import ServoResponder
    from tools.sitl.procs import run_serving
    trim = list(PlantSim(load("cruise")).trim_rad)
    resp = ServoResponder()
    out = tmp_path / "engine"
    argv = [sys.executable, "-m", "plant_sim", "run", "--scenario", "cruise",
            "--fc", f"127.0.0.1:{resp.addr[1]}", "--bind", "127.0.0.1:0",
            "--out", str(out), "--duration", "2.0", "--progress-every", "0"]
    try:
        proc = run_serving("plant", argv, lambda: resp.serve_one(
            lambda stamp, vals: trim + [0.9 if stamp >= 1_000_000 else -1.0], timeout_s=0.2), 60.0)
    finally:
        resp.close()
    assert proc.poll() == 0, proc.stderr_tail
    assert json.loads((out / "plant_summary.json").read_text())["frames"] == 1000
    tr = truthlog.load(out)
    t, thrust = tr["t_s"], tr["thrust_N"]
    # GIVEN throttle 0 (PWM 1000) for the first second, THEN the thrust decays with the lag
    assert thrust[np.searchsorted(t, 0.99)] < 0.2 * thrust[0]
    # WHEN servo4 asks 0.9, THEN the thrust rises toward 0.9 C_T qbar S
    q = tr["qbar_pa"][-1]
    assert thrust[-1] > 0.8 * 0.9 * 0.02576 * q * S_REF_M2
