"""Scenario files: the shipped ones load; bad ones fail with a message naming the key."""
import math

import numpy as np
import pytest

from plant_sim.scenario import ScenarioError, list_names, load, parse
from plant_sim.sim import PlantSim


def test_shipped_scenarios_load_and_build():
    names = list_names()
    assert {"paper", "nominal", "cg_aft"} <= set(names)
    for n in names:
        sc = load(n)
        sim = PlantSim(sc)
        assert sim.n_sub * sim.physics_dt_s == pytest.approx(sim.frame_dt_s, rel=1e-12)
        assert sc.commands, n


def test_paper_scenario_matches_the_paper():
    sc = load("paper")
    ini = sc.data["initial"]
    assert (ini["V_m_s"], ini["h_m"], ini["alpha_deg"], ini["beta_deg"], ini["mu_deg"]) == (2200.0, 21000.0, 1.0, 5.0, 0.0)
    assert (ini["p_deg_s"], ini["q_deg_s"], ini["r_deg_s"]) == (0.0, 0.0, 0.0)
    assert sc.commands[0] == (0.0, 5.0, 0.0, 4.0)
    assert sc.duration_s == 20.0
    u = sc.data["uncertainty"]
    assert (u["CL"], u["CD"], u["CY"], u["Cl"], u["Cm"], u["Cn"]) == (0.2, 0.2, 0.2, -0.2, -0.2, -0.2)
    assert sc.data["disturbance"]["enabled"] and sc.data["disturbance"]["amplitude"] == 10.0
    assert sc.data["vehicle"]["x_cg_m"] == 0.0
    a, b, m = sc.command_at(3.0)
    assert (a, b, m) == pytest.approx((math.radians(5), 0.0, math.radians(4)))
    nominal = load("nominal").data
    assert all(v == 0.0 for v in nominal["uncertainty"].values())
    assert not nominal["disturbance"]["enabled"] and not nominal["sensors"]["enabled"]
    assert load("cg_aft").data["vehicle"]["x_cg_m"] == 2.90


def _paper_text():
    return open(load("paper").path).read()


@pytest.mark.parametrize("old, new, key", [
    ("x_cg_m = 0.0", "x_cg_m = 0.0\nxcg = 1.0", "vehicle.xcg"),
    ("[actuators]", "[actuator]\nfoo = 1\n[actuators]", "actuator"),
    ("attitude_deg = 0.02", "atitude_deg = 0.02", "sensors.noise.atitude_deg"),
    ("V_m_s = 2200.0", "V_m_s = -5.0", "initial.V_m_s"),
    ("limit_deg = 20.0", "limit_deg = 30.0", "actuators.limit_deg"),
    ("tau_s = 0.02", "tau_s = \"fast\"", "actuators.tau_s"),
    ('unit = "deg/s^2"', 'unit = "furlongs"', "disturbance.unit"),
    ("enabled = true\namplitude", "enabled = 1\namplitude", "disturbance.enabled"),
    ("frame_hz = 500.0", "frame_hz = 300.0", "timing.physics_hz"),
    ("mu_deg = 4.0", "mu_deg = 400.0", "command[0].mu_deg"),
    ("mu_deg = 4.0", "mu_deg = 4.0\nphi_deg = 1.0", "command[0].phi_deg"),
    ("pwm_trim_us = 1500", "pwm_trim_us = 2100", "servo.pwm_min_us"),
    ("seed = 1", "seed = 1.5", "seed"),
])
def test_bad_values_are_rejected_naming_the_key(old, new, key):
    text = _paper_text()
    assert old in text
    with pytest.raises(ScenarioError) as e:
        parse(text.replace(old, new, 1), "bad.toml")
    assert f"'{key}'" in str(e.value) and "bad.toml" in str(e.value)


def test_malformed_and_missing_files():
    with pytest.raises(ScenarioError, match="not valid TOML"):
        parse("name = [", "broken.toml")
    with pytest.raises(ScenarioError, match="unknown scenario 'nope'"):
        load("nope")
    with pytest.raises(ScenarioError, match="not found"):
        load("/nonexistent/x.toml")


def test_round_trip_of_the_scenario_as_used():
    sc = load("paper")
    again = parse(sc.to_toml(), "as_used.toml")
    assert again.data == sc.data
    assert again.commands == sc.commands


def _leaves(schema, prefix=""):
    from plant_sim.scenario import Key
    for k, v in schema.items():
        if isinstance(v, dict):
            yield from _leaves(v, prefix + k + ".")
        else:
            assert isinstance(v, Key)
            yield prefix + k, v


def test_every_key_rejects_wrong_types_and_out_of_range_values():
    """Systematic: each schema key, set to a wrong type or just outside its range, fails with a
    message naming that key; its default is accepted."""
    import copy
    from plant_sim.scenario import SCHEMA, _apply, ScenarioError as SE
    checked = 0
    for dotted, key in _leaves(SCHEMA):
        parts = dotted.split(".")

        def with_value(v):
            given = {}
            node = given
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = v
            return given

        _apply("t.toml", SCHEMA, with_value(copy.deepcopy(key.default)), "")
        bad = ["text"] if key.kind != "str" else [1.5]
        if key.kind in ("float", "int"):
            if key.lo is not None and math.isfinite(key.lo):
                bad.append(key.lo - (1 if key.kind == "int" else max(1e-6, abs(key.lo) * 1e-6)))
            if key.hi is not None and math.isfinite(key.hi):
                bad.append(key.hi + (1 if key.kind == "int" else max(1e-6, abs(key.hi) * 1e-6)))
        if key.kind == "str" and key.choices:
            bad.append("not-a-choice")
        for v in bad:
            with pytest.raises(SE) as e:
                _apply("t.toml", SCHEMA, with_value(v), "")
            assert f"'{dotted}'" in str(e.value), (dotted, v, str(e.value))
            checked += 1
    assert checked > 150
