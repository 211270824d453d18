"""Dispersion files (tools.evidence.montecarlo.dispersions): validation, sampling, seeds.

Tier 1: no cluster, no simulation.
"""
import math

import numpy as np
import pytest

from tools.evidence.montecarlo import __main__ as cli
from tools.evidence.montecarlo import dispersions as dsp


# GIVEN a malformed dispersion file WHEN parsed THEN DispersionError names the key at fault.
BAD = [
    ("[wind]\nspeed = 1.0\n", "wind"),                                         # unknown section
    ("[aero]\nCX = 1.1\n", "aero.CX"),                                         # unknown variable
    ("[aero]\nCL = { dist = 'gauss', mean = 1.0, std = 0.1 }\n", "aero.CL.dist"),
    ("[aero]\nCL = { low = 0.8, high = 1.2 }\n", "aero.CL"),                   # no dist
    ("[aero]\nCL = { dist = 'uniform', low = 0.8 }\n", "aero.CL"),             # missing high
    ("[aero]\nCL = { dist = 'uniform', low = 0.8, high = 1.2, hi = 3 }\n", "aero.CL.hi"),
    ("[aero]\nCL = { dist = 'uniform', low = 1.2, high = 0.8 }\n", "aero.CL"),  # low > high
    ("[aero]\nCL = { dist = 'uniform', low = 1.0, high = 1.0 }\n", "aero.CL"),  # empty
    ("[aero]\nCL = { dist = 'normal', mean = 1.0, std = 0.0, low = 0.5, high = 1.5 }\n",
     "aero.CL.std"),
    ("[aero]\nCL = { dist = 'normal', mean = 2.0, std = 0.1, low = 0.5, high = 1.5 }\n",
     "aero.CL.mean"),
    ("[aero]\nCL = { dist = 'normal', mean = 1.0, std = 0.1 }\n", "aero.CL"),  # unbounded factor
    ("[aero]\nCL = { dist = 'uniform', low = -0.2, high = 1.2 }\n", "aero.CL.low"),  # factor <= 0
    ("[aero]\nCL = 0.0\n", "aero.CL"),                                         # factor <= 0
    ("[aero]\nCL = 'big'\n", "aero.CL"),                                       # not a number
    ("[aero]\nCL = true\n", "aero.CL"),                                        # bool for a number
    ("[aero]\nCL = { dist = 'uniform', low = '0.8', high = 1.2 }\n", "aero.CL.low"),
    ("[actuators]\ntau_s = -0.01\n", "actuators.tau_s"),
    ("[actuators]\nrate_max_deg_s = { dist = 'uniform', low = 0.0, high = 60.0 }\n",
     "actuators.rate_max_deg_s.low"),
    ("[sensors]\nnoise = 1\n", "sensors.noise"),                               # switch needs bool
    ("[initial]\nalpha_deg = { dist = 'fixed' }\n", "initial.alpha_deg"),
    ("[spec]\novershoot_pct = 10\n", "spec.overshoot_pct"),
    ("[spec]\novershoot_max_pct = { alpha = 10, gamma = 3 }\n", "spec.overshoot_max_pct.gamma"),
    ("[spec]\nsettling_max_s = -1\n", "spec.settling_max_s"),
    ("[campaign]\nauthor = 'x'\n", "campaign.author"),
    ("aero = 3\n", "aero"),
    ("[aero\nCL = 1\n", "not valid TOML"),
]


@pytest.mark.parametrize("text,key", BAD)
def test_bad_files_rejected_naming_the_key(text, key):
    with pytest.raises(dsp.DispersionError) as exc:
        dsp.parse(text, name="bad")
    assert key in str(exc.value)


def test_cli_rejects_bad_file_before_starting_anything(tmp_path, capsys):
    # GIVEN a dispersion file with an unknown distribution
    bad = tmp_path / "bad.toml"
    bad.write_text("[aero]\nCm = { dist = 'triangular', low = 0.8, high = 1.2 }\n")
    # WHEN the campaign command is given it THEN it exits 2 with the key in the message
    rc = cli.main(["--runs", "3", "--dispersions", str(bad), "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "aero.Cm.dist" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_unknown_shipped_name_lists_the_shipped_files():
    with pytest.raises(dsp.DispersionError) as exc:
        dsp.load("no_such_dispersions")
    assert "paper" in str(exc.value)


def test_paper_dispersions_as_documented():
    d = dsp.load("paper")
    for c in dsp.AERO_COEFFICIENTS:
        dist = d.dists[f"aero.{c}"]
        assert (dist.kind, dist.low, dist.high) == ("uniform", 0.8, 1.2)
    assert d.dists["sensors.noise"].value == 1.0
    assert d.dists["disturbance.amplitude_factor"].value == 1.0
    for ax in ("roll", "pitch", "yaw"):
        p = d.dists.get(f"disturbance.phase_{ax}_deg")
        # the random phase waits for the plant's disturbance.phase_*_deg keys
        assert p is None or (p.kind, p.low, p.high) == ("uniform", 0.0, 360.0)


def test_every_variable_maps_to_a_key_of_the_plant_scenario_or_says_which_is_missing():
    from plant_sim.scenario import load
    from tools.evidence.montecarlo import apply
    base = load("paper")
    for key, var in dsp.VARIABLES.items():
        # GIVEN one variable at a value inside its range and the plant's
        val = 0.0 if var.is_switch else 0.5 if var.unit == "1" else \
            0.05 if key.endswith("tau_s") else 45.0 if key.endswith("rate_max_deg_s") else 2.0
        # WHEN applied THEN it lands on its scenario key, or the error names both keys
        try:
            sc = apply.apply(base, {key: val})
        except dsp.DispersionError as exc:
            assert key in str(exc) and "plant" in str(exc)
            continue
        if key.startswith("aero."):
            assert sc.data["uncertainty"][key[5:]] == pytest.approx(val - 1.0)
        elif key in apply._SET:
            assert sc.get(apply._SET[key]) == val
        elif key in apply._SCALE:
            assert sc.get(apply._SCALE[key]) == pytest.approx(val * base.get(apply._SCALE[key]))
        else:
            assert key in ("sensors.noise", "sensors.noise_factor")
            assert all(sc.data["sensors"]["noise"][k] == pytest.approx(
                val * base.data["sensors"]["noise"][k]) for k in sc.data["sensors"]["noise"])


def test_applied_values_reach_the_plant_scenario():
    from plant_sim.scenario import load
    from tools.evidence.montecarlo import apply
    base = load("paper")
    sc = apply.apply(base, {"aero.Cm": 0.85, "mass.iyy_factor": 1.1, "initial.beta_deg": 3.0,
                            "sensors.noise": 0.0, "actuators.rate_max_deg_s": 45.0,
                            "disturbance.amplitude_factor": 0.5})
    assert sc.data["uncertainty"]["Cm"] == pytest.approx(-0.15)
    assert sc.data["uncertainty"]["CL"] == base.data["uncertainty"]["CL"]
    assert sc.data["vehicle"]["Iyy_kg_m2"] == pytest.approx(1.1 * base.data["vehicle"]["Iyy_kg_m2"])
    assert sc.data["initial"]["beta_deg"] == 3.0
    assert all(v == 0.0 for v in sc.data["sensors"]["noise"].values())
    assert sc.data["actuators"]["rate_limit_deg_s"] == 45.0
    assert sc.data["disturbance"]["scale"] == pytest.approx(0.5 * base.data["disturbance"]["scale"])
    assert sc.commands == base.commands
    # the loaded scenario itself is untouched
    assert base.data["uncertainty"]["Cm"] == -0.2 and base.data["initial"]["beta_deg"] == 5.0


def test_sampling_is_a_function_of_seed_and_index():
    d = dsp.load("paper")
    a = d.sample(7, 3)
    assert a == d.sample(7, 3)
    assert a != d.sample(7, 4)
    assert a != d.sample(8, 3)
    assert dsp.case_sim_seed(7, 3) == dsp.case_sim_seed(7, 3) != dsp.case_sim_seed(7, 4)


def test_adding_a_variable_does_not_change_the_others_draws():
    base = "[aero]\nCL = { dist = 'uniform', low = 0.8, high = 1.2 }\n"
    more = base + "[mass]\nmass_factor = { dist = 'uniform', low = 0.9, high = 1.1 }\n"
    for i in range(5):
        assert dsp.parse(base).sample(1, i)["aero.CL"] == dsp.parse(more).sample(1, i)["aero.CL"]


def test_draws_within_bounds_and_distributed_as_declared():
    d = dsp.parse("[aero]\nCL = { dist = 'uniform', low = 0.8, high = 1.2 }\n"
                  "Cm = { dist = 'normal', mean = 1.0, std = 0.1, low = 0.95, high = 1.3 }\n"
                  "[initial]\nbeta_deg = 4.0\n")
    s = [d.sample(3, i) for i in range(4000)]
    cl = np.array([x["aero.CL"] for x in s])
    cm = np.array([x["aero.Cm"] for x in s])
    assert cl.min() >= 0.8 and cl.max() <= 1.2
    assert abs(cl.mean() - 1.0) < 0.01 and abs(cl.std() - 0.4 / math.sqrt(12)) < 0.01
    assert cm.min() >= 0.95 and cm.max() <= 1.3
    # truncated to [-0.5, +3] sigma: the mean moves right of 1.0 by
    # sigma (phi(-0.5) - phi(3)) / (Phi(3) - Phi(-0.5)) = 0.0504 (closed form)
    assert abs(cm.mean() - 1.0504) < 0.003
    assert all(x["initial.beta_deg"] == 4.0 for x in s)


def test_spec_scalar_and_per_channel():
    d = dsp.parse("[spec]\novershoot_max_pct = { beta = 40 }\nsettling_max_s = 3\n")
    assert d.spec["overshoot_max_pct"] == {"alpha": 30.0, "beta": 40.0, "mu": 30.0}
    assert d.spec["settling_max_s"] == {"alpha": 3.0, "beta": 3.0, "mu": 3.0}
    assert d.spec["final_error_max_deg"]["mu"] == dsp.SPEC_DEFAULTS["final_error_max_deg"]


def test_campaign_identity_ignores_comments_and_spec_but_not_distributions():
    from tools.evidence.montecarlo.case import CampaignConfig
    text = dsp.load("paper").source_text

    def ident(t):
        return CampaignConfig("paper", t, "paper", 1).identity()
    assert ident(text) == ident("# a comment\n" + text.replace("overshoot_max_pct = 10.0",
                                                               "overshoot_max_pct = 12.0"))
    assert ident(text) != ident(text.replace("CL = { dist = \"uniform\", low = 0.8",
                                             "CL = { dist = \"uniform\", low = 0.7"))
