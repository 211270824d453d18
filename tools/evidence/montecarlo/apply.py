"""A case's dispersion values applied to the plant's scenario; the in-process flight.

``apply(scenario, values)`` returns a new, re-validated ``plant_sim.scenario.Scenario``:
the loaded scenario's ``data`` is deep-copied, edited key by key, and parsed again from its TOML
form, so the plant's own ranges check every dispersed value (a value outside them raises
``plant_sim.scenario.ScenarioError`` naming the scenario key). The plant's files are never
touched. Mapping (dispersion variable -> scenario key):

| dispersion | scenario | how |
|---|---|---|
| ``aero.C*`` (factor f) | ``uncertainty.C*`` | set to f - 1 (replaces the scenario's value: the factor is on the database's coefficient) |
| ``mass.mass_factor`` etc. | ``vehicle.mass_kg``, ``Ixx/Iyy/Izz_kg_m2`` | multiplied |
| ``mass.x_cg_m`` | ``vehicle.x_cg_m`` | set |
| ``initial.*`` | ``initial.*`` (same names) | set |
| ``disturbance.amplitude_factor`` | ``disturbance.scale`` | multiplied |
| ``disturbance.phase_*_deg`` | ``disturbance.phase_*_deg`` | set (needs the plant to have the key) |
| ``sensors.noise`` (false) | every ``sensors.noise.*`` | set to 0 |
| ``sensors.noise_factor`` | every ``sensors.noise.*`` | multiplied |
| ``sensors.bias_alpha_deg`` / ``beta`` | ``sensors.bias.aoa_deg`` / ``ssa_deg`` | set |
| ``sensors.bias_{roll,pitch,yaw}_deg``, ``bias_{p,q,r}_deg_s`` | ``sensors.bias.*`` | set |
| ``actuators.tau_s`` | ``actuators.tau_s`` | set |
| ``actuators.rate_max_deg_s`` | ``actuators.rate_limit_deg_s`` | set |
"""
from __future__ import annotations

import copy
import math

import numpy as np

from tools.evidence.montecarlo.dispersions import DispersionError

_SET = {
    "mass.x_cg_m": "vehicle.x_cg_m",
    "initial.alpha_deg": "initial.alpha_deg",
    "initial.beta_deg": "initial.beta_deg",
    "initial.mu_deg": "initial.mu_deg",
    "initial.p_deg_s": "initial.p_deg_s",
    "initial.q_deg_s": "initial.q_deg_s",
    "initial.r_deg_s": "initial.r_deg_s",
    "disturbance.phase_roll_deg": "disturbance.phase_roll_deg",
    "disturbance.phase_pitch_deg": "disturbance.phase_pitch_deg",
    "disturbance.phase_yaw_deg": "disturbance.phase_yaw_deg",
    "sensors.bias_alpha_deg": "sensors.bias.aoa_deg",
    "sensors.bias_beta_deg": "sensors.bias.ssa_deg",
    "sensors.bias_roll_deg": "sensors.bias.roll_deg",
    "sensors.bias_pitch_deg": "sensors.bias.pitch_deg",
    "sensors.bias_yaw_deg": "sensors.bias.yaw_deg",
    "sensors.bias_p_deg_s": "sensors.bias.p_deg_s",
    "sensors.bias_q_deg_s": "sensors.bias.q_deg_s",
    "sensors.bias_r_deg_s": "sensors.bias.r_deg_s",
    "actuators.tau_s": "actuators.tau_s",
    "actuators.rate_max_deg_s": "actuators.rate_limit_deg_s",
}
_SCALE = {
    "mass.mass_factor": "vehicle.mass_kg",
    "mass.ixx_factor": "vehicle.Ixx_kg_m2",
    "mass.iyy_factor": "vehicle.Iyy_kg_m2",
    "mass.izz_factor": "vehicle.Izz_kg_m2",
    "disturbance.amplitude_factor": "disturbance.scale",
}


def _node(data: dict, dotted: str, key_for_error: str):
    parts = dotted.split(".")
    node = data
    for p in parts[:-1]:
        node = node[p]
    if parts[-1] not in node:
        raise DispersionError(
            f"{key_for_error}: the plant's scenario has no key '{dotted}' to apply it to "
            f"(plant_sim.scenario.SCHEMA); remove {key_for_error} from the dispersion file "
            f"or add the key to the plant")
    return node, parts[-1]


def apply(scenario, values: dict):
    """A new Scenario: ``scenario`` with the case's dispersion ``values`` applied."""
    from plant_sim.scenario import Scenario, parse
    data = copy.deepcopy(scenario.data)
    for key, v in values.items():
        if key.startswith("aero."):
            node, leaf = _node(data, f"uncertainty.{key[5:]}", key)
            node[leaf] = float(v) - 1.0
        elif key in _SET:
            node, leaf = _node(data, _SET[key], key)
            node[leaf] = float(v)
        elif key in _SCALE:
            node, leaf = _node(data, _SCALE[key], key)
            node[leaf] = float(node[leaf]) * float(v)
        elif key == "sensors.noise":
            if v == 0.0:
                for k in data["sensors"]["noise"]:
                    data["sensors"]["noise"][k] = 0.0
        elif key == "sensors.noise_factor":
            for k in data["sensors"]["noise"]:
                data["sensors"]["noise"][k] = float(data["sensors"]["noise"][k]) * float(v)
        else:
            raise DispersionError(f"{key}: no rule to apply it to the plant's scenario")
    edited = Scenario(name=scenario.name, path=scenario.path, data=data,
                      commands=list(scenario.commands))
    # re-validate with the plant's own ranges (and get a Scenario exactly as loading gives)
    return parse(edited.to_toml(), src=f"{scenario.path} (dispersed)", name=scenario.name)


def fly_closed_loop(scenario, variant: str, duration_s, sim_seed: int, law_overrides: dict,
                    full: bool = False):
    """Fly one variant of a dispersed scenario with ``tools.sitl.closed_loop.simulate``.

    Every frame is recorded (as the plant's truth log of the main job), so the metrics are
    taken on the same samples as ``summary.json``'s. The law sees the fc's estimate from the
    plant's sensor model (``estimate="sensors"``), as in the two-process product, so sensor
    noise and bias dispersions act in process too.
    """
    from tools.sitl import closed_loop
    res = closed_loop.simulate(scenario, coordinated=(variant == "coordinated"),
                               duration_s=duration_s, seed=sim_seed,
                               law_overrides=law_overrides or None, estimate="sensors")
    return flight_from_result(res, full)


def flight_from_result(res, full: bool = False):
    """A ``case.Flight`` from a ``tools.sitl.closed_loop.ClosedLoopResult``.

    With ``full``, ``Flight.full`` holds the arrays ``tools.sitl.plots`` draws (rates, surfaces,
    limits) plus the plant's truth and the law's status with their column names.
    """
    from tools.evidence.montecarlo.flight import Flight
    fl = Flight(t_s=res.t_s, alpha_rad=res.alpha_rad, beta_rad=res.beta_rad, mu_rad=res.mu_rad,
                cmd_t_s=np.asarray(res.cmd_t_s, float), cmd_rad=np.asarray(res.cmd_rad, float),
                diverged=bool(res.diverged), surfaces=res.surface_figures())
    if full:
        from tools.sitl import metrics as mt
        peak, sat_s = mt.surface_metrics(res.t_s, res.delta_rad, res.surface_limit_rad)
        fl.full = {
            "p_rad_s": res.p_rad_s, "q_rad_s": res.q_rad_s, "r_rad_s": res.r_rad_s,
            "V_m_s": res.V_m_s, "h_m": res.h_m,
            "delta_rad": res.delta_rad, "delta_cmd_rad": res.delta_cmd_rad,
            "limit_rad": res.surface_limit_rad, "max_surface_deg": peak,
            "saturated_s": sat_s,
            "alpha_ref_rad": res.alpha_ref_rad, "beta_ref_rad": res.beta_ref_rad,
            "mu_ref_rad": res.mu_ref_rad,
            "truth": res.truth, "truth_names": np.array(res.truth_names),
            "status": res.status, "status_names": np.array(res.status_names),
            "law_params": res.params,
        }
    return fl
